"""Generation with a trained FCRBM: valence/arousal per frame in, motion out (issue 6).

Context: valence and arousal on the paper's 1-3 scale (1 low, 2 neutral, 3 high), constant
(:func:`constant_context`) or a schedule of keyframes (:func:`schedule_context`), each keyframe
giving ``valence`` and ``arousal`` or an ``emotion`` (converted through the project's
circumplex, :data:`emotive.data.emotion.VALENCE_AROUSAL`: ``2 + (v, a)``). Values beyond 1-3
exaggerate (extrapolation) and are accepted within :data:`CONTEXT_RANGE`; the context must stay
positive because every interaction of the model is multiplicative in it.

Start: the last ``N`` frames of a primer clip on the training rig, or by default ``N`` copies
of the training data's mean frame (a statistic, not a recording). From the mean frame the model
first walks :data:`WARMUP_SECONDS` at the neutral point :data:`WARMUP_CONTEXT`, where its
walk starts most reliably, then changes linearly to the first requested context over
:data:`WARMUP_RAMP_SECONDS`; those frames are dropped, so the output starts in motion (the paper
started from six recorded frames of the requested state instead, which a checkpoint cannot
ship).

Root: the model predicts the root's velocity beside the pose, and where its legs slow down or
step in place that velocity can go on (the root glides). By default (``root="feet"``) the
decoded root path is rebuilt from the stance foot (:func:`emotive.ik.root_from_stance`, a
post-process: the planted foot stays still and the root moves by what the legs do);
``root="model"`` keeps the model's own root velocity.

Legend: ``T`` frames, ``D`` visible units, ``N`` order.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.data.emotion import ALL_LABELS, Emotion
from emotive.errors import ConfigError, EmotiveError
from emotive.ik.stance_root import root_from_stance
from emotive.models.fcrbm.checkpoint import load_fcrbm_checkpoint
from emotive.models.fcrbm.data import CONTEXT_RANGE, FrameCodec, frame_vectors
from emotive.models.fcrbm.model import FCRBM

#: Seconds generated at :data:`WARMUP_CONTEXT` and dropped when starting from the mean frame.
WARMUP_SECONDS = 2.0
#: Valence/arousal of the warm-up from the mean frame.
WARMUP_CONTEXT = (2.0, 2.0)
#: Seconds of linear change from the warm-up to the first requested context (also dropped).
WARMUP_RAMP_SECONDS = 1.0
#: Root paths of :func:`generate_motion`: rebuilt from the stance foot, or the model's own.
ROOT_MODES = ("feet", "model")
#: A standardized frame value beyond this means the model's dynamics diverged.
DIVERGED = 25.0


class FCRBMInputError(EmotiveError):
    """Valence/arousal, schedule, primer or length the FCRBM cannot use."""


class FCRBMDivergedError(EmotiveError):
    """The generated frames left the data's range: the model is unstable for this context."""


def default_checkpoint_path() -> Path:
    """The committed FCRBM checkpoint."""
    return Path(str(files("emotive.assets") / "fcrbm" / "fcrbm.pt"))


@dataclass(frozen=True, eq=False)
class FCRBMModel:
    """A trained FCRBM with the codec of its frames."""

    network: FCRBM
    codec: FrameCodec

    @property
    def fps(self) -> float:
        """Frame rate of the generated motion."""
        return self.codec.fps


def load_fcrbm_model(path: str | Path | None = None) -> FCRBMModel:
    """The FCRBM of a checkpoint, by default the committed one.

    Raises:
        ConfigError: missing, corrupt, or not an FCRBM checkpoint.
    """
    if path is None and not default_checkpoint_path().is_file():
        raise ConfigError(f"the built-in FCRBM checkpoint {default_checkpoint_path()} is "
                          "missing: reinstall emotive, or train one with `emotive fcrbm train "
                          "--out models/fcrbm` and pass --model models/fcrbm/last.pt")
    network, codec, _ = load_fcrbm_checkpoint(path or default_checkpoint_path())
    return FCRBMModel(network, codec)


def check_context(values: np.ndarray, where: str) -> np.ndarray:
    """``(..., 2)`` valence/arousal as float64, or :class:`FCRBMInputError` naming ``where``."""
    z = np.asarray(values, dtype=np.float64)
    low, high = CONTEXT_RANGE
    if not np.isfinite(z).all() or (z < low).any() or (z > high).any():
        bad = z[~(np.isfinite(z) & (z >= low) & (z <= high))].ravel()[0]
        raise FCRBMInputError(
            f"{where}: valence and arousal must be numbers in [{low:g}, {high:g}] (the paper's "
            f"scale is 1 low, 2 neutral, 3 high), got {bad}"
        )
    return z


