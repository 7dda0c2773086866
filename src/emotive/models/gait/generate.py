"""Animation with the gait network: many agents stepped in one batch, following paths.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``C`` emotion labels, ``T`` frames.

:class:`GaitGenerator` is the streaming API. Each :meth:`~GaitGenerator.step` advances every
agent by one frame with a single batched call of :meth:`GaitNetwork.step
<emotive.models.gait.network.GaitNetwork.step>`, carrying each agent's GRU state from frame to
frame (the original implementation re-ran the network over a whole input window for every new
frame, one agent at a time). Agents can be added and removed, and their emotion and path
changed, between steps.

Per agent and frame, one call of :class:`~emotive.models.gait.step_graph.AgentStep` (the
module that :mod:`~emotive.models.gait.step_export` exports as one ONNX graph) does:

1. The network reads the current pose (heading-canonical local rotations, as in training), the
   18 affective features of that pose, the emotion ``m`` at the agent's clock, the movement
   controls ``[sin theta, cos theta, omega, s_lowpass, kappa]`` and the current root features
   ``[h, s, delta]``, and predicts the next pose and root features.
2. Controls. The stepping phase advances by ``omega``, the emotion-weighted walking step
   frequency of the training data (:mod:`~emotive.models.gait.controls`); ``s_lowpass``
   follows the emotion-weighted walking speed through a one-pole low-pass at
   :data:`~emotive.features.movement.LOWPASS_HZ` (so a start accelerates as in the data);
   the target speed is lowered in turns as the data's walkers slow (``1 - turn_slowing |k|``,
   :mod:`~emotive.models.gait.controls`);
   ``kappa = s^2 |k|`` with ``k`` the path's curvature under the agent, the paper's
   ``|tau_t - tau_{t-1}|`` of a point moving at ``s`` metres per frame along it.
3. Path following. The agent advances along the path's arc length by the predicted speed
   ``s`` (so it slows where the network slows, in sharp turns or sad walks), stands on the
   path, and faces along the path's tangent turned by the predicted ``delta`` towards the
   inside of the turn (``delta`` is unsigned; the side is the sign of the curvature, faded out
   on straight stretches), low-passed like ``s_lowpass``. Its height is the standing height
   plus the predicted ``h``. Near the end of an open path the target speed falls to zero and
   the agent stops.
4. The pose is placed in the world: the mover joint (the hips) gets the heading and position,
   every other joint keeps the predicted local rotation, except the joints above the mover
   (the Bandai file root ``joint_Root``), which stay at the identity as in the data.

5. Planted feet are held by the causal foot lock (:mod:`emotive.ik.foot_lock`).

The generator itself is the step's host, as an engine would be: it keeps each agent's arc
length, path, emotion schedule and pace, samples each path around its agent
(:meth:`PathBank.ahead <emotive.paths.bank.PathBank.ahead>`, in the agent's frame) and feeds
the step's state back.

Starts. By default an agent starts from the built-in standing pose (a statistic of the
training data kept in the checkpoint), held for :data:`WARMUP_FRAMES` frames to settle the GRU
(the step's start mode), so no data set is needed; or from a primer clip on the model's rig,
whose frames are run through the network first. Predicted values are clamped to plausible
ranges and a non-finite prediction keeps the previous pose, so the output never holds NaN.

Files. :func:`~emotive.models.gait.walks.generate_walks` (behind ``emotive generate``) also
cleans up foot contacts after the fact (with the future known); the streaming generator holds
planted feet causally, frame by frame.

Randomness. The network is deterministic; the seed draws each agent's starting stepping phase,
which sets which foot leads and the timing of steps.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.data.emotion import EmotionLike, EmotionSchedule
from emotive.errors import PathError
from emotive.models.gait.agent_inputs import check_pace, to_model_schedule
from emotive.models.gait.agents import AgentBatch, empty_batch, joined, kept
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs
from emotive.models.gait.primer import primer_features
from emotive.models.gait.step_graph import (
    FULL_TURN_CURVATURE,
    HEIGHT_RANGE,
    MAX_SPEED,
    PATH_MERGE_SLOPE,
    STOP_DISTANCE,
    WARMUP_STEPS,
    AgentStep,
    StepOutputs,
)
from emotive.models.gait.step_path import to_agent_frame
from emotive.paths import GroundPath, waypoints
from emotive.paths.bank import PathBank

__all__ = [
    "FULL_TURN_CURVATURE", "HEIGHT_RANGE", "MAX_SPEED", "MIN_TARGET_DISTANCE",
    "PATH_MERGE_SLOPE", "STOP_DISTANCE", "TARGET_LEAD", "WARMUP_FRAMES", "GaitFrame",
    "GaitGenerator", "to_model_schedule", "torch_threads",
]

#: Frames of the standing start: the network runs over ``WARMUP_FRAMES - 1`` of them.
WARMUP_FRAMES = WARMUP_STEPS + 1
#: A "go to" target nearer than this (metres) stops the agent where it stands.
MIN_TARGET_DISTANCE = 0.05
#: A "go to" path leaves along the agent's heading for up to this many metres.
TARGET_LEAD = 0.75
#: ``path_left`` of an agent on a loop (metres): never near an end.
LOOP_LEFT = 1e9


class GaitFrame(NamedTuple):
    """One frame of every agent, after :meth:`GaitGenerator.step`.

    Attributes:
        agents: the ``B`` agent ids, in batch order.
        rotations: ``(B, J, 4)`` local rotations, the mover's carrying the world heading.
        positions: ``(B, J, 3)`` local translations, the mover's its world position (metres).
        world: ``(B, J + E, 3)`` world positions of joints then end sites.
        emotion: ``(B, C)`` emotion of each agent at this frame.
        root: ``(B, 2)`` ground position ``(x, z)`` of each agent.
    """

    agents: tuple[int, ...]
    rotations: np.ndarray
    positions: np.ndarray
    world: np.ndarray
    emotion: np.ndarray
    root: np.ndarray


@dataclass
class _Agent:
    """Per-agent bookkeeping that is not batched."""

    path: GroundPath
    schedule: EmotionSchedule
    schedule_start: float
    constant: bool


@contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """Run the block with ``count`` torch intra-op threads, then restore the caller's count.

    A generator step is many small operations on small tensors: a second thread only adds
    synchronization (on a loaded 2-core machine 100 agents stepped 4x faster on one thread),
    so :class:`GaitGenerator` steps on one thread unless told otherwise.
    """
    before = torch.get_num_threads()
    if before != count:
        torch.set_num_threads(count)
    try:
        yield
    finally:
        if before != count:
            torch.set_num_threads(before)


class GaitGenerator:
    """Steps many agents at once with a gait model (see the module docstring).

    Args:
        model: the trained model (:func:`~emotive.models.gait.model.load_gait_model`).
        seed: seed of the agents' starting phases (agent ``k`` draws from ``seed`` and ``k``).
        dtype: float type of the step.
        threads: torch intra-op threads while stepping (:func:`torch_threads`); the
            caller's setting is restored after each call.
        foot_lock: hold planted feet still in every streamed frame
            (:mod:`emotive.ik.foot_lock`); ``False`` streams the network's raw poses.
        network: the network to step instead of the model's torch network: an object with
            the :class:`~emotive.models.gait.network.GaitNetwork` surface (``config``,
            ``initial_state``, ``step`` and a call over warm-up windows, torch tensors in
            and out), e.g. :class:`~emotive.models.gait.onnx_runtime.OnnxGaitNetwork` from
            :func:`~emotive.models.gait.onnx_runtime.load_onnx_network`; it must be the
            model's network (same config and weights). ``None``: the model's own network,
            cast to ``dtype``.
        step: the whole step to call instead of :class:`AgentStep` (same arguments and
            :class:`~emotive.models.gait.step_graph.StepOutputs`, torch tensors), e.g. the
            exported graph on ONNX Runtime (:mod:`~emotive.models.gait.step_runtime`).
        traced: run the torch step as TorchScript, traced at its first use: once for
            calls that start agents and once for walking calls, which leave the start
            selections out (:meth:`AgentStep.traced
            <emotive.models.gait.step_graph.AgentStep.traced>`; the same numbers, less
            interpreter time); ``False`` runs it eagerly. Ignored with ``network`` or
            ``step``.

    Example::

        gen = GaitGenerator(load_gait_model())
        a = gen.add_agent(figure8(), "happy=0.7,neutral=0.3")
        for _ in range(300):
            frame = gen.step()      # frame.world[0]: agent a's joints
        gen.set_emotion(a, "sad")
    """

    def __init__(self, model: GaitModel, seed: int = 0, dtype: torch.dtype = torch.float32,
                 threads: int = 1, foot_lock: bool = True, network: Any = None,
                 step: Any = None, traced: bool = True) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.threads = int(threads)
        self.model = model
        self.seed = int(seed)
        self.dtype = dtype
        self.graph = AgentStep(model, dtype, foot_lock=foot_lock, network=network)
        self.network = self.graph.network
        self._step_fn = self.graph if step is None else step
        # Traced lazily, once for calls that start agents and once for walking calls only.
        self._traces: dict[bool, Any] = {} if (traced and step is None and network is None) \
            else {False: None, True: None}
        self.labels = model.labels
        self.fps = model.fps
        self._offsets = self.graph.sampling.offsets()
        self._local = np.asarray(model.controls.standing_positions, dtype=np.float64)
        self._next_id = 0
        self._agents: dict[int, _Agent] = {}
        self._order: list[int] = []
        self._where: dict[int, int] | None = None
        self._paths = PathBank()
        self._batch = empty_batch(self.network.initial_state(0, dtype=dtype),
                                  self.graph.layout.size, len(self.labels), dtype)

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order."""
        return tuple(self._order)

    def __len__(self) -> int:
        return len(self._order)

    def agent_field(self, name: str) -> np.ndarray:
        """``(B, *shape)`` one field of every agent's state row, in batch order (float64).

        ``name`` is a field of :mod:`~emotive.models.gait.step_layout` (``theta``,
        ``heading``, ``lock_planted``, ...) or ``arc`` (metres along the path).

        Raises:
            KeyError: an unknown field.
        """
        if name == "arc":
            return self._batch.arc.copy()
        if name not in self.graph.layout.shapes:
            raise KeyError(f"no agent field {name!r}; fields: arc, "
                           f"{', '.join(self.graph.layout.shapes)}")
        return self.graph.layout.field(self._batch.rows, name).double().numpy().copy()

    def add_agent(
        self, path: GroundPath, emotion: EmotionLike = "neutral", primer: Motion | None = None,
        start: float = 0.0, seed: int | None = None, pace: float = 1.0,
    ) -> int:
        """Add an agent standing on ``path`` at arc length ``start``; returns its id.

        Args:
            path: the path to follow.
            emotion: its emotion or schedule (times from now); see :func:`to_model_schedule`.
            primer: a clip on the model's rig to start from; ``None`` for the standing start.
            start: arc length (metres) where it starts.
            seed: seed of its starting phase (default: from the generator's seed and its id).
            pace: factor on the emotion's walking speed, 0.5-1.5 (its step frequency changes
                by the square root, the rest by longer or shorter strides).

        Raises:
            EmotionError: a bad emotion. PathError: not a path. RigError: a primer on another
            rig or too short. ValueError: a pace outside
            :data:`~emotive.models.gait.agent_inputs.PACE_RANGE`.
        """
        return self.add_agents([path], [emotion], primer=primer, starts=[start],
                               seeds=None if seed is None else [seed], paces=[pace])[0]

    def add_agents(
        self, paths: Sequence[GroundPath], emotions: Sequence[EmotionLike],
        primer: Motion | None = None, starts: Sequence[float] | None = None,
        seeds: Sequence[int] | None = None, paces: Sequence[float] | None = None,
    ) -> list[int]:
        """Add many agents at once (one warm-up of the network for all); returns their ids.

        Arguments are as for :meth:`add_agent`, one entry per agent (``None``: the defaults).
        Nothing is added if any entry is bad.
        """
        n = len(paths)
        starts = [0.0] * n if starts is None else list(starts)
        paces = [check_pace(p) for p in ([1.0] * n if paces is None else paces)]
        if not (len(emotions) == len(starts) == len(paces) == n
                and (seeds is None or len(seeds) == n)):
            raise ValueError("give one emotion, start, pace and seed per path")
        for path, start in zip(paths, starts, strict=True):
            if not isinstance(path, GroundPath):
                raise PathError(f"an agent needs a GroundPath to follow, got "
                                f"{type(path).__name__}")
            if not math.isfinite(start):
                raise PathError(f"start must be a finite arc length in metres, got {start}")
        schedules = [to_model_schedule(e, self.labels) for e in emotions]
        ids = list(range(self._next_id, self._next_id + n))
        m = np.stack([sch.at(0.0) for sch in schedules]) if n else np.zeros((0, len(self.labels)))
        slots = np.array(self._paths.add_many(paths), dtype=np.int64)
        new = AgentBatch(self.network.initial_state(n, dtype=self.dtype),
                         torch.zeros(n, self.graph.layout.size, dtype=self.dtype), m,
                         np.asarray(starts, dtype=np.float64), np.zeros(n), slots,
                         np.asarray(paces, dtype=np.float64))
        try:
            with torch_threads(self.threads), torch.inference_mode():
                phases = np.array([
                    np.random.default_rng([self.seed, a] if seeds is None else [int(seeds[k])])
                    .uniform(0.0, 2.0 * math.pi) for k, a in enumerate(ids)])
                for _ in range(WARMUP_STEPS):
                    out = self._call(new, np.ones(n), phases)
                    new = new.with_values(state=out.recurrent, rows=out.agent)
                if primer is not None:
                    new = self._primed(new, primer)
        except Exception:
            for slot in slots:
                self._paths.release(int(slot))
            raise
        self._next_id += n
        for a, path, sch in zip(ids, paths, schedules, strict=True):
            self._agents[a] = _Agent(path, sch, 0.0, len(sch.times) == 1)
        self._order.extend(ids)
        self._where = None
        self._batch = joined(self._batch, new)
        return ids

    def remove_agent(self, agent: int) -> None:
        """Remove an agent.

        Raises:
            KeyError: no live agent has that id.
        """
        k = self._index(agent)
        self._paths.release(int(self._batch.slot[k]))
        self._batch = kept(self._batch, np.delete(np.arange(len(self._order)), k))
        del self._order[k]
        del self._agents[agent]
        self._where = None

    def set_emotion(self, agent: int, emotion: EmotionLike) -> None:
        """Give an agent a new emotion or schedule; a schedule's time 0 is now.

        Raises:
            KeyError: unknown agent. EmotionError: a bad emotion.
        """
        k = self._index(agent)
        schedule = to_model_schedule(emotion, self.labels)
        self._agents[agent] = _Agent(self._agents[agent].path, schedule,
                                     float(self._batch.clock[k]), len(schedule.times) == 1)
        self._batch.emotion[k] = schedule.at(0.0)

    def set_path(self, agent: int, path: GroundPath) -> None:
        """Send an agent along another path from its nearest point.

        The agent does not jump: the gap to the new path closes as it walks
        (:data:`PATH_MERGE_SLOPE`). For many agents at once, :meth:`set_paths`.

        Raises:
            KeyError: unknown agent. PathError: not a path.
        """
        self.set_paths([agent], [path])

    def set_paths(self, agents: Sequence[int], paths: Sequence[GroundPath]) -> None:
        """Send each of ``agents`` along its entry of ``paths``, from its nearest point.

        The same as :meth:`set_path` for each pair in turn (an agent named twice takes its
        last path), in one batch: the paths enter the path bank together
        (:meth:`PathBank.add_many <emotive.paths.bank.PathBank.add_many>`) and the nearest
        points are found over all of them at once (:meth:`PathBank.nearest
        <emotive.paths.bank.PathBank.nearest>`), so a crowd that gives every agent a new
        path each frame pays a few array operations, not a few per agent.

        Raises:
            ValueError: not one path per agent. KeyError: an unknown agent. PathError: not a
            path. Nothing is changed when any of these is raised.
        """
        if len(agents) != len(paths):
            raise ValueError(f"set_paths: give one path per agent, got {len(agents)} agents "
                             f"and {len(paths)} paths")
        for path in paths:
            if not isinstance(path, GroundPath):
                raise PathError(f"an agent needs a GroundPath to follow, got "
                                f"{type(path).__name__}")
        last: dict[int, int] = {}
        for i, agent in enumerate(agents):
            last[agent] = i
        if not last:
            return
        k = np.array([self._index(a) for a in last], dtype=np.int64)
        chosen = [paths[i] for i in last.values()]
        b, bank = self._batch, self._paths
        ground = self._grounds(k)
        for slot in b.slot[k]:
            bank.release(int(slot))
        b.slot[k] = bank.add_many(chosen)
        b.arc[k] = bank.nearest(b.slot[k], ground)
        for agent, path in zip(last, chosen, strict=True):
            self._agents[agent].path = path

    def set_target(self, agent: int, xz: Sequence[float]) -> GroundPath:
        """Send an agent to a ground point ``(x, z)`` (metres) and stop it there.

        The new path is a spline from where the agent stands, leaving along its heading, to
        the target, so the agent neither jumps nor turns on the spot. A target closer than
        :data:`MIN_TARGET_DISTANCE` leaves the agent where it is, stopping.

        Returns:
            The path the agent now follows.

        Raises:
            KeyError: unknown agent. PathError: a non-finite target or one beyond
            :data:`emotive.paths.MAX_COORDINATE`.
        """
        k = self._index(agent)
        target = np.asarray(xz, dtype=np.float64).reshape(-1)
        if target.shape != (2,) or not np.isfinite(target).all():
            raise PathError(f"set_target: the target must be two finite numbers (x, z) in "
                            f"metres, got {xz!r}")
        here = self._ground(k)
        yaw = float(self.graph.layout.field(self._batch.rows[k:k + 1], "heading")[0])
        facing = np.array([math.sin(yaw), math.cos(yaw)])
        gap = float(np.linalg.norm(target - here))
        if gap < MIN_TARGET_DISTANCE:
            path = GroundPath.from_polyline(np.stack((here, here + 0.01 * facing)), name="target")
        else:
            lead = here + min(TARGET_LEAD, 0.4 * gap) * facing
            path = waypoints(np.stack((here, lead, target)), name="target")
        self._follow(agent, k, path, 0.0)
        return path

    def set_pace(self, agent: int, pace: float) -> None:
        """Walk an agent faster or slower than its emotion does, by ``pace`` (0.5-1.5).

        Raises:
            KeyError: unknown agent. ValueError: ``pace`` outside
            :data:`~emotive.models.gait.agent_inputs.PACE_RANGE`.
        """
        k = self._index(agent)
        self._batch.pace[k] = check_pace(pace)

    def _ground(self, k: int) -> np.ndarray:
        """``(2,)`` where agent ``k`` (batch index) stands."""
        return self._grounds(np.array([k]))[0]

    def _grounds(self, k: np.ndarray) -> np.ndarray:
        """``(K, 2)`` where agents ``k`` (``(K,)`` batch indices) stand, ``(x, z)`` metres."""
        columns = [self.graph.layout.slices[name].start for name in ("x", "z")]
        return self._batch.rows.numpy()[np.ix_(k, columns)].astype(np.float64)

    def _follow(self, agent: int, k: int, path: GroundPath, arc: float) -> None:
        """Put agent ``agent`` (batch index ``k``) on ``path`` at ``arc``.

        The gap between where it stands and the path is what the step closes as it walks.
        """
        b = self._batch
        self._paths.release(int(b.slot[k]))
        b.slot[k] = self._paths.add(path)
        b.arc[k] = arc
        self._agents[agent].path = path

    def _index(self, agent: int) -> int:
        """Agent ``agent``'s batch index (from a map made again after adds and removals)."""
        if self._where is None:
            self._where = {a: k for k, a in enumerate(self._order)}
        try:
            return self._where[agent]
        except KeyError:
            raise KeyError(f"no live agent with id {agent}; live agents: {self._order}") from None

    # ----------------------------------------------------------------------------- starts

    @torch.no_grad()
    def _primed(self, new: AgentBatch, primer: Motion) -> AgentBatch:
        """Started agents ``new`` continued from the primer's last frame.

        The network runs over the primer's frames from a zero state, and the agents take its
        last pose, root features, phase and speed (standing where the standing start put
        them).
        """
        f = primer_features(primer, self.model.controls)
        n, layout = len(new), self.graph.layout

        def t(x: np.ndarray) -> torch.Tensor:
            x = torch.as_tensor(x, dtype=self.dtype)
            return x.expand(n, *x.shape).clone()

        inputs = GaitInputs(t(f["rotations"][:-1]), t(f["affective"][:-1]),
                            torch.as_tensor(new.emotion, dtype=self.dtype), t(f["movement"][:-1]),
                            t(f["root"][:-1]))
        _, state = self.network(inputs)
        fields = layout.unpack(new.rows.clone())
        fields["rotations"] = t(f["rotations"][-1])
        fields["root"] = t(f["root"][-1])
        fields["affective"] = t(f["affective"][-1])
        fields["theta"] = torch.full((n,), math.atan2(f["movement"][-1, 0], f["movement"][-1, 1]),
                                     dtype=self.dtype)
        fields["speed_lowpass"] = torch.full((n,), float(f["movement"][-1, 3]), dtype=self.dtype)
        return new.with_values(state=state, rows=layout.pack(fields))

    # ----------------------------------------------------------------------------- stepping

    def _call(self, batch: AgentBatch, start: np.ndarray, phase: np.ndarray) -> StepOutputs:
        """One call of the step on ``batch``: the host's part (path samples) and the step."""
        layout, bank = self.graph.layout, self._paths
        rows = batch.rows
        xz = torch.stack((layout.field(rows, "x"), layout.field(rows, "z")), -1).double().numpy()
        heading = layout.field(rows, "heading").double().numpy()
        points = bank.ahead(batch.slot, batch.arc, self._offsets)
        left = np.where(bank.closed(batch.slot), LOOP_LEFT, bank.length(batch.slot) - batch.arc)

        def t(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.asarray(x), dtype=self.dtype)

        trace = self._trace(walking=not bool(np.any(start)))
        step = self._step_fn if trace is None else (lambda *a: StepOutputs(*trace(*a)))
        return step(batch.state, rows, t(batch.emotion), t(batch.pace),
                    t(to_agent_frame(points, xz, heading)), t(left), t(start), t(phase))

    def prepare(self) -> None:
        """Trace the torch step now rather than at its first use (about half a second).

        For a host that times its frames (a live server): the traces then do not fall in a
        frame. Nothing to do when the step runs eagerly or is not the torch step.
        """
        self._trace(walking=False)
        self._trace(walking=True)

    def _trace(self, walking: bool) -> Any:
        """The traced step for start calls or walking calls (``None``: step eagerly)."""
        if walking not in self._traces:
            try:
                self._traces[walking] = self.graph.traced(LOOP_LEFT, walking=walking)
            except (AttributeError, RuntimeError):  # a torch without TorchScript tracing
                self._traces[walking] = None
        return self._traces[walking]

    def _update_emotions(self) -> None:
        b = self._batch
        for k, agent in enumerate(self._order):
            info = self._agents[agent]
            if not info.constant:
                b.emotion[k] = info.schedule.at(b.clock[k] - info.schedule_start)

    def step(self) -> GaitFrame:
        """Advance every agent by one frame (``1 / fps`` seconds) and return the new frame."""
        # Inference mode, not only no_grad: no version counters or views tracked, a fifth
        # less time for one agent's step (the step is hundreds of small operations).
        with torch_threads(self.threads), torch.inference_mode():
            b = self._batch
            n = len(b)
            out = self._call(b, np.zeros(n), np.zeros(n))
            arc = b.arc + out.advance.double().numpy()
            self._batch = b.with_values(state=out.recurrent, rows=out.agent, arc=arc,
                                        clock=b.clock + 1.0 / self.fps)
            self._update_emotions()
            return self._frame(out.rotations, out.root_position, out.world)

    @torch.no_grad()
    def first_frame(self) -> GaitFrame:
        """The agents' current frame before any step.

        The standing pose or the primer's last frame placed where the agents stand, so that
        a clip can start there.
        """
        f = self.graph.layout.unpack(self._batch.rows)
        xz = torch.stack((f["x"], f["z"]), -1)
        rotations, root, world, _ = self.graph.pose_world(f["rotations"], f["root"][:, 0], xz,
                                                          f["heading"])
        return self._frame(rotations, root, world)

    def _frame(self, rotations: torch.Tensor, root: torch.Tensor, world: torch.Tensor
               ) -> GaitFrame:
        """The frame of placed rotations ``(B, J, 4)``, mover positions ``(B, 3)`` and points."""
        root_np = root.double().numpy()
        positions = np.repeat(self._local[None], len(root_np), 0)
        positions[:, self.graph.mover] = root_np
        return GaitFrame(tuple(self._order), rotations.double().numpy(), positions,
                         world.double().numpy(), self._batch.emotion.copy(),
                         root_np[:, [0, 2]].copy())
