"""The whole per-frame step of a gait agent as one torch module: what is exported and run.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``P = J + E`` points, ``C`` emotion
labels, ``K`` path samples, ``L`` GRU layers, ``H`` GRU width, ``S`` the agent row
(:mod:`~emotive.models.gait.step_layout`).

:class:`AgentStep` is the main paper's animation loop (Sec. 4: the network reads the pose,
its affective features, the emotion and the movement controls, and predicts the next pose
and root) with everything around the network inside: the movement controls (stepping phase
advanced by the emotion's step frequency, a low-passed target speed that slows in turns and
at the end of an open path), the clamps and the fallback of a non-finite prediction, the
placement on the path (:mod:`~emotive.models.gait.step_path`, from points an engine samples
ahead of the agent), forward kinematics, the affective features of the new pose, and the
causal foot lock (:mod:`emotive.ik.foot_lock_kernel`). :class:`~emotive.models.gait.generate
.GaitGenerator` runs it eagerly; :mod:`~emotive.models.gait.step_export` traces it into one
ONNX graph, so an engine does only what is left: sample each agent's path ahead of it and
pose its skeleton.

A new agent is started by :data:`WARMUP_STEPS` calls with ``start = 1`` (any agent row, e.g.
zeros, and a zero GRU state): each runs the network on the standing pose with the stepping
phase ``phase`` and the agent's emotion, to settle the GRU as the main paper's model is
primed, and returns the agent standing at the first path point (arc offset 0), facing along
the path.
"""

from __future__ import annotations

import math
import warnings
from typing import Any, NamedTuple

import torch
from torch import nn

from emotive.core.roles import resolve_roles
from emotive.features.movement import LOWPASS_HZ
from emotive.ik.foot_lock import LockSettings, leg_index, leg_rig
from emotive.ik.foot_lock_kernel import LockTensors, lock_batch_last
from emotive.models.gait.affect import gait_affective, gait_affective_batch_last
from emotive.models.gait.controls import MIN_TURN_FACTOR
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs, GaitNetwork
from emotive.models.gait.step_layout import LOCK_FIELDS, AgentLayout
from emotive.models.gait.step_path import PathSampling, path_at
from emotive.transforms.kinematics import PoseFK
from emotive.transforms.rotations import quaternion_multiply

#: Network steps on the standing pose that start an agent (a GRU state from zeros).
WARMUP_STEPS = 9
#: Distance (metres) before the end of an open path over which the agent slows to a stop.
STOP_DISTANCE = 1.0
#: Curvature (1/m) from which ``delta`` turns the body fully to the inside of a turn.
FULL_TURN_CURVATURE = 0.2
#: Metres of the gap to the path (after a path change) closed per metre walked: the agent
#: merges onto a new path at about 27 degrees.
PATH_MERGE_SLOPE = 0.5
#: Clamps of the predicted root features: height in metres, speed in metres per second.
HEIGHT_RANGE = (-0.6, 0.4)
MAX_SPEED = 8.0
#: Calls that TorchScript's profiling executor makes before it runs an optimized graph.
PROFILING_CALLS = 2
#: Unlocked heel and toe positions written for a new agent (metres): so far from any foot
#: that nothing plants on its first frame.
NO_PREVIOUS_POSITION = 1e4


class StepOutputs(NamedTuple):
    """What one step returns.

    Attributes:
        recurrent: ``(L, B, H)`` the GRU state to feed back.
        agent: ``(B, S)`` the agent rows to feed back.
        rotations: ``(B, J, 4)`` local rotations, the mover's carrying the world heading.
        root_position: ``(B, 3)`` world position of the mover joint, metres.
        world: ``(B, P, 3)`` world positions of joints then end sites, metres.
        contacts: ``(B, 2, 2)`` planted heel and toe of the left and right foot (0 or 1).
        ground: ``(B, 3)`` ``(x, z, heading)``: where the agent stands and faces; the frame
            of the next frame's path samples.
        advance: ``(B,)`` metres to move the agent's arc length along its path.
    """

    recurrent: torch.Tensor
    agent: torch.Tensor
    rotations: torch.Tensor
    root_position: torch.Tensor
    world: torch.Tensor
    contacts: torch.Tensor
    ground: torch.Tensor
    advance: torch.Tensor