def emotion_context(emotion: str) -> np.ndarray:
    """``(2,)`` valence/arousal (1-3 scale) of an emotion.

    ``(2,)`` valence/arousal (1-3 scale) of an emotion such as ``"sad"`` or
    ``"happy=0.5,angry=0.5"``.

    Raises:
        EmotionError: unknown names or bad weights.
    """
    return 2.0 + Emotion.parse(emotion, ALL_LABELS).valence_arousal()


def constant_context(valence: float, arousal: float, frames: int) -> np.ndarray:
    """``(frames, 2)`` constant context.

    Raises:
        FCRBMInputError: a value outside :data:`CONTEXT_RANGE` or NaN.
    """
    z = check_context(np.array([valence, arousal]), "--valence/--arousal")
    return np.repeat(z[None], frames, axis=0)


def schedule_context(path: str | Path, frames: int, fps: float) -> np.ndarray:
    """``(frames, 2)`` context from a JSON schedule.

    Interpolated linearly between keyframes and held before the first and after the last.

    The file holds ``[{"t": 0, "valence": 3, "arousal": 1}, {"t": 10, "emotion": "sad"}]``
    (seconds; ``emotion`` as for :func:`emotion_context`).

    Raises:
        FCRBMInputError: unreadable file, bad keyframes or values.
    """
    path = Path(path)
    try:
        keys = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FCRBMInputError(f"{path}: cannot read the schedule ({exc})") from None
    if not isinstance(keys, list) or not keys:
        raise FCRBMInputError(f"{path}: a schedule is a non-empty JSON list of keyframes such "
                              'as {"t": 0, "valence": 3, "arousal": 1}')
    times, points = [], []
    for k, key in enumerate(keys):
        where = f"{path}: keyframe {k}"
        if not isinstance(key, dict) or not isinstance(key.get("t"), int | float) or not (
                math.isfinite(key["t"]) and key["t"] >= 0):
            raise FCRBMInputError(f"{where}: needs a time \"t\" >= 0 in seconds")
        if "emotion" in key:
            point = emotion_context(str(key["emotion"]))
        elif "valence" in key and "arousal" in key:
            try:
                point = np.array([float(key["valence"]), float(key["arousal"])])
            except (TypeError, ValueError):
                raise FCRBMInputError(f"{where}: valence and arousal must be numbers") from None
        else:
            raise FCRBMInputError(f"{where}: give \"valence\" and \"arousal\", or \"emotion\"")
        times.append(float(key["t"]))
        points.append(check_context(point, where))
    if any(b < a for a, b in itertools.pairwise(times)):
        raise FCRBMInputError(f"{path}: keyframe times must not decrease")
    t = np.arange(frames) / fps
    pts = np.array(points)
    return np.stack([np.interp(t, times, pts[:, d]) for d in range(2)], 1)


def seed_frames(model: FCRBMModel, primer: Motion | None = None) -> np.ndarray:
    """``(N, D)`` starting frames: the primer's last ``N`` or the mean frame repeated.

    Raises:
        FCRBMInputError: the primer is on another rig or shorter than ``N + 1`` frames.
    """
    n = model.network.config.order
    if primer is None:
        return np.zeros((n, model.codec.dim), dtype=np.float32)
    name = primer.metadata.get("name", "the primer")
    if primer.skeleton.names != model.codec.skeleton.names:
        raise FCRBMInputError(f"{name}: the primer must be on the model's rig "
                              f"({len(model.codec.skeleton.names)} joints from "
                              f"{model.codec.skeleton.names[0]}); retarget it first")
    if primer.num_frames < n + 1:
        raise FCRBMInputError(f"{name}: the primer has {primer.num_frames} frames; the model "
                              f"needs at least {n + 1} initial frames")
    if abs(primer.fps - model.fps) > 1e-6:
        primer = resample(primer, model.fps)
    return model.codec.encode(frame_vectors(primer))[-n:]


