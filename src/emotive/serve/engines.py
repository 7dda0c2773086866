"""One small adapter over the streaming generators the server can run.

The gait network (:class:`~emotive.models.gait.generate.GaitGenerator`, on torch or, with
``backend="onnx"``, the exported whole per-frame step on ONNX Runtime through
``emotive.models.gait.step_runtime``) and the FCRBM
(``emotive.models.fcrbm.stream.FCRBMStream``) share the methods the server calls; the
:class:`Engine` adds what the server needs beside them (the rig, the mover joint, a standing
pose for the mannequin) and steps an empty scene without calling the model. The ONNX and
FCRBM modules are imported by name only when chosen.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``C`` emotion labels.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.data.emotion import EmotionSchedule
from emotive.models.gait.agent_inputs import point_labels
from emotive.models.gait.generate import GaitFrame, GaitGenerator
from emotive.models.gait.model import GaitModel, load_gait_model
from emotive.paths import GroundPath
from emotive.serve.errors import ServeError

#: Module and class of the FCRBM's streaming generator.
FCRBM_STREAM = "emotive.models.fcrbm.stream"
#: Module and loader of the gait network's ONNX Runtime step.
GAIT_ONNX = "emotive.models.gait.step_runtime"


def _optional_module(name: str, option: str) -> Any:
    """Module ``name``, which ``option`` needs, or a :class:`ServeError` saying it is missing."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        missing = exc.name or name
        raise ServeError(f"{option} needs the module {missing}, which this installation lacks "
                         f"(the {name} part of emotive, or its extra: pip install "
                         "'emotive[serve,onnx]'); run without it") from None


class Engine:
    """A streaming generator with its rig, stepped by the simulation thread only.

    Args:
        generator: a :class:`GaitGenerator` or an ``FCRBMStream``.
        skeleton: the rig of its frames.
        mover: the joint whose local translation is the agent's world position.
        rest: a one-frame :class:`Motion` of the rig standing (the mannequin's bind pose).
        model: the model's name (``"gait"``, ``"fcrbm"``).
        backend: ``"torch"`` or ``"onnx"``.
        points_over: the labels a valence/arousal point blends
            (:func:`~emotive.data.emotion.point_emotion`; ``None``: all the labels).
    """

    def __init__(self, generator: Any, skeleton: Skeleton, mover: int, rest: Motion,
                 model: str, backend: str, points_over: Sequence[str] | None = None) -> None:
        self.generator = generator
        self.skeleton = skeleton
        self.mover = int(mover)
        self.rest = rest
        self.model = model
        self.backend = backend
        self.labels: tuple[str, ...] = tuple(generator.labels)
        self.points_over = None if points_over is None else tuple(points_over)
        self.fps = float(generator.fps)

    def __len__(self) -> int:
        return len(self.generator.agents)

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order."""
        return tuple(self.generator.agents)

    def add_agents(self, paths: Sequence[GroundPath], schedules: Sequence[EmotionSchedule],
                   starts: Sequence[float], paces: Sequence[float]) -> list[int]:
        """Add agents in one call (one warm-up of the model for all); returns their ids."""
        return list(self.generator.add_agents(list(paths), list(schedules), starts=list(starts),
                                              paces=list(paces)))

    def remove_agent(self, agent: int) -> None:
        """Remove an agent (``KeyError``: no such agent)."""
        self.generator.remove_agent(agent)

    def set_emotion(self, agent: int, schedule: EmotionSchedule) -> None:
        """Give an agent a new emotion or schedule, its time 0 now."""
        self.generator.set_emotion(agent, schedule)

    def set_path(self, agent: int, path: GroundPath) -> None:
        """Send an agent along another path from its nearest point."""
        self.generator.set_path(agent, path)

    def set_target(self, agent: int, xz: Sequence[float]) -> GroundPath:
        """Send an agent to a ground point ``(x, z)``; returns the path it now follows."""
        return self.generator.set_target(agent, xz)

    def set_pace(self, agent: int, pace: float) -> None:
        """Walk an agent faster or slower than its emotion does."""
        self.generator.set_pace(agent, pace)

    def step(self) -> GaitFrame:
        """Advance every agent one frame; an empty scene gives an empty frame (no model call)."""
        if len(self) == 0:
            j = self.skeleton.num_joints
            p = j + len(self.skeleton.end_site_parents)
            return GaitFrame((), np.zeros((0, j, 4)), np.zeros((0, j, 3)), np.zeros((0, p, 3)),
                             np.zeros((0, len(self.labels))), np.zeros((0, 2)))
        return self.generator.step()


def gait_rest(model: GaitModel) -> Motion:
    """The gait rig standing, one frame: the mannequin's bind pose."""
    c = model.controls
    return Motion(c.skeleton, np.asarray(c.standing_rotations)[None],
                  np.asarray(c.standing_positions)[None], model.fps, {"name": "mannequin"})


def _gait_engine(backend: str, seed: int) -> Engine:
    model = load_gait_model()
    c = model.controls
    step = None
    if backend == "onnx":
        step = _optional_module(GAIT_ONNX, "--backend onnx").load_agent_step(model)
    generator = GaitGenerator(model, seed=seed, step=step)
    generator.prepare()  # the traces would otherwise fall in the first measured steps
    return Engine(generator, c.skeleton, c.mover, gait_rest(model), "gait", backend,
                  point_labels(generator.labels))


def _fcrbm_engine(seed: int) -> Engine:
    stream_module = _optional_module(FCRBM_STREAM, "--model fcrbm")
    generate = importlib.import_module("emotive.models.fcrbm.generate")
    # Deferred: new agents warm up over the next ticks, a bounded number of frames each, so
    # that adding many does not stall the scene.
    stream = stream_module.FCRBMStream(generate.load_fcrbm_model(), seed=seed, deferred=True)
    skeleton = stream.skeleton
    mover = int(np.flatnonzero(np.asarray(skeleton.parents) < 0)[0])
    return Engine(stream, skeleton, getattr(stream, "mover", mover), stream.rest, "fcrbm",
                  "torch", getattr(stream, "points_over", None))


def load_engine(model: str = "gait", backend: str = "torch", seed: int = 0) -> Engine:
    """The engine of ``--model`` and ``--backend``, with its committed weights.

    Raises:
        ServeError: the FCRBM stream or the ONNX backend is not part of this installation.
        ConfigError: the committed weights are missing or corrupt.
    """
    if model == "fcrbm":
        return _fcrbm_engine(seed)
    return _gait_engine(backend, seed)