def _wrap(x: torch.Tensor) -> torch.Tensor:
    return torch.atan2(torch.sin(x), torch.cos(x))


class AgentStep(nn.Module):
    """One frame of ``B`` agents, everything included (see the module docstring).

    Args:
        model: the trained model.
        dtype: float type of the computation (float32 is what is exported).
        foot_lock: hold planted feet (:mod:`emotive.ik.foot_lock`); ``False`` returns the
            network's poses placed on the path.
        network: the network to step: ``None`` for the model's own (cast to ``dtype``), or an
            object with the :class:`~emotive.models.gait.network.GaitNetwork` ``step`` and
            ``config`` (e.g. the ONNX network of :mod:`~emotive.models.gait.onnx_runtime`).
        settings: the foot lock's thresholds.
    """

    def __init__(self, model: GaitModel, dtype: torch.dtype = torch.float32,
                 foot_lock: bool = True, network: Any = None,
                 settings: LockSettings | None = None) -> None:
        super().__init__()
        c = model.controls
        sk = c.skeleton
        self.network = model.network.to(dtype).eval() if network is None else network
        self.dtype = dtype
        self.labels = model.labels
        self.fps = float(model.fps)
        self.mover = int(c.mover)
        self.num_joints = sk.num_joints
        self.layout = AgentLayout(sk.num_joints)
        self.sampling = PathSampling.for_step(MAX_SPEED / self.fps)
        self.foot_lock = bool(foot_lock)
        self.settings = settings or LockSettings()
        self.turn_slowing = float(c.turn_slowing)
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * LOWPASS_HZ / self.fps)
        self.use_affective = bool(self.network.config.use_affective)
        self._walking_only = False

        def const(x: Any) -> torch.Tensor:
            return torch.as_tensor(x, dtype=dtype)

        self.register_buffer("freq", const(c.step_frequency))
        self.register_buffer("speed", const(c.speed))
        self.register_buffer("local", const(c.standing_positions))
        self.fk = PoseFK(sk.parents, c.standing_positions, sk.end_site_parents,
                         sk.end_site_offsets, dtype)
        self.roles = resolve_roles(sk)
        standing = const(c.standing_rotations)
        standing_world = self.fk(standing[None])
        self.register_buffer("standing", standing)
        self.register_buffer("standing_last", standing[:, :, None])
        self.register_buffer("standing_affective",
                             gait_affective(standing_world, self.roles)[0])
        self.standing_height = float(c.standing_height)
        rig = leg_rig(sk, self.roles, standing_world[0].double().numpy())
        self.legs = leg_index(rig)
        # Joints above the mover stay at the identity (as in the data): the mover alone
        # places the body.
        above, j = [], int(sk.parents[self.mover])
        while j >= 0:
            above.append(j)
            j = int(sk.parents[j])
        keep = torch.ones(sk.num_joints, 1, dtype=dtype)
        keep[above] = 0.0
        identity = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=dtype)[:, None]
        self.register_buffer("keep", keep[:, :, None])
        self.register_buffer("identity", identity)
        self.register_buffer("unkept", identity * (1.0 - keep[:, :, None]))
        # World height of the mover = base + h.
        self.base = float(c.standing_positions[self.mover, 1] - c.standing_height)

    def example_inputs(self, path_left: float, batch: int = 2) -> tuple[torch.Tensor, ...]:
        """Inputs of a start step of ``batch`` agents (for tracing), in the module's dtype."""
        cfg, d = self.network.config, self.dtype
        return (torch.zeros(cfg.gru_layers, batch, cfg.gru_hidden, dtype=d),
                torch.zeros(batch, self.layout.size, dtype=d),
                torch.full((batch, len(self.labels)), 1.0 / len(self.labels), dtype=d),
                torch.ones(batch, dtype=d), torch.zeros(batch, self.sampling.count, 2, dtype=d),
                torch.full((batch,), path_left, dtype=d), torch.ones(batch, dtype=d),
                torch.zeros(batch, dtype=d))

    def traced(self, path_left: float, walking: bool = False) -> Any:
        """This step as frozen TorchScript.

        Traced with every start selection in it, or, with ``walking``, without them: a
        trace for calls whose agents all walk (``start = 0``), which must not be given a
        start step.

        The same operations without the Python interpreter between them: on the development
        machine one agent's step took less than half the time, 1,000 agents' about 20 %
        less. The network must be a torch module (not an ONNX one). torch 2.13 marks
        tracing as deprecated (its warning is silenced here); a torch without it makes
        :class:`~emotive.models.gait.generate.GaitGenerator` step eagerly instead.
        """
        with warnings.catch_warnings(), torch.no_grad():
            warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)
            warnings.filterwarnings("ignore", category=DeprecationWarning)
            self._walking_only = walking
            try:
                trace = torch.jit.trace(self.eval(), self.example_inputs(path_left),
                                        check_trace=False)
            finally:
                self._walking_only = False
            frozen = torch.jit.freeze(trace)
            # TorchScript optimizes a graph over its first calls (tens of milliseconds
            # each): make them here, not in a host's first frames.
            for _ in range(PROFILING_CALLS):
                frozen(*self.example_inputs(path_left, batch=1))
            return frozen

    # ------------------------------------------------------------------------------ pieces

    def _targets(self, emotion: torch.Tensor, pace: torch.Tensor, left: torch.Tensor,
                 curvature: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(B,)`` step frequency (radians per frame) and target speed (metres per frame)."""
        omega = (emotion @ self.freq) * torch.sqrt(pace)
        target = (emotion @ self.speed) * pace * (left / STOP_DISTANCE).clamp(0.0, 1.0)
        if self.turn_slowing > 0:
            target = target * (1.0 - self.turn_slowing * curvature.abs()).clamp_min(
                MIN_TURN_FACTOR)
        return omega, target

    def pose_world(self, rot: torch.Tensor, h: torch.Tensor, xz: torch.Tensor,
                   heading: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Canonical poses placed in the world: yaw about Y, then ground position and height.

        Args:
            rot: ``(B, J, 4)`` heading-canonical local rotations.
            h: ``(B,)`` root height features.
            xz: ``(B, 2)`` ground positions.
            heading: ``(B,)`` world yaws.

        Returns:
            The placed rotations ``(B, J, 4)``, the mover's position ``(B, 3)``, the world
            points ``(B, P, 3)`` and the canonical points ``(B, P, 3)``.
        """
        rotations, root, world, canonical = self._placed(
            rot.permute(1, 2, 0).contiguous(), h, xz, heading)
        return (rotations.permute(2, 0, 1), root, world.permute(2, 0, 1),
                canonical.permute(2, 0, 1))

    def _placed(self, rot: torch.Tensor, h: torch.Tensor, xz: torch.Tensor,
                heading: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """:meth:`pose_world` with the agents last: ``(J, 4, B)`` and ``(P, 3, B)``.

        Every arithmetic operation then runs over contiguous rows of the ``B`` agents.
        """
        canonical = self.fk.batch_last(rot)
        mv = self.mover
        half = 0.5 * heading
        zero = torch.zeros_like(half)
        yaw = torch.stack((torch.cos(half), zero, torch.sin(half), zero), 0)
        turned = quaternion_multiply(yaw, rot[mv], -2)
        rotations = torch.cat((rot[:mv], turned[None], rot[mv + 1:]), 0)
        height = self.base + h
        root = torch.stack((xz[:, 0], height, xz[:, 1]), -1)
        lift = height - self.local[mv, 1]
        c, s = torch.cos(heading), torch.sin(heading)
        x, y, z = canonical.unbind(1)
        world = torch.stack((c * x + s * z + xz[:, 0], y + lift,
                             -s * x + c * z + xz[:, 1]), 1)
        return rotations, root, world, canonical

    def _next_rotations(self, raw: torch.Tensor, current: torch.Tensor, finite: torch.Tensor
                        ) -> torch.Tensor:
        """``(J, 4, B)`` the network's next rotations made safe to feed back.

        Normalized (a zero quaternion becomes the identity), in the hemisphere of the
        current rotations ``(J, 4, B)`` (the prediction may take either sign,
        :func:`~emotive.models.gait.network.same_hemisphere`), the current ones kept where
        an agent's prediction is not ``finite`` ``(B,)``, and the joints above the mover at
        the identity.
        """
        # Products rather than selections with broadcast masks (several times faster in
        # onnxruntime).
        norm = torch.sqrt((raw * raw).sum(1, keepdim=True))
        q = raw / norm.clamp_min(1e-12) + self.identity * (norm <= 1e-12).to(raw.dtype)
        q = q * (1.0 - 2.0 * ((q * current).sum(1, keepdim=True) < 0).to(raw.dtype))
        q = torch.where(finite, q, current)
        return q * self.keep + self.unkept

    # ------------------------------------------------------------------------------ step

    def forward(self, recurrent: torch.Tensor, agent: torch.Tensor, emotion: torch.Tensor,
                pace: torch.Tensor, path: torch.Tensor, path_left: torch.Tensor,
                start: torch.Tensor, phase: torch.Tensor) -> StepOutputs:
        """Advance ``B`` agents by one frame (``1 / fps`` seconds).

        Args:
            recurrent: ``(L, B, H)`` GRU state (zeros for a new agent).
            agent: ``(B, S)`` agent rows (anything, e.g. zeros, with ``start = 1``).
            emotion: ``(B, C)`` emotion weights over the labels.
            pace: ``(B,)`` factor on the emotion's walking speed (0.5-1.5).
            path: ``(B, K, 2)`` the path sampled around the agent, in its frame
                (:mod:`~emotive.models.gait.step_path`).
            path_left: ``(B,)`` metres from the agent's arc length to the end of an open
                path (at least 1e6 for a loop).
            start: ``(B,)`` 1 to run a start step (see the module docstring), else 0.
            phase: ``(B,)`` stepping phase of a start step, radians (ignored otherwise).

        Returns:
            :class:`StepOutputs`.
        """
        f = self.layout.unpack(agent)
        starting = start > 0.5
        b = agent.shape[0]
        # Start steps take other values in a few places; eagerly, a frame without one skips
        # those selections (an exported graph always makes them; a walking trace never).
        starts = not self._walking_only and (torch.jit.is_tracing() or bool(starting.any()))

        def sel(if_start: torch.Tensor | float, otherwise: torch.Tensor) -> torch.Tensor:
            if not starts:
                return otherwise
            mask = starting.reshape(-1, *([1] * (otherwise.ndim - 1)))
            value = if_start if isinstance(if_start, torch.Tensor) else torch.full_like(
                otherwise, if_start)
            return torch.where(mask, value, otherwise)

        # Controls (Sec. 4.2): phase advance, low-passed speed, kappa.
        omega, target = self._targets(emotion, pace, path_left, f["curvature"])
        slp = f["speed_lowpass"]
        moving = torch.where(target > 1e-9, (slp / target.clamp_min(1e-9)).clamp(0.0, 1.0),
                             torch.zeros_like(slp))
        moving = torch.where(path_left > STOP_DISTANCE, torch.ones_like(moving), moving)
        omega = sel(0.0, omega * moving)
        theta = sel(phase, f["theta"])
        movement = torch.stack((torch.sin(theta), torch.cos(theta), omega, sel(0.0, slp),
                                sel(0.0, f["kappa"])), -1)
        stand_root = torch.tensor([self.standing_height, 0.0, 0.0], dtype=agent.dtype)
        cur_rot = sel(self.standing.expand(b, -1, -1), f["rotations"])
        cur_root = sel(stand_root.expand(b, -1), f["root"])
        cur_aff = sel(self.standing_affective.expand(b, -1), f["affective"])
        inputs = GaitInputs(cur_rot, cur_aff if self.use_affective else None, emotion,
                            movement, cur_root)
        out, state = self._predict(inputs, recurrent)
        root = out.root
        cur = cur_rot.permute(1, 2, 0)
        raw = out.raw_rotations.permute(1, 2, 0).contiguous()
        # A prediction holding NaN or inf keeps the previous pose, root and state (x - x is
        # 0 for every finite x only).
        total = raw.sum((0, 1)) + root.sum(-1)
        finite = (total - total) == 0
        rot = self._next_rotations(raw, cur, finite)
        root = torch.where(finite[:, None], root, cur_root)
        state = torch.where(finite[None, :, None], state, recurrent)
        h = root[:, 0].clamp(*HEIGHT_RANGE)
        s_pf = root[:, 1].clamp(0.0, MAX_SPEED / self.fps)
        delta = root[:, 2].clamp(0.0, math.pi)
        # Placement along the path (Sec. 4.3), in the agent's frame.
        advance = sel(0.0, torch.minimum(s_pf, path_left.clamp_min(0.0)))
        origin, ahead, tangent, curvature = path_at(path, advance, self.sampling)
        side = (curvature / FULL_TURN_CURVATURE).clamp(-1.0, 1.0)
        delta_lp = f["delta"] + self.alpha * (delta - f["delta"])
        gap = torch.sqrt((origin * origin).sum(-1))
        shrink = (gap - PATH_MERGE_SLOPE * s_pf).clamp_min(0.0) / gap.clamp_min(1e-12)
        local = sel(origin, ahead - origin * shrink[:, None])
        heading0 = f["heading"]
        c, s = torch.cos(heading0), torch.sin(heading0)
        x = f["x"] + c * local[:, 0] + s * local[:, 1]
        z = f["z"] - s * local[:, 0] + c * local[:, 1]
        heading = _wrap(heading0 + tangent + sel(0.0, side * delta_lp))
        if starts:
            rot = torch.where(starting, self.standing_last, rot)
        root = sel(stand_root.expand(b, -1), torch.stack((h, s_pf, delta), 1))
        xz = torch.stack((x, z), -1)
        rotations, root_position, world, canonical = self._placed(rot, root[:, 0], xz, heading)
        tau = 2.0 * math.pi
        theta = theta + omega
        new = {
            "rotations": rot.permute(2, 0, 1), "root": root,
            "affective": gait_affective_batch_last(canonical, self.roles).permute(1, 0),
            "theta": theta - tau * torch.floor(theta / tau),
            "speed_lowpass": sel(0.0, slp + self.alpha * (target - slp)),
            "delta": sel(0.0, delta_lp), "kappa": sel(0.0, s_pf * s_pf * curvature.abs()),
            "curvature": curvature, "x": x, "z": z, "heading": heading,
        }
        lock = LockTensors(*(f[f"lock_{k}"] for k in LOCK_FIELDS))
        lock = lock._replace(planted=lock.planted > 0.5)
        if self.foot_lock:
            rotations, world, lock = lock_batch_last(self.legs, lock, rotations, world,
                                                     s_pf * self.fps, self.fps, self.settings)
        for k, v in zip(LOCK_FIELDS, lock, strict=True):
            new[f"lock_{k}"] = sel(NO_PREVIOUS_POSITION if k == "previous" else 0.0,
                                   v.to(agent.dtype))
        contacts = new["lock_planted"]
        ground = torch.stack((x, z, heading), -1)
        return StepOutputs(state, self.layout.pack(new), rotations.permute(2, 0, 1),
                           root_position, world.permute(2, 0, 1), contacts, ground, advance)

    def _predict(self, inputs: GaitInputs, recurrent: torch.Tensor) -> tuple[Any, torch.Tensor]:
        """The network's step; a torch network's without normalizing (done here)."""
        if isinstance(self.network, GaitNetwork):
            return self.network.step(inputs, recurrent, normalize=False)
        return self.network.step(inputs, recurrent)
