"""Animation with the gait network: many agents stepped in one batch, following paths.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``C`` emotion labels, ``T`` frames.

:class:`GaitGenerator` is the streaming API. Each :meth:`~GaitGenerator.step` advances every
agent by one frame with a single batched call of :meth:`GaitNetwork.step
<emotive.models.gait.network.GaitNetwork.step>`, carrying each agent's GRU state from frame to
frame (the original implementation re-ran the network over a whole input window for every new
frame, one agent at a time). Agents can be added and removed, and their emotion and path
changed, between steps.

Per agent and frame:

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

Starts. By default an agent starts from the built-in standing pose (a statistic of the
training data kept in the checkpoint), held for :data:`WARMUP_FRAMES` frames to settle the GRU,
so no data set is needed; or from a primer clip on the model's rig, whose frames are run
through the network first. Predicted values are clamped to plausible ranges and a non-finite
prediction keeps the previous pose, so the output never holds NaN.

Files. :func:`~emotive.models.gait.walks.generate_walks` (behind ``emotive generate``) also
cleans up foot contacts after the fact; the streaming generator returns the network's raw
frames.

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
from emotive.core.roles import resolve_roles
from emotive.data.emotion import EmotionLike, EmotionSchedule
from emotive.errors import PathError
from emotive.features.movement import LOWPASS_HZ
from emotive.ik.foot_lock import initial_lock_state, leg_rig, lock_feet
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.agent_inputs import check_pace, to_model_schedule
from emotive.models.gait.agents import AgentBatch, empty_batch, joined, kept
from emotive.models.gait.controls import MIN_TURN_FACTOR
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs, same_hemisphere
from emotive.models.gait.primer import primer_features
from emotive.paths import GroundPath, waypoints
from emotive.paths.bank import PathBank
from emotive.transforms.kinematics import PoseFK
from emotive.transforms.rotations import quaternion_multiply, yaw_quaternion

#: Frames of the standing start fed to the network before the first step.
WARMUP_FRAMES = 10
#: Distance (metres) before the end of an open path over which the agent slows to a stop.
STOP_DISTANCE = 1.0
#: Curvature (1/m) from which ``delta`` turns the body fully to the inside of a turn.
FULL_TURN_CURVATURE = 0.2
#: Metres of the gap to a new path (:meth:`GaitGenerator.set_path`) closed per metre walked:
#: the agent merges onto it at about 27 degrees.
PATH_MERGE_SLOPE = 0.5
#: Clamps of the predicted root features, ``(low, high)``: height in metres, speed in metres
#: per second.
HEIGHT_RANGE = (-0.6, 0.4)
MAX_SPEED = 8.0
#: A "go to" target nearer than this (metres) stops the agent where it stands.
MIN_TARGET_DISTANCE = 0.05
#: A "go to" path leaves along the agent's heading for up to this many metres.
TARGET_LEAD = 0.75


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
        dtype: float type of the network.
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

    Example::

        gen = GaitGenerator(load_gait_model())
        a = gen.add_agent(figure8(), "happy=0.7,neutral=0.3")
        for _ in range(300):
            frame = gen.step()      # frame.world[0]: agent a's joints
        gen.set_emotion(a, "sad")
    """

    def __init__(self, model: GaitModel, seed: int = 0, dtype: torch.dtype = torch.float32,
                 threads: int = 1, foot_lock: bool = True, network: Any = None) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.threads = int(threads)
        self.model = model
        self.seed = int(seed)
        self.dtype = dtype
        net = model.network.to(dtype).eval() if network is None else network
        self.network = net
        c = model.controls
        self.labels = model.labels
        self.fps = model.fps
        self._freq = torch.as_tensor(c.step_frequency, dtype=torch.float64)
        self._speed = torch.as_tensor(c.speed, dtype=torch.float64)
        sk = c.skeleton
        self._fk = PoseFK(sk.parents, c.standing_positions, sk.end_site_parents,
                          sk.end_site_offsets, dtype)
        self._roles = resolve_roles(c.skeleton)
        standing = self._fk(torch.as_tensor(c.standing_rotations, dtype=dtype)[None])[0]
        self._legs = leg_rig(sk, self._roles, standing.double().numpy()) if foot_lock else None
        self._local = torch.as_tensor(c.standing_positions, dtype=dtype)
        # Joints above the mover stay at the identity (as in the data): the network's
        # prediction for them is discarded, so the mover alone places the body.
        above, j = [], int(c.skeleton.parents[c.mover])
        while j >= 0:
            above.append(j)
            j = int(c.skeleton.parents[j])
        self._above = torch.as_tensor(above, dtype=torch.long)
        # World height of the mover = base + h.
        self._base = float(c.standing_positions[c.mover, 1] - c.standing_height)
        self._alpha = 1.0 - math.exp(-2.0 * math.pi * LOWPASS_HZ / self.fps)
        self._next_id = 0
        self._agents: dict[int, _Agent] = {}
        self._order: list[int] = []
        self._paths = PathBank()
        self._batch = empty_batch(net.initial_state(0, dtype=dtype), c.skeleton.num_joints,
                                  len(self.labels), dtype)

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order."""
        return tuple(self._order)

    def __len__(self) -> int:
        return len(self._order)

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
        with torch_threads(self.threads):
            if primer is None:
                phases = np.array([
                    np.random.default_rng([self.seed, a] if seeds is None else [int(seeds[k])])
                    .uniform(0.0, 2.0 * math.pi) for k, a in enumerate(ids)])
                state, rot, root, affective, theta, slp = self._standing_start(m, phases)
            else:
                state, rot, root, affective, theta, slp = self._primer_start(primer, m)
        slots = [self._paths.add(path) for path in paths]
        self._next_id += n
        for a, path, sch in zip(ids, paths, schedules, strict=True):
            self._agents[a] = _Agent(path, sch, 0.0, len(sch.times) == 1)
        self._order.extend(ids)
        arc = np.asarray(starts, dtype=np.float64)
        heading = np.array([float(p.heading(float(s))) for p, s in zip(paths, arc, strict=True)])
        new = AgentBatch(
            state, rot, root, affective, m, theta, slp, arc, np.zeros(n), np.zeros(n),
            np.zeros(n), heading, np.zeros((n, 2)), np.array(slots, dtype=np.int64),
            np.array(paces), self._paths.curvature(np.array(slots, dtype=np.int64), arc),
            *initial_lock_state(n),
        )
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
        (:data:`PATH_MERGE_SLOPE`).

        Raises:
            KeyError: unknown agent. PathError: not a path.
        """
        if not isinstance(path, GroundPath):
            raise PathError(f"an agent needs a GroundPath to follow, got {type(path).__name__}")
        k = self._index(agent)
        here = self._ground_position(k)
        arc, _ = path.nearest(here[None])
        self._follow(agent, k, path, float(arc[0]), here - path.position(float(arc[0])))

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
        here = self._ground_position(k)
        yaw = float(self._batch.heading[k])
        facing = np.array([math.sin(yaw), math.cos(yaw)])
        gap = float(np.linalg.norm(target - here))
        if gap < MIN_TARGET_DISTANCE:
            path = GroundPath.from_polyline(np.stack((here, here + 0.01 * facing)), name="target")
        else:
            lead = here + min(TARGET_LEAD, 0.4 * gap) * facing
            path = waypoints(np.stack((here, lead, target)), name="target")
        self._follow(agent, k, path, 0.0, np.zeros(2))
        return path

    def set_pace(self, agent: int, pace: float) -> None:
        """Walk an agent faster or slower than its emotion does, by ``pace`` (0.5-1.5).

        Raises:
            KeyError: unknown agent. ValueError: ``pace`` outside
            :data:`~emotive.models.gait.agent_inputs.PACE_RANGE`.
        """
        k = self._index(agent)
        self._batch.pace[k] = check_pace(pace)

    def _ground_position(self, k: int) -> np.ndarray:
        """``(2,)`` where agent ``k`` (batch index) stands, path gap included."""
        b = self._batch
        return self._paths.position(b.slot[k:k + 1], b.arc[k:k + 1])[0] + b.offset[k]

    def _follow(self, agent: int, k: int, path: GroundPath, arc: float, offset: np.ndarray
                ) -> None:
        """Put agent ``agent`` (batch index ``k``) on ``path`` at ``arc`` with a gap ``offset``."""
        b = self._batch
        self._paths.release(int(b.slot[k]))
        b.slot[k] = self._paths.add(path)
        b.arc[k] = arc
        b.offset[k] = offset
        b.curvature[k] = self._paths.curvature(b.slot[k:k + 1], b.arc[k:k + 1])[0]
        self._agents[agent].path = path

    def _index(self, agent: int) -> int:
        try:
            return self._order.index(agent)
        except ValueError:
            raise KeyError(f"no live agent with id {agent}; live agents: {self._order}") from None

    # ----------------------------------------------------------------------------- starts

    def _affective_of(self, rot: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """World positions ``(..., J + E, 3)`` of canonical poses and their affective features."""
        pos = self._fk(rot.reshape(-1, *rot.shape[-2:])).reshape(*rot.shape[:-2], -1, 3)
        return pos, gait_affective(pos, self._roles)

    @torch.no_grad()
    def _standing_start(self, m: np.ndarray, theta: np.ndarray) -> tuple:
        """Network state after :data:`WARMUP_FRAMES` standing frames, for ``(N, C)`` emotions."""
        c = self.model.controls
        n, k = len(m), WARMUP_FRAMES - 1
        rot = torch.as_tensor(c.standing_rotations, dtype=self.dtype)
        _, affective = self._affective_of(rot)
        root = torch.tensor([c.standing_height, 0.0, 0.0], dtype=self.dtype)
        movement = torch.zeros(n, k, 5, dtype=self.dtype)
        movement[..., 0] = torch.as_tensor(np.sin(theta), dtype=self.dtype)[:, None]
        movement[..., 1] = torch.as_tensor(np.cos(theta), dtype=self.dtype)[:, None]
        inputs = GaitInputs(
            rot.expand(n, k, -1, -1), affective.expand(n, k, -1),
            torch.as_tensor(m, dtype=self.dtype), movement, root.expand(n, k, -1),
        )
        _, state = self.network(inputs)
        return (state, rot.expand(n, -1, -1).clone(), root.expand(n, -1).clone(),
                affective.expand(n, -1).clone(), np.asarray(theta, dtype=np.float64),
                np.zeros(n))

    @torch.no_grad()
    def _primer_start(self, primer: Motion, m: np.ndarray) -> tuple:
        """Network state after the primer's frames, for ``(N, C)`` emotions."""
        f = primer_features(primer, self.model.controls)
        n = len(m)

        def t(x: np.ndarray) -> torch.Tensor:
            x = torch.as_tensor(x, dtype=self.dtype)
            return x.expand(n, *x.shape).clone()

        inputs = GaitInputs(t(f["rotations"][:-1]), t(f["affective"][:-1]),
                            torch.as_tensor(m, dtype=self.dtype), t(f["movement"][:-1]),
                            t(f["root"][:-1]))
        _, state = self.network(inputs)
        theta = math.atan2(f["movement"][-1, 0], f["movement"][-1, 1])
        return (state, t(f["rotations"][-1]), t(f["root"][-1]), t(f["affective"][-1]),
                np.full(n, theta), np.full(n, float(f["movement"][-1, 3])))

    # ----------------------------------------------------------------------------- stepping

    def _update_emotions(self) -> None:
        b = self._batch
        for k, agent in enumerate(self._order):
            info = self._agents[agent]
            if not info.constant:
                b.emotion[k] = info.schedule.at(b.clock[k] - info.schedule_start)

    def _turn_factor(self, curvature: np.ndarray) -> np.ndarray:
        """``(B,)`` the data's slowing in turns at each agent's curvature ``(B,)`` (1/m)."""
        slowing = self.model.controls.turn_slowing
        if slowing <= 0:
            return np.ones(len(curvature))
        return np.maximum(1.0 - slowing * np.abs(curvature), MIN_TURN_FACTOR)

    def step(self) -> GaitFrame:
        """Advance every agent by one frame (``1 / fps`` seconds) and return the new frame."""
        with torch_threads(self.threads), torch.no_grad():
            return self._step()

    def _step(self) -> GaitFrame:
        b, bank = self._batch, self._paths
        dt = 1.0 / self.fps
        m = torch.as_tensor(b.emotion, dtype=torch.float64)
        omega = (m @ self._freq).numpy() * np.sqrt(b.pace)
        target = (m @ self._speed).numpy() * b.pace
        # Slow to a stop before the end of an open path.
        remaining = np.where(bank.closed(b.slot), np.inf, bank.length(b.slot) - b.arc)
        target = (target * np.clip(remaining / STOP_DISTANCE, 0.0, 1.0)
                  * self._turn_factor(b.curvature))
        slp = b.speed_lowpass
        moving = np.where(target > 1e-9, np.clip(slp / np.maximum(target, 1e-9), 0, 1), 0)
        moving = np.where(remaining > STOP_DISTANCE, 1.0, moving)
        omega = omega * moving
        movement = np.stack((np.sin(b.theta), np.cos(b.theta), omega, slp, b.kappa), 1)
        inputs = GaitInputs(
            b.rotations, b.affective if self.network.config.use_affective else None,
            m.to(self.dtype), torch.as_tensor(movement, dtype=self.dtype), b.root,
        )
        out, state = self.network.step(inputs, b.state)
        rot = out.rotations
        finite = torch.isfinite(rot).all(-1).all(-1) & torch.isfinite(out.root).all(-1)
        rot = torch.where(finite[:, None, None], same_hemisphere(rot, b.rotations), b.rotations)
        rot[:, self._above] = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=self.dtype)
        root = torch.where(finite[:, None], out.root, b.root)
        state = torch.where(finite[None, :, None], state, b.state)
        h = root[:, 0].clamp(*HEIGHT_RANGE)
        s_pf = root[:, 1].clamp(0.0, MAX_SPEED / self.fps)
        delta = root[:, 2].clamp(0.0, math.pi)
        root = torch.stack((h, s_pf, delta), 1)
        s_np, delta_np = s_pf.double().numpy(), delta.double().numpy()
        # Controls and placement along the paths, every agent at once.
        arc = b.arc + np.minimum(s_np, np.maximum(remaining, 0.0))
        curvature = bank.curvature(b.slot, arc)
        side = np.clip(curvature / FULL_TURN_CURVATURE, -1.0, 1.0)
        delta_lp = b.delta + self._alpha * (delta_np - b.delta)
        gap = np.linalg.norm(b.offset, axis=1)
        shrink = np.maximum(gap - PATH_MERGE_SLOPE * s_np, 0.0) / np.maximum(gap, 1e-12)
        offset = b.offset * shrink[:, None]
        world_canon, affective = self._affective_of(rot)
        self._batch = b.with_values(
            state=state, rotations=rot, root=root, affective=affective,
            theta=np.mod(b.theta + omega, 2.0 * math.pi),
            speed_lowpass=slp + self._alpha * (target - slp), arc=arc, delta=delta_lp,
            clock=b.clock + dt, kappa=s_np ** 2 * np.abs(curvature),
            heading=bank.heading(b.slot, arc) + side * delta_lp, offset=offset,
            curvature=curvature,
        )
        self._update_emotions()
        xz = bank.position(b.slot, arc) + offset
        frame = self._frame(rot, world_canon, h, xz)
        if self._legs is None:
            return frame
        rotations, world, feet = lock_feet(self._legs, self._batch.feet, frame.rotations,
                                           frame.world, s_np * self.fps, self.fps)
        self._batch = self._batch.with_feet(feet)
        return frame._replace(rotations=rotations, world=world)

    @torch.no_grad()
    def first_frame(self) -> GaitFrame:
        """The agents' current frame before any step.

        The agents' current frame before any step (the standing pose or the primer's last
        frame placed on the path), so that a clip can start where the agents stand.
        """
        b = self._batch
        xz = self._paths.position(b.slot, b.arc) + b.offset
        world_canon, _ = self._affective_of(b.rotations)
        return self._frame(b.rotations, world_canon, b.root[:, 0], xz)

    def _frame(self, rot: torch.Tensor, world_canon: torch.Tensor, h: torch.Tensor,
               xz: np.ndarray) -> GaitFrame:
        """Canonical poses placed in the world: yaw about Y, then ground position and height.

        Args:
            rot: ``(B, J, 4)`` heading-canonical local rotations.
            world_canon: ``(B, J + E, 3)`` their positions with the mover over the origin.
            h: ``(B,)`` root height features.
            xz: ``(B, 2)`` ground positions.
        """
        mv = self.model.controls.mover
        rotations = rot.clone()
        rotations[:, mv] = quaternion_multiply(
            yaw_quaternion(torch.as_tensor(self._batch.heading, dtype=self.dtype)), rot[:, mv])
        positions = self._local.expand(len(rot), -1, -1).clone()
        height = self._base + h
        positions[:, mv, 0] = torch.as_tensor(xz[:, 0], dtype=self.dtype)
        positions[:, mv, 1] = height
        positions[:, mv, 2] = torch.as_tensor(xz[:, 1], dtype=self.dtype)
        world = _place(world_canon.double().numpy(), self._batch.heading, xz,
                       (height - self._local[mv, 1]).double().numpy())
        return GaitFrame(tuple(self._order), rotations.double().numpy(),
                         positions.double().numpy(), world, self._batch.emotion.copy(), xz)


def _place(canonical: np.ndarray, heading: np.ndarray, xz: np.ndarray, lift: np.ndarray
           ) -> np.ndarray:
    """``(B, P, 3)`` canonical points turned, moved and raised.

    ``(B, P, 3)`` canonical points turned by ``heading`` about Y, moved to ``xz`` and
    raised by ``lift``.
    """
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    x, y, z = canonical[..., 0], canonical[..., 1], canonical[..., 2]
    return np.stack((c * x + s * z + xz[:, :1], y + lift[:, None], -s * x + c * z + xz[:, 1:]),
                    -1)