def warmup_context(first: np.ndarray, fps: float) -> np.ndarray:
    """``(W, B, 2)`` context of the warm-up before a first requested context.

    ``(W, B, 2)`` context of the warm-up before a ``(B, 2)`` first requested context:
    :data:`WARMUP_SECONDS` at :data:`WARMUP_CONTEXT`, then a linear change to ``first`` over
    :data:`WARMUP_RAMP_SECONDS` (its last frame just before ``first``).
    """
    hold, ramp = round(WARMUP_SECONDS * fps), round(WARMUP_RAMP_SECONDS * fps)
    neutral = np.broadcast_to(np.asarray(WARMUP_CONTEXT, dtype=np.float64), first.shape)
    weight = (np.arange(1, ramp + 1) / (ramp + 1))[:, None, None]
    return np.concatenate((np.repeat(neutral[None], hold, axis=0),
                           (1 - weight) * neutral + weight * first))


def generate_motion(
    model: FCRBMModel,
    context: np.ndarray,
    seed: int = 0,
    primer: Motion | None = None,
    gibbs: int | None = None,
    name: str = "fcrbm",
    root: str = "feet",
) -> tuple[Motion, np.ndarray]:
    """Generate ``T`` frames following a per-frame context.

    Args:
        model: the trained model.
        context: ``(T, 2)`` valence/arousal per frame (1-3 scale), or ``(T, B, 2)`` for ``B``
            agents generated in one batch.
        seed: seed of the hidden samples.
        primer: starting clip (see :func:`seed_frames`).
        gibbs: Gibbs iterations per frame (default: the config's).
        name: name of the motion.
        root: ``"feet"`` or ``"model"`` (:data:`ROOT_MODES`, module doc).

    Returns:
        The motion (starting at the origin, facing +Z; the first agent's when batched) and the
        ``(T, D)`` (or ``(B, T, D)``) standardized frames (always the model's own root; decode
        other agents with :func:`decode_frames`).

    Raises:
        FCRBMInputError: bad context, primer, gibbs or root.
        FCRBMDivergedError: the frames ran out of the data's range.
    """
    z = check_context(context, "context")
    batched = z.ndim == 3
    z = z if batched else z[:, None]
    frames, agents = z.shape[0], z.shape[1]
    if frames < 1:
        raise FCRBMInputError("generate at least one frame")
    if gibbs is not None and gibbs < 1:
        raise FCRBMInputError(f"--gibbs must be >= 1, got {gibbs}")
    check_root(root)
    start = seed_frames(model, primer)
    lead = np.zeros((0, agents, 2)) if primer is not None else warmup_context(z[0], model.fps)
    warm = len(lead)
    zt = torch.from_numpy(np.concatenate((lead, z)).astype(np.float32))
    past = torch.from_numpy(np.repeat(start[None], agents, axis=0))
    gen = torch.Generator().manual_seed(seed)
    try:
        out = model.network.generate(past, zt, gibbs=gibbs, generator=gen).numpy()
    except RuntimeError:
        # Non-finite hidden probabilities: the frames ran off to infinity.
        out = np.full((1, 1, 1), np.inf)
    bad = ~(np.abs(out) <= DIVERGED).all(axis=(0, 2))
    if bad.any():
        raise FCRBMDivergedError(
            f"the model diverged (frames beyond {DIVERGED:g} standard deviations of the data) "
            f"for valence/arousal {np.round(z[0, 0], 2).tolist()}; this checkpoint is unstable "
            "there: use a context closer to its training points or retrain with more past_noise"
        )
    out = out[:, warm:]
    motion = decode_frames(model, out[0], name, root)
    return motion, (out if batched else out[0])


def check_root(root: str) -> None:
    """Raise :class:`FCRBMInputError` unless ``root`` is one of :data:`ROOT_MODES`."""
    if root not in ROOT_MODES:
        raise FCRBMInputError(f"--root must be one of {', '.join(ROOT_MODES)}, got {root!r}")


def decode_frames(model: FCRBMModel, frames: np.ndarray, name: str = "fcrbm",
                  root: str = "feet") -> Motion:
    """``(T, D)`` standardized frames to a clip, its root path as ``root`` says (module doc).

    Raises:
        FCRBMInputError: ``root`` is not one of :data:`ROOT_MODES`.
    """
    check_root(root)
    motion = model.codec.decode(frames, name)
    return root_from_stance(motion) if root == "feet" else motion


def motion_summary(motion: Motion, mover: int) -> dict[str, Any]:
    """Root speed (m/s) of joint ``mover`` and mean joint speed (m/s) of a clip."""
    p = motion.positions_with_end_sites()
    root = p[:, mover]
    speed = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1) * motion.fps
    joints = np.linalg.norm(np.diff(p, axis=0), axis=2).mean(1) * motion.fps
    return {"root_speed": float(speed.mean()), "joint_speed": float(joints.mean())}
