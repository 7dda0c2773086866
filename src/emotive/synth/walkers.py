"""One batched generator call per shard: the registry's generators as walkers of many paths.

The main paper's augmented data set is made by its own network (Bhattacharya et al. 2020,
section 5.2): gaits on new trajectories and with new emotions and transitions, which the
network makes "at test time" because it follows any trajectory and any emotion vector. A
walker makes the walks of one shard at once; it is chosen by what the registry's generator
is (:func:`load_walker`):

* the gait network and its ablations (a generator holding a gait model):
  :class:`GaitWalker`, every walk of the shard one agent of one
  :class:`~emotive.models.gait.generate.GaitGenerator` stepped in one batch, planted feet
  held in the stream as ``emotive generate`` holds them;
* the FCRBM (a generator driven by valence and arousal that holds an FCRBM): the
  FCRBM's streaming counterpart, :class:`~emotive.models.fcrbm.stream.FCRBMStream`, imported
  by name as the server does, every walk one agent on its path;
* any other generator (the LGB): :class:`RequestWalker`, one
  :class:`~emotive.models.api.GenerationRequest` per walk through the model contract; a
  generator without paths walks freely (no path is recorded), one of single labels walks the
  heaviest label of each blend.

Every walk takes its own seed (from the recipe's seed and its sample index), so nothing
depends on where in the batch a walk sits other than the batch itself, which the shard fixes.

Legend: ``N`` walks, ``T`` frames, ``J`` joints, ``C`` labels (happy, sad, angry, neutral).
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.data.emotion import coerce_emotion, valence_arousal
from emotive.models.api import GenerationRequest
from emotive.models.gait.generate import GaitGenerator
from emotive.models.registry import ModelError, get_model, model_names
from emotive.paths import GroundPath
from emotive.synth.emotions import LABELS
from emotive.synth.recipe import SynthError

#: Module of the FCRBM's streaming generator, imported only when the FCRBM is chosen.
FCRBM_STREAM = "emotive.models.fcrbm.stream"


@dataclass(frozen=True, eq=False)
class WalkBatch:
    """The walks of one shard.

    Attributes:
        skeleton: the rig of every walk.
        fps: frames per second.
        rotations: ``(N, T, J, 4)`` local rotations ``(w, x, y, z)``.
        positions: ``(N, T, J, 3)`` local translations, metres (the root's its world position).
        emotion: ``(N, T, C)`` emotion weights over :data:`~emotive.synth.emotions.LABELS`.
        valence_arousal: ``(N, T, 2)`` valence and arousal, -1..1.
        paths: the path each walk followed, or ``None`` for a walk that followed none.
    """

    skeleton: Skeleton
    fps: float
    rotations: np.ndarray
    positions: np.ndarray
    emotion: np.ndarray
    valence_arousal: np.ndarray
    paths: tuple[GroundPath | None, ...]

    def motion(self, k: int, name: str) -> Motion:
        """Walk ``k`` as a :class:`~emotive.core.motion.Motion` named ``name``."""
        return Motion(self.skeleton, self.rotations[k], self.positions[k], self.fps,
                      {"name": name})


def on_labels(weights: np.ndarray, labels: Sequence[str]) -> np.ndarray:
    """``(..., C)`` the columns of ``weights`` ``(..., L)`` over ``labels`` that are LABELS.

    Renormalized to sum to one (the synthetic emotions weigh nothing elsewhere); a row with
    no weight on them (a model's other style) stays zero.
    """
    index = [list(labels).index(label) for label in LABELS]
    picked = np.asarray(weights, dtype=np.float64)[..., index]
    total = picked.sum(-1, keepdims=True)
    return np.divide(picked, total, out=np.zeros_like(picked), where=total > 0)


@dataclass
class GaitWalker:
    """Walks of the gait network, every walk one agent of one batched generator.

    Attributes:
        model: the gait model (:class:`~emotive.models.gait.model.GaitModel`).
        foot_lock: hold planted feet in the stream.
        point: whether emotions are valence/arousal points (no: blends).
        follows_paths: whether walks follow their paths.
    """

    model: Any
    foot_lock: bool = True
    point: bool = False
    follows_paths: bool = True

    def walk(self, paths: Sequence[GroundPath], keyframes: Sequence[list[dict]],
             seeds: Sequence[int], seconds: float) -> WalkBatch:
        """The walks, one per (path, keyframes, seed), ``seconds`` long, stepped in one batch."""
        gen = GaitGenerator(self.model, seed=0, foot_lock=self.foot_lock)
        gen.add_agents(list(paths), [list(k) for k in keyframes], seeds=list(seeds))
        frames = [gen.first_frame()]
        frames += [gen.step() for _ in range(max(1, round(seconds * gen.fps)))]
        emotion = on_labels(np.stack([f.emotion for f in frames], 1), gen.labels)
        return WalkBatch(self.model.controls.skeleton, float(gen.fps),
                         np.stack([f.rotations for f in frames], 1),
                         np.stack([f.positions for f in frames], 1), emotion,
                         valence_arousal(emotion, LABELS), tuple(paths))


@dataclass
class StreamWalker:
    """Walks of the FCRBM's stream, every walk one agent on its path.

    Attributes:
        model: the FCRBM model.
        gibbs: Gibbs iterations per frame (``None``: the model's).
        point: whether emotions are valence/arousal points (yes).
        follows_paths: whether walks follow their paths.
    """

    model: Any
    gibbs: int | None = None
    point: bool = True
    follows_paths: bool = True

    def walk(self, paths: Sequence[GroundPath], keyframes: Sequence[list[dict]],
             seeds: Sequence[int], seconds: float) -> WalkBatch:
        """The walks, one per (path, keyframes, seed), ``seconds`` long, stepped in one batch."""
        stream = importlib.import_module(FCRBM_STREAM).FCRBMStream(self.model, seed=0,
                                                                    gibbs=self.gibbs)
        stream.add_agents(list(paths), [list(k) for k in keyframes], seeds=list(seeds))
        frames = [stream.step() for _ in range(max(1, round(seconds * stream.fps)) + 1)]
        emotion = on_labels(np.stack([f.emotion for f in frames], 1), stream.labels)
        return WalkBatch(stream.skeleton, float(stream.fps),
                         np.stack([f.rotations for f in frames], 1),
                         np.stack([f.positions for f in frames], 1), emotion,
                         np.stack([f.valence_arousal for f in frames], 1), tuple(paths))


@dataclass
class RequestWalker:
    """Walks of any registry generator, one request each (the model contract).

    Attributes:
        generator: a :class:`~emotive.models.api.Generator`.
        point: whether emotions are valence/arousal points.
        follows_paths: whether walks follow their paths.
    """

    generator: Any
    point: bool = field(init=False)
    follows_paths: bool = field(init=False)

    def __post_init__(self) -> None:
        caps = self.generator.capabilities
        self.point = bool(caps.valence_arousal)
        self.follows_paths = bool(caps.paths)

    def walk(self, paths: Sequence[GroundPath], keyframes: Sequence[list[dict]],
             seeds: Sequence[int], seconds: float) -> WalkBatch:
        """The walks, one request each, cut to the shortest."""
        gen = self.generator
        made = []
        for k, (path, frames, seed) in enumerate(zip(paths, keyframes, seeds, strict=True)):
            schedule = coerce_emotion(self._emotion(frames), gen.labels)
            request = GenerationRequest(f"walk-{k}", schedule, seconds,
                                        path if self.follows_paths else None, int(seed))
            made.append(gen.generate(request))
        t = min(g.motion.num_frames for g in made)
        emotion = on_labels(np.stack([g.emotion[:t] for g in made]), made[0].labels)
        return WalkBatch(made[0].motion.skeleton, float(made[0].motion.fps),
                         np.stack([g.motion.rotations[:t] for g in made]),
                         np.stack([g.motion.positions[:t] for g in made]), emotion,
                         valence_arousal(emotion, LABELS),
                         tuple(g.path for g in made) if self.follows_paths
                         else (None,) * len(made))

    def _emotion(self, frames: list[dict]) -> Any:
        """The keyframes, or the heaviest label of the first for a generator of single labels."""
        if self.generator.capabilities.blends or "emotion" not in frames[0]:
            return frames
        weights = frames[0]["emotion"]
        return max(weights, key=weights.get)


def load_walker(model: str) -> GaitWalker | StreamWalker | RequestWalker:
    """The walker of registry generator ``model`` with its default weights.

    Raises:
        ModelError: an unknown model, or one that is no generator (naming the generators).
    """
    entry = get_model(model)
    if "generator" not in entry.kinds:
        raise ModelError(f"--model {model}: it makes no new motion (it is a "
                         f"{', '.join(entry.kinds)}); use one of "
                         f"{', '.join(model_names('generator'))}")
    generator = entry.load("generator")
    held = getattr(generator, "model", None)
    if getattr(held, "controls", None) is not None:
        return GaitWalker(held, foot_lock=getattr(generator, "foot_lock", True))
    if generator.capabilities.valence_arousal and getattr(held, "codec", None) is not None:
        return StreamWalker(held, gibbs=getattr(generator, "gibbs", None))
    return RequestWalker(generator)


def check_walker(walker: GaitWalker | StreamWalker | RequestWalker, model: str,
                 transitions: int, seconds: float) -> None:
    """Raise :class:`SynthError` for a recipe the walker cannot make.

    Raises:
        SynthError: transitions for a generator of constant emotions, or walks longer than
            it makes.
    """
    if isinstance(walker, RequestWalker):
        caps = walker.generator.capabilities
        if transitions and not caps.schedules:
            raise SynthError(f"--transitions {transitions}: model {model!r} makes one constant "
                             "emotion per walk; give --transitions 0 or another --model")
        if seconds > caps.max_seconds:
            raise SynthError(f"--seconds {seconds:g}: model {model!r} makes at most "
                             f"{caps.max_seconds:g} s; give a shorter walk")
