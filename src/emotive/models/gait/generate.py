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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.core.roles import resolve_roles
from emotive.data.emotion import Emotion, EmotionSchedule, coerce_emotion
from emotive.errors import PathError, RigError
from emotive.features.movement import LOWPASS_HZ
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.controls import MIN_TURN_FACTOR
from emotive.models.gait.data import canonical_frames, clip_features
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs, same_hemisphere
from emotive.paths import GroundPath
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

EmotionLike = Emotion | EmotionSchedule | str | Mapping[str, float] | np.ndarray


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


def to_model_schedule(emotion: EmotionLike, labels: Sequence[str]) -> EmotionSchedule:
    """An emotion or schedule over the model's ``labels``.

    Accepts what :func:`~emotive.data.emotion.coerce_emotion` accepts: an :class:`Emotion`,
    an :class:`EmotionSchedule`, text such as ``"happy=0.7,neutral=0.3"`` or
    ``"valence=0.5,arousal=0.2"``, a mapping, ``(C,)`` weights over ``labels``, keyframes or a
    JSON file of them. Labels of the input that the model lacks must weigh zero.

    Raises:
        EmotionError: unknown names, negative, NaN or all-zero weights, or weight on a label
            the model was not trained with.
    """
    return coerce_emotion(emotion, labels)


