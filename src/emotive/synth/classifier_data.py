"""Synthetic walks as training clips of the perceived-emotion classifier.

The main paper offers its augmented data set, "Synthesized Emotive Gaits" (Bhattacharya et al.
2020, section 5.2), for "more research in emotion prediction". Here every walk of a folder of
``emotive synth`` becomes a training clip of :mod:`emotive.eval.classifier_training`, on the
same feature path as a real clip:

* its 21 role tracks are the world positions of the joints the classifier reads
  (:func:`emotive.eval.classifier.judge_joints` on the data set's rig, indices into the
  ``world`` array's joints; :func:`~emotive.eval.classifier.role_track` reads the same joints
  of a real clip), ``(T, 21, 3)`` float32 metres at the walk's rate (30 fps for the gait
  network);
* its features are :func:`emotive.eval.classifier.track_features` of that track: resampled
  to the classifier's rate (15 fps), ``(T', F)``;
* like a real training clip it also enters as :attr:`SynthMix.copies` variants of
  :func:`emotive.eval.classifier_augment.augment` (other proportions, layouts, heights,
  mirror images, source frame rates), drawn from their own seeded stream so that the real
  clips' variants are those of the real-only recipe.

Targets. A synthetic walk was made for a *blend* of the four labels (weights on the simplex,
none above 0.7, :mod:`emotive.synth.emotions`), and a transition walk moves from one blend to
another over 1 s. The emotion the generator was asked for is kept per frame, resampled to
the features' rate like the features (linear in time from the walk's start, so an augmented
variant at another frame rate keeps the same emotion at the same second): ``emotion``
``(T', C)`` and ``valence_arousal`` ``(T', 2)``. A training window's targets are the means of
these over the window's frames (:mod:`emotive.synth.classifier_mix`): the emotion *at the
window*, so a window before a transition teaches the first blend, one across it a mixture.
Those weights are a soft target of the label head (``target = "blend"``) or their heaviest
label (``"heaviest"``); the valence/arousal head learns the window's mean point; the style
head learns nothing from a synthetic walk (it has no style). ``"shuffled"`` is a control:
every walk gets the emotion track (and valence/arousal) of another walk of the folder, a
seeded permutation, so the motion is the same but its emotion is not the one it was made
for (:func:`shuffle_targets`); what synthetic walks teach beyond more walking shows as the
difference from ``"blend"``. The classifier's own reading of
each walk (the manifest's ``perceived``) is never used: that would train the classifier on
itself.

Legend: ``T`` frames, ``F`` features, ``C`` labels, ``J`` joints, ``E`` end sites.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import track

from emotive.core.roles import resolve_roles
from emotive.eval.classifier import ClassifierConfig, judge_joints, track_features
from emotive.eval.classifier_augment import augment
from emotive.synth.dataset import SyntheticGaits
from emotive.synth.recipe import SynthError

#: Seed stream of the synthetic walks' augmented variants (``[seed, stream]``).
AUGMENT_STREAM = 71
#: Seed stream of the ``"shuffled"`` control's permutation of walks.
SHUFFLE_STREAM = 72
#: What the label head learns from a synthetic window's emotion.
TARGETS = ("blend", "heaviest", "shuffled")


@dataclass(frozen=True)
class SynthMix:
    """How synthetic walks enter the classifier's training.

    Attributes:
        share: fraction of every training batch drawn from synthetic walks, ``0 <= share <
            1`` (``round(share * batch_size)`` windows; the rest are real, drawn as the
            real-only recipe draws them). 0 is the real-only recipe.
        target: ``"blend"`` (the window's mean emotion weights as a soft target),
            ``"heaviest"`` (their heaviest label as a hard one) or ``"shuffled"`` (a control:
            the blend target of another walk, :func:`shuffle_targets`).
        copies: augmented variants of every synthetic walk besides the walk itself (``None``:
            the recipe's ``augment_copies``, as for a real clip).
        limit: use only the first ``limit`` walks of the folder (0: all).
    """

    share: float = 0.25
    target: str = "blend"
    copies: int | None = None
    limit: int = 0

    def __post_init__(self) -> None:
        s = self.share
        if isinstance(s, bool) or not isinstance(s, int | float) or not 0 <= s < 1:
            raise SynthError(f"synthetic share {s!r}: give the fraction of every batch drawn "
                             "from synthetic walks, from 0 (none) up to but not 1")
        if self.target not in TARGETS:
            raise SynthError(f"synthetic target {self.target!r}: choose one of "
                             f"{', '.join(TARGETS)}")
        for name in ("copies", "limit"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
                raise SynthError(f"synthetic {name} {v!r}: give a whole number, 0 or more")


@dataclass(frozen=True)
class SynthClip:
    """One synthetic walk (or an augmented variant) as classifier training data.

    Attributes:
        name: ``synthetic-NNNNNN`` (the walk's sample id).
        sample_id: the walk's sample id in its folder.
        kind: the manifest's ``kind`` (``constant`` or ``transition``).
        features: ``(T, F)`` float32 features at the classifier's rate.
        emotion: ``(T, C)`` float32 weights over the classifier's labels, per feature frame.
        valence_arousal: ``(T, 2)`` float32 valence and arousal in -1..1, per feature frame.
        variant: 0 for the walk itself, ``k`` for its ``k``-th augmented variant.
    """

    name: str
    sample_id: int
    kind: str
    features: np.ndarray
    emotion: np.ndarray
    valence_arousal: np.ndarray
    variant: int = 0

    @property
    def dataset(self) -> str:
        """The data set's name among the training clips' (never a real one)."""
        return "synthetic"


def _on_grid(values: np.ndarray, fps: float, frames: int, out_fps: float) -> np.ndarray:
    """``(frames, K)`` of ``(T, K)`` per-frame values at ``fps``, linear at ``out_fps``."""
    t_in = np.arange(len(values)) / fps
    t_out = np.arange(frames) / out_fps
    return np.stack([np.interp(t_out, t_in, values[:, k]) for k in range(values.shape[1])],
                    1).astype(np.float32)


def walk_clips(points: np.ndarray, fps: float, emotion: np.ndarray, va: np.ndarray,
               config: ClassifierConfig, copies: int, rng: np.random.Generator,
               sample_id: int = 0, kind: str = "constant") -> list[SynthClip]:
    """One walk and its augmented variants as training clips (module docstring).

    Args:
        points: ``(T, 21, 3)`` role positions, metres, Y up.
        fps: their frame rate.
        emotion: ``(T, C)`` emotion weights over ``config.labels`` per frame.
        va: ``(T, 2)`` valence and arousal per frame.
        config: the classifier's recipe (rate, augmentation ranges).
        copies: augmented variants besides the walk itself.
        rng: draws of the variants.
        sample_id: the walk's id, for its name.
        kind: ``constant`` or ``transition``.

    Returns:
        The clips at least ``config.min_seconds`` long (variant 0 first).
    """
    need = math.ceil(config.min_seconds * config.fps)
    tracks = [(points, fps)] + [augment(points, fps, rng, config.augment) for _ in range(copies)]
    out = []
    for k, (p, rate) in enumerate(tracks):
        feats = track_features(p, rate, config)
        if len(feats) < need:
            continue
        out.append(SynthClip(f"synthetic-{sample_id:06d}", sample_id, kind, feats,
                             _on_grid(emotion, fps, len(feats), config.fps),
                             _on_grid(va, fps, len(feats), config.fps), k))
    return out


def _roles(root: Path) -> str | None:
    """The role map the data set was made with (``--rig-roles``), or ``None``."""
    try:
        return json.loads((root / "recipe.json").read_text()).get("rig_roles")
    except (OSError, ValueError):
        return None


def synthetic_clips(root: str | Path, config: ClassifierConfig, mix: SynthMix, seed: int,
                    progress: bool = False) -> list[SynthClip]:
    """Every walk of a synthetic data set folder as training clips (module docstring).

    Args:
        root: a finished folder of ``emotive synth`` (with ``manifest.parquet``).
        config: the classifier's recipe; its ``labels`` must all be among the folder's.
        mix: how many variants per walk and how many walks (:class:`SynthMix`).
        seed: seed of the variants (with :data:`AUGMENT_STREAM`).
        progress: a progress bar on stderr.

    Returns:
        The clips, walk by walk in sample order, each walk's variants together.

    Raises:
        SynthError: no such folder, an unfinished one, or labels the classifier lacks.
    """
    root = Path(root)
    if not root.is_dir():
        raise SynthError(f"--synth {root}: no such folder; make it first with `emotive synth "
                         f"--out {root}` (or pass --make)")
    try:
        walks = SyntheticGaits(root, fields=("world", "emotion", "valence_arousal"))
    except SynthError as exc:
        raise SynthError(f"--synth {exc}") from None
    missing = [label for label in config.labels if label not in walks.labels]
    if missing or not len(walks):
        raise SynthError(f"--synth {root}: its walks carry the labels {list(walks.labels)}, "
                         f"not {missing or list(config.labels)} of the classifier; make it with "
                         "a generator of label blends (`emotive synth --model gait`)")
    columns = [walks.labels.index(label) for label in config.labels]
    skeleton = walks.motion(0).skeleton
    joints = judge_joints(skeleton, resolve_roles(skeleton, _roles(root)))
    kinds = walks.manifest.column("kind").to_pylist()
    fps = float(walks.manifest.column("fps")[0].as_py())
    copies = config.augment_copies if mix.copies is None else mix.copies
    rng = np.random.default_rng([seed, AUGMENT_STREAM])
    count = len(walks) if not mix.limit else min(mix.limit, len(walks))
    out: list[SynthClip] = []
    for i in track(range(count), description=f"synthetic walks of {root.name}",
                   disable=not progress, console=Console(stderr=True), transient=True):
        item = walks[i]
        emotion = item["emotion"].numpy()[:, columns]
        out += walk_clips(item["world"].numpy()[:, joints], fps, emotion,
                          item["valence_arousal"].numpy(), config, copies, rng,
                          int(item["sample_id"]), kinds[i])
    return shuffle_targets(out, seed) if mix.target == "shuffled" else out


def _fit(values: np.ndarray, frames: int) -> np.ndarray:
    """``values`` cut or padded with its last row to ``frames`` rows."""
    if len(values) >= frames:
        return values[:frames]
    return np.concatenate((values, np.repeat(values[-1:], frames - len(values), 0)))


def shuffle_targets(clips: Sequence[SynthClip], seed: int) -> list[SynthClip]:
    """The clips with every walk's targets taken from another walk (the control).

    Walks are permuted by a generator seeded ``[seed, SHUFFLE_STREAM]``; each clip (every
    variant) takes the ``emotion`` and ``valence_arousal`` of its partner walk's own clip
    (variant 0), cut or padded to its length (they differ by a frame at most).
    """
    own = {c.sample_id: c for c in clips if c.variant == 0}
    ids = sorted(own)
    partner = dict(zip(ids, np.random.default_rng([seed, SHUFFLE_STREAM]).permutation(ids),
                       strict=True))
    out = []
    for c in clips:
        src = own[int(partner[c.sample_id])]
        out.append(replace(c, emotion=_fit(src.emotion, len(c.features)),
                           valence_arousal=_fit(src.valence_arousal, len(c.features))))
    return out


def describe(clips: Sequence[SynthClip], labels: Sequence[str]) -> dict:
    """Counts of a list of synthetic clips: walks, clips, kinds, heaviest labels, seconds."""
    own = [c for c in clips if c.variant == 0]
    heaviest = np.bincount([int(c.emotion.mean(0).argmax()) for c in own],
                           minlength=len(labels))
    kinds: dict[str, int] = {}
    for c in own:
        kinds[c.kind] = kinds.get(c.kind, 0) + 1
    return {"walks": len(own), "clips": len(clips), "kinds": kinds,
            "heaviest_label": dict(zip(labels, map(int, heaviest), strict=True)),
            "largest_weight_mean": float(np.mean([c.emotion.max(-1).mean() for c in own]))
            if own else float("nan")}