class GaitGenerator:
    """Steps many agents at once with a gait model (see the module docstring).

    Args:
        model: the trained model (:func:`~emotive.models.gait.model.load_gait_model`).
        seed: seed of the agents' starting phases (agent ``k`` draws from ``seed`` and ``k``).
        dtype: float type of the network.

    Example::

        gen = GaitGenerator(load_gait_model())
        a = gen.add_agent(figure8(), "happy=0.7,neutral=0.3")
        for _ in range(300):
            frame = gen.step()      # frame.world[0]: agent a's joints
        gen.set_emotion(a, "sad")
    """

    def __init__(self, model: GaitModel, seed: int = 0, dtype: torch.dtype = torch.float32
                 ) -> None:
        self.model = model
        self.seed = int(seed)
        self.dtype = dtype
        net = model.network
        self.network = net.to(dtype).eval()
        c = model.controls
        self.labels = model.labels
        self.fps = model.fps
        self._freq = torch.as_tensor(c.step_frequency, dtype=torch.float64)
        self._speed = torch.as_tensor(c.speed, dtype=torch.float64)
        sk = c.skeleton
        self._fk = PoseFK(sk.parents, c.standing_positions, sk.end_site_parents,
                          sk.end_site_offsets, dtype)
        self._roles = resolve_roles(c.skeleton)
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
        self._groups: list[tuple[GroundPath, np.ndarray]] | None = None
        j = c.skeleton.num_joints
        self._state = net.initial_state(0, dtype=dtype)
        self._rot = torch.zeros(0, j, 4, dtype=dtype)
        self._root = torch.zeros(0, 3, dtype=dtype)
        self._affective = torch.zeros(0, 18, dtype=dtype)
        self._emotion = np.zeros((0, len(self.labels)))
        # Per-agent float64 controls: phase, s_lowpass, arc position, smoothed delta,
        # clock, curvature input, heading, path offset (x, z), stopping flag.
        self._theta = np.zeros(0)
        self._slp = np.zeros(0)
        self._arc = np.zeros(0)
        self._delta = np.zeros(0)
        self._time = np.zeros(0)
        self._kappa = np.zeros(0)
        self._heading = np.zeros(0)
        self._offset = np.zeros((0, 2))

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order."""
        return tuple(self._order)

    def __len__(self) -> int:
        return len(self._order)

    def add_agent(
        self, path: GroundPath, emotion: EmotionLike = "neutral", primer: Motion | None = None,
        start: float = 0.0, seed: int | None = None,
    ) -> int:
        """Add an agent standing on ``path`` at arc length ``start``; returns its id.

        Args:
            path: the path to follow.
            emotion: its emotion or schedule (times from now); see :func:`to_model_schedule`.
            primer: a clip on the model's rig to start from; ``None`` for the standing start.
            start: arc length (metres) where it starts.
            seed: seed of its starting phase (default: from the generator's seed and its id).

        Raises:
            EmotionError: a bad emotion. PathError: not a path. RigError: a primer on another
            rig or too short.
        """
        if not isinstance(path, GroundPath):
            raise PathError(f"an agent needs a GroundPath to follow, got {type(path).__name__}")
        if not math.isfinite(start):
            raise PathError(f"start must be a finite arc length in metres, got {start}")
        schedule = to_model_schedule(emotion, self.labels)
        agent = self._next_id
        rng = np.random.default_rng([self.seed, agent] if seed is None else [int(seed)])
        m = schedule.at(0.0)
        if primer is None:
            prime = self._standing_start(m, float(rng.uniform(0.0, 2.0 * math.pi)))
        else:
            prime = self._primer_start(primer, m)
        state, rot, root, affective, theta, slp = prime
        self._next_id += 1
        self._agents[agent] = _Agent(path, schedule, 0.0, len(schedule.times) == 1)
        self._order.append(agent)
        self._groups = None
        self._state = torch.cat((self._state, state), 1)
        self._rot = torch.cat((self._rot, rot[None]))
        self._root = torch.cat((self._root, root[None]))
        self._affective = torch.cat((self._affective, affective[None]))
        self._emotion = np.vstack((self._emotion, m[None]))
        self._theta = np.append(self._theta, theta)
        self._slp = np.append(self._slp, slp)
        self._arc = np.append(self._arc, float(start))
        self._delta = np.append(self._delta, 0.0)
        self._time = np.append(self._time, 0.0)
        self._kappa = np.append(self._kappa, 0.0)
        self._heading = np.append(self._heading, float(path.heading(float(start))))
        self._offset = np.vstack((self._offset, np.zeros((1, 2))))
        return agent

    def remove_agent(self, agent: int) -> None:
        """Remove an agent.

        Raises:
            KeyError: no live agent has that id.
        """
        k = self._index(agent)
        keep = [i for i in range(len(self._order)) if i != k]
        idx = torch.as_tensor(keep, dtype=torch.long)
        self._state = self._state[:, idx]
        for name in ("_rot", "_root", "_affective"):
            setattr(self, name, getattr(self, name)[idx])
        for name in ("_emotion", "_theta", "_slp", "_arc", "_delta", "_time", "_kappa",
                     "_heading", "_offset"):
            setattr(self, name, getattr(self, name)[keep])
        del self._order[k]
        del self._agents[agent]
        self._groups = None

    def set_emotion(self, agent: int, emotion: EmotionLike) -> None:
        """Give an agent a new emotion or schedule; a schedule's time 0 is now.

        Raises:
            KeyError: unknown agent. EmotionError: a bad emotion.
        """
        k = self._index(agent)
        schedule = to_model_schedule(emotion, self.labels)
        self._agents[agent] = _Agent(self._agents[agent].path, schedule, float(self._time[k]),
                                     len(schedule.times) == 1)
        self._emotion[k] = schedule.at(0.0)

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
        info = self._agents[agent]
        here = info.path.position(self._arc[k]) + self._offset[k]
        arc, _ = path.nearest(here[None])
        self._arc[k] = float(arc[0])
        self._offset[k] = here - path.position(self._arc[k])
        info.path = path
        self._groups = None

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
    def _standing_start(self, m: np.ndarray, theta: float) -> tuple:
        c = self.model.controls
        rot = torch.as_tensor(c.standing_rotations, dtype=self.dtype)
        _, affective = self._affective_of(rot)
        root = torch.tensor([c.standing_height, 0.0, 0.0], dtype=self.dtype)
        movement = torch.tensor([math.sin(theta), math.cos(theta), 0.0, 0.0, 0.0],
                                dtype=self.dtype)
        n = WARMUP_FRAMES - 1
        inputs = GaitInputs(
            rot.expand(1, n, -1, -1), affective.expand(1, n, -1),
            torch.as_tensor(m, dtype=self.dtype)[None], movement.expand(1, n, -1),
            root.expand(1, n, -1),
        )
        _, state = self.network(inputs)
        return state, rot, root, affective, theta, 0.0

    @torch.no_grad()
    def _primer_start(self, primer: Motion, m: np.ndarray) -> tuple:
        f = primer_features(primer, self.model.controls)

        def t(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(x, dtype=self.dtype)

        inputs = GaitInputs(t(f["rotations"][None, :-1]), t(f["affective"][None, :-1]),
                            t(m[None]), t(f["movement"][None, :-1]), t(f["root"][None, :-1]))
        _, state = self.network(inputs)
        theta = math.atan2(f["movement"][-1, 0], f["movement"][-1, 1])
        return (state, t(f["rotations"][-1]), t(f["root"][-1]), t(f["affective"][-1]), theta,
                float(f["movement"][-1, 3]))

    # ----------------------------------------------------------------------------- stepping

    def _update_emotions(self) -> None:
        for k, agent in enumerate(self._order):
            info = self._agents[agent]
            if not info.constant:
                self._emotion[k] = info.schedule.at(self._time[k] - info.schedule_start)

    def _turn_factor(self) -> np.ndarray:
        """``(B,)`` the data's slowing in turns at each agent's point of its path."""
        factor = np.ones(len(self._order))
        slowing = self.model.controls.turn_slowing
        if slowing > 0:
            for path, members in self._by_path():
                k = np.abs(path.curvature(self._arc[members]))
                factor[members] = np.maximum(1.0 - slowing * k, MIN_TURN_FACTOR)
        return factor

    def _by_path(self) -> list[tuple[GroundPath, np.ndarray]]:
        """The agents grouped by the path they follow, ``(path, batch indices)``.

        Kept until an agent is added or removed or changes path, so a step queries each path in one
        call.
        """
        if self._groups is None:
            groups: dict[int, tuple[GroundPath, list[int]]] = {}
            for k, agent in enumerate(self._order):
                path = self._agents[agent].path
                groups.setdefault(id(path), (path, []))[1].append(k)
            self._groups = [(path, np.asarray(members)) for path, members in groups.values()]
        return self._groups

    @torch.no_grad()
    def step(self) -> GaitFrame:
        """Advance every agent by one frame (``1 / fps`` seconds) and return the new frame."""
        n = len(self._order)
        dt = 1.0 / self.fps
        m = torch.as_tensor(self._emotion, dtype=torch.float64)
        omega = (m @ self._freq).numpy()
        target = (m @ self._speed).numpy()
        # Slow to a stop before the end of an open path.
        remaining = np.full(n, np.inf)
        for path, members in self._by_path():
            if not path.closed:
                remaining[members] = path.length - self._arc[members]
        target = target * np.clip(remaining / STOP_DISTANCE, 0.0, 1.0) * self._turn_factor()
        moving = np.where(target > 1e-9, np.clip(self._slp / np.maximum(target, 1e-9), 0, 1), 0)
        moving = np.where(remaining > STOP_DISTANCE, 1.0, moving)
        omega = omega * moving
        movement = np.stack((np.sin(self._theta), np.cos(self._theta), omega, self._slp,
                             self._kappa), 1)
        inputs = GaitInputs(
            self._rot, self._affective if self.network.config.use_affective else None,
            m.to(self.dtype), torch.as_tensor(movement, dtype=self.dtype), self._root,
        )
        out, state = self.network.step(inputs, self._state)
        rot = out.rotations
        finite = torch.isfinite(rot).all(-1).all(-1) & torch.isfinite(out.root).all(-1)
        rot = torch.where(finite[:, None, None], same_hemisphere(rot, self._rot), self._rot)
        rot[:, self._above] = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=self.dtype)
        root = torch.where(finite[:, None], out.root, self._root)
        state = torch.where(finite[None, :, None], state, self._state)
        h = root[:, 0].clamp(*HEIGHT_RANGE)
        s = root[:, 1].clamp(0.0, MAX_SPEED / self.fps)
        delta = root[:, 2].clamp(0.0, math.pi)
        root = torch.stack((h, s, delta), 1)
        s_np, delta_np = s.double().numpy(), delta.double().numpy()
        # Controls and placement along the paths.
        self._theta = np.mod(self._theta + omega, 2.0 * math.pi)
        self._slp += self._alpha * (target - self._slp)
        self._delta += self._alpha * (delta_np - self._delta)
        self._arc = self._arc + np.minimum(s_np, np.maximum(remaining, 0.0))
        xz = np.zeros((n, 2))
        for path, members in self._by_path():
            arc = self._arc[members]
            curvature = path.curvature(arc)
            side = np.clip(curvature / FULL_TURN_CURVATURE, -1.0, 1.0)
            self._heading[members] = path.heading(arc) + side * self._delta[members]
            self._kappa[members] = s_np[members] ** 2 * np.abs(curvature)
            xz[members] = path.position(arc)
        gap = np.linalg.norm(self._offset, axis=1)
        shrink = np.maximum(gap - PATH_MERGE_SLOPE * s_np, 0.0) / np.maximum(gap, 1e-12)
        self._offset *= shrink[:, None]
        xz += self._offset
        self._time += dt
        self._update_emotions()
        # Next inputs.
        world_canon, affective = self._affective_of(rot)
        self._state, self._rot, self._root, self._affective = state, rot, root, affective
        return self._frame(rot, world_canon, h, xz)

    @torch.no_grad()
    def first_frame(self) -> GaitFrame:
        """The agents' current frame before any step.

        The agents' current frame before any step (the standing pose or the primer's last
        frame placed on the path), so that a clip can start where the agents stand.
        """
        xz = np.zeros((len(self._order), 2))
        for path, members in self._by_path():
            xz[members] = path.position(self._arc[members])
        world_canon, _ = self._affective_of(self._rot)
        return self._frame(self._rot, world_canon, self._root[:, 0], xz + self._offset)

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
            yaw_quaternion(torch.as_tensor(self._heading, dtype=self.dtype)), rot[:, mv])
        positions = self._local.expand(len(rot), -1, -1).clone()
        height = self._base + h
        positions[:, mv, 0] = torch.as_tensor(xz[:, 0], dtype=self.dtype)
        positions[:, mv, 1] = height
        positions[:, mv, 2] = torch.as_tensor(xz[:, 1], dtype=self.dtype)
        world = _place(world_canon.double().numpy(), self._heading, xz,
                       (height - self._local[mv, 1]).double().numpy())
        return GaitFrame(tuple(self._order), rotations.double().numpy(),
                         positions.double().numpy(), world, self._emotion.copy(), xz)


def primer_features(primer: Motion, controls: Any) -> dict[str, np.ndarray]:
    """Per-frame network inputs of a primer clip, as in training, at the model's rate.

    Args:
        primer: a clip on the model's rig (same joint names and hierarchy).
        controls: the model's :class:`~emotive.models.gait.controls.GaitControls`.

    Returns:
        :func:`~emotive.models.gait.data.clip_features` of the clip resampled to
        ``controls.fps``, with ``rotations`` made heading-canonical per frame (the mover in the
        standing pose's hemisphere); ``T >= 2`` frames.

    Raises:
        RigError: not a motion, another rig, or fewer than two frames.
    """
    sk = controls.skeleton
    if not isinstance(primer, Motion):
        raise RigError(f"a primer must be a Motion, got {type(primer).__name__}")
    if primer.skeleton.names != sk.names or not np.array_equal(primer.skeleton.parents,
                                                               sk.parents):
        raise RigError(
            f"primer {primer.metadata.get('name', '')!r} is on another rig "
            f"({primer.skeleton.num_joints} joints) than the model's ({sk.num_joints} "
            "joints of the Bandai Namco rig): give a clip of the training rig"
        )
    if abs(primer.fps - controls.fps) > 1e-6 * controls.fps:
        primer = resample(primer, controls.fps)
    if primer.num_frames < 2:
        raise RigError("a primer needs at least two frames at the model's frame rate")
    f = clip_features(primer)
    rot, _ = canonical_frames(f["rotations"], f["positions"], f["heading"], f["root_xz"],
                              controls.mover)
    mv = controls.mover
    rot[:, mv] *= np.where((rot[:, mv] @ controls.standing_rotations[mv])[:, None] < 0, -1.0, 1.0)
    f["rotations"] = rot
    return f


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
