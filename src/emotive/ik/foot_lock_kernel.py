"""Torch kernels of the causal foot lock, without data-dependent branches.

:mod:`emotive.ik.foot_lock` describes the method (contacts with hysteresis, one horizontal
and one yaw correction per foot, an analytic two-bone solve per leg). Here every step is a
tensor expression: where the method picks between cases the kernel computes both and selects,
so the same code runs eagerly on any float type and traces into one exported graph (the gait
step of :mod:`emotive.models.gait.step_graph`). The NumPy functions of
:mod:`~emotive.ik.foot_lock` call these kernels in float64.

Legend: ``B`` agents, ``J`` joints, ``P = J + E`` points (joints then end sites). The leg
axis (left, right) follows the agents': ``(B, 2, ...)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import torch

from emotive.transforms.rotations import cross_product as cross
from emotive.transforms.rotations import quaternion_multiply
from emotive.transforms.rotations import quaternion_rotate as rotate

#: Where a point has no previous position (a new agent), its speed is taken as this (m/s):
#: above every release speed, so nothing plants on the first frame.
NO_PREVIOUS_SPEED = 1e6


@dataclass(frozen=True)
class LegIndex:
    """The legs of a rig as constants of the kernels.

    Attributes:
        chain: ``(2, 4)`` joint indices per leg: hip's parent, hip, knee, ankle.
        toe: ``(2,)`` index of each toe point.
        below: ``(2, P)`` bool, the points that move with each ankle.
        ground: ``(2, 2)`` standing height of each leg's heel and toe, metres.
        leg_length: hip -> knee -> ankle length of the standing pose, metres.
        parents: the ``J`` parents.
    """

    chain: tuple[tuple[int, ...], ...]
    toe: tuple[int, ...]
    below: torch.Tensor
    ground: torch.Tensor
    leg_length: float
    parents: tuple[int, ...]
    index: dict[str, torch.Tensor | tuple[torch.Tensor, ...]] = field(
        init=False, repr=False, compare=False)
    world_levels: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # Index tensors of the solve, made once: gathers by index_select, and the solved
        # rows put back by one concatenation and one permutation (no in-place writes).
        up, hip, knee, ankle = (list(c) for c in zip(*self.chain, strict=True))
        points, joints = int(self.below.shape[1]), len(self.parents)
        below = [(int(p), leg) for leg in range(2) for p in torch.nonzero(self.below[leg])[:, 0]]
        point_source = list(range(points))
        for leg, k in enumerate(knee):
            point_source[k] = points + leg
        for n, (p, _) in enumerate(below):
            point_source[p] = points + 2 + n
        rotation_source = list(range(joints))
        for n, j in enumerate(hip + knee + ankle):
            rotation_source[j] = joints + n

        def long(x: list[int]) -> torch.Tensor:
            return torch.tensor(x, dtype=torch.long)

        index = {"up": long(up), "hip": long(hip), "knee": long(knee), "ankle": long(ankle),
                 "toe": long(list(self.toe)), "below": long([p for p, _ in below]),
                 "below_leg": long([leg for _, leg in below]),
                 "point_source": long(point_source), "rotation_source": long(rotation_source)}
        object.__setattr__(self, "index", index)
        # The joints from the roots to the ankles, by depth: (joints, their parents).
        need: set[int] = set()
        for j in ankle:
            while j >= 0 and j not in need:
                need.add(j)
                j = self.parents[j]
        depth = {}
        for j in sorted(need):
            depth[j] = 0 if self.parents[j] < 0 else depth[self.parents[j]] + 1
        levels = tuple((tuple(j for j in sorted(need) if depth[j] == d),
                        tuple(self.parents[j] for j in sorted(need) if depth[j] == d))
                       for d in range(max(depth.values()) + 1))
        object.__setattr__(self, "world_levels", levels)
        index["world_levels"] = tuple(long(list(joints)) for joints, _ in levels)


class LockTensors(NamedTuple):
    """The lock's per-agent state as tensors (fields as :class:`~emotive.ik.foot_lock.LockState`).

    ``planted`` is a bool tensor; ``previous`` may hold NaN where there is no previous frame.
    """

    previous: torch.Tensor
    planted: torch.Tensor
    anchor: torch.Tensor
    correction: torch.Tensor
    yaw_anchor: torch.Tensor
    yaw_correction: torch.Tensor
    released: torch.Tensor


# The kernels work with the agents last: a vector per leg is ``(2, 3, B)``, a quaternion per
# joint ``(J, 4, B)``, a point ``(P, 3, B)``: components along dimension -2. Every arithmetic
# operation then runs over long contiguous rows (with the agents first, a thousand agents'
# tiny rows of 3 made most operations slower than their dispatch), and moving the agents
# last is a plain 2-D transpose (onnxruntime's fast case). :func:`lock_step` and
# :func:`two_bone` take and give the agents first, as their callers hold them.


def _dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return (a * b).sum(-2)


def _norm(x: torch.Tensor) -> torch.Tensor:
    return torch.sqrt((x * x).sum(-2))


def _unit(x: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    return x / torch.sqrt((x * x).sum(-2, keepdim=True)).clamp_min(eps)


_COLUMNS: dict[tuple, torch.Tensor] = {}


def _column(values: tuple[float, ...], like: torch.Tensor) -> torch.Tensor:
    """A constant ``(n, 1)``: one value per component, broadcast over the agents."""
    key = (values, like.dtype)
    if key not in _COLUMNS:
        _COLUMNS[key] = torch.tensor(values, dtype=like.dtype)[:, None]
    return _COLUMNS[key]


def _conj(q: torch.Tensor) -> torch.Tensor:
    return q * _column((1.0, -1.0, -1.0, -1.0), q)


def _qmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return quaternion_multiply(a, b, -2)


def _between(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``(..., 4, B)`` shortest rotation taking direction ``u`` to ``v`` ``(..., 3, B)``."""
    u, v = _unit(u), _unit(v)
    w = 1.0 + _dot(u, v).unsqueeze(-2)
    q = torch.cat((w, cross(u, v, -2)), -2)
    q = torch.where(w > 1e-9, q, _column((1.0, 0.0, 0.0, 0.0), q))
    return _unit(q)


def wrap_angle(x: torch.Tensor) -> torch.Tensor:
    """Angles wrapped to ``(-pi, pi]``."""
    return torch.atan2(torch.sin(x), torch.cos(x))


def fade(released: torch.Tensor, frames: int) -> torch.Tensor:
    """Factor taking a correction from ``released - 1`` to ``released`` frames (any shape).

    The correction left ``k`` frames after a contact ended is ``c0 s(k)``, ``s`` the
    smoothstep from 1 to 0 over ``frames`` frames, so one frame scales it by
    ``s(k) / s(k - 1)``.
    """

    def left(k: torch.Tensor) -> torch.Tensor:
        x = (k / max(frames, 1)).clamp(0.0, 1.0)
        return 1.0 - x * x * (3.0 - 2.0 * x)

    before = left(released - 1.0)
    return torch.where(before > 0, left(released) / before.clamp_min(1e-12),
                       torch.zeros_like(before))


def _contacts(legs: LegIndex, state: LockTensors, feet: torch.Tensor, body: torch.Tensor,
              fps: float, settings) -> torch.Tensor:
    """``(2, 2, B)`` planted heels and toes after this frame's hysteresis.

    Args:
        legs: the legs.
        state: the lock's state after the previous frame (agents last).
        feet: ``(2, 2, 3, B)`` heel and toe positions of each leg.
        body: ``(B,)`` the body's walking speed, m/s.
        fps: frames per second.
        settings: a :class:`~emotive.ik.foot_lock.LockSettings`.
    """
    scale = legs.leg_length
    height = feet[:, :, 1] - legs.ground.to(feet.dtype)[..., None]
    speed = _norm(feet - state.previous) * fps
    speed = torch.where(torch.isnan(speed), torch.full_like(speed, NO_PREVIOUS_SPEED), speed)
    on = (height < settings.height_on * scale) & (
        speed < settings.speed_on * scale + settings.body_on * body)
    off = (height > settings.height_off * scale) | (
        speed > settings.speed_off * scale + settings.body_off * body)
    return on | (state.planted & ~off)


def _corrections(state: LockTensors, xz: torch.Tensor, planted: torch.Tensor, frames: int,
                 limit: float) -> tuple[torch.Tensor, ...]:
    """This frame's ``(2, 2, B)`` horizontal corrections and anchors (leg, ``(x, z)``, agent).

    While the heel is planted the heel is held where it planted; with only the toe planted,
    the toe where the heel lifted; new anchors are taken from the corrected foot; in swing
    the correction fades out over ``frames`` frames (:func:`fade`). A leg whose correction
    would be longer than ``limit`` metres is dragged, not planted: it is released.

    Args:
        state: the lock's state after the previous frame (agents last).
        xz: ``(2, 2, 2, B)``: leg, heel/toe, ``(x, z)``, agent.
        planted: ``(2, 2, B)`` this frame's contacts.
        frames: frames of the fade.
        limit: the longest correction of a planted foot, metres.

    Returns:
        The corrections and the anchors ``(2, 2, B)``, the planted heels and toes
        ``(2, 2, B)`` after the release of dragged legs, and per leg ``(2, B)`` the frames
        since release and the fade factor of this frame.
    """
    heel, toe = planted[:, 0], planted[:, 1]
    was_heel = state.planted[:, 0]
    held = (heel & was_heel) | (toe & ~heel & state.planted.any(1) & ~was_heel)
    toe_xz = xz[:, 1]
    ref = torch.where(heel[:, None], xz[:, 0], toe_xz)
    anchor = torch.where(held[:, None], state.anchor, ref + state.correction)
    hold = anchor - ref
    # A dragged leg plants neither point: its anchor is then taken from the toe.
    dragged = (heel | toe) & (_norm(hold) > limit)
    planted = planted & ~dragged[:, None]
    released = torch.where(planted.any(1), torch.zeros_like(state.released),
                           state.released + 1.0)
    factor = fade(released, frames)
    correction = torch.where(((heel | toe) & ~dragged)[:, None], hold,
                             factor[:, None] * state.correction)
    anchor = torch.where(dragged[:, None], toe_xz + state.correction, anchor)
    return correction, anchor, planted, released, factor


def _yaw_corrections(state: LockTensors, feet: torch.Tensor, contact: torch.Tensor,
                     factor: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """This frame's ``(2, B)`` yaw corrections and anchors (radians).

    A foot in contact keeps the yaw of its heel -> toe direction (0 faces +Z) it had,
    corrected, when the contact began; in swing the correction is scaled by ``factor``.
    """
    d = feet[:, 1] - feet[:, 0]
    yaw = torch.atan2(d[:, 0], d[:, 2])
    fresh = yaw + state.yaw_correction
    anchor = torch.where(contact & state.planted.any(1), state.yaw_anchor, fresh)
    return torch.where(contact, wrap_angle(anchor - yaw), factor * state.yaw_correction), anchor


def _world_rotations(legs: LegIndex, rotations: torch.Tensor) -> dict[int, torch.Tensor]:
    """World rotations ``(4, B)`` of the joints on the paths from the roots to the ankles."""
    world: dict[int, torch.Tensor] = {}
    for (joints, parents), index in zip(legs.world_levels, legs.index["world_levels"],
                                        strict=True):
        local = rotations.index_select(0, index)
        if parents[0] < 0:
            level = local
        else:
            level = _qmul(torch.stack([world[p] for p in parents], 0), local)
        for k, j in enumerate(joints):
            world[j] = level[k]
    return world


def _two_bone(legs: LegIndex, rotations: torch.Tensor, points: torch.Tensor,
              shift: torch.Tensor, yaw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """:func:`two_bone` with the agents last.

    Rotations ``(J, 4, B)``, points ``(P, 3, B)``, shift ``(2, 3, B)``, yaw ``(2, B)``.
    """
    world = _world_rotations(legs, rotations)
    ix = legs.index
    h, k, a = (points.index_select(0, ix[n]) for n in ("hip", "knee", "ankle"))
    la, lb = _norm(k - h), _norm(a - k)
    reach = la + lb - 1e-6
    target = a + shift
    flat = torch.sqrt((target[:, 0] - h[:, 0]) ** 2 + (target[:, 2] - h[:, 2]) ** 2)
    lowest = h[:, 1] - torch.sqrt((reach * reach - flat * flat).clamp_min(0.0))
    target = torch.stack((target[:, 0], torch.maximum(target[:, 1], lowest), target[:, 2]), 1)
    to_target = target - h
    d = torch.minimum(torch.maximum(_norm(to_target), (la - lb).abs() + 1e-6), reach)
    u = _unit(to_target)
    side = (k - h) - _dot(k - h, u)[:, None] * u
    v = _unit(side)
    along = (la * la - lb * lb + d * d) / (2 * d)
    k_new = h + along[:, None] * u + torch.sqrt(
        (la * la - along * along).clamp_min(0.0))[:, None] * v
    a_new = h + d[:, None] * u

    def per_leg(name: int) -> torch.Tensor:
        return torch.stack([world[c[name]] for c in legs.chain], 0)

    g_up, g_hip, g_knee, g_ankle = per_leg(0), per_leg(1), per_leg(2), per_leg(3)
    r1 = _between(k - h, k_new - h)
    g_hip2 = _qmul(r1, g_hip)
    r2 = _between(rotate(r1, a - k, -2), a_new - k_new)
    g_knee2 = _qmul(r2, _qmul(r1, g_knee))
    half = 0.5 * yaw
    zero = torch.zeros_like(half)
    turn = torch.stack((torch.cos(half), zero, torch.sin(half), zero), 1)
    new = torch.cat((
        _unit(_qmul(_conj(g_up), g_hip2)),
        _unit(_qmul(_conj(g_hip2), g_knee2)),
        _unit(_qmul(_conj(g_knee2), _qmul(turn, g_ankle))),
    ), 0)
    rotations = torch.cat((rotations, new), 0).index_select(0, ix["rotation_source"])
    leg = ix["below_leg"]
    moved = a_new.index_select(0, leg) + rotate(
        turn.index_select(0, leg), points.index_select(0, ix["below"]) - a.index_select(0, leg),
        -2)
    points = torch.cat((points, k_new, moved), 0).index_select(0, ix["point_source"])
    return rotations, points


def _last(x: torch.Tensor) -> torch.Tensor:
    """The agents (dimension 0) moved last, contiguous."""
    return x.permute(*range(1, x.ndim), 0).contiguous()


def _last_view(x: torch.Tensor) -> torch.Tensor:
    """The agents (dimension 0) moved last, a view (for the small state tensors)."""
    return x.permute(*range(1, x.ndim), 0)


def _first(x: torch.Tensor) -> torch.Tensor:
    """The agents (the last dimension) moved first."""
    return x.permute(x.ndim - 1, *range(x.ndim - 1))


def two_bone(legs: LegIndex, rotations: torch.Tensor, points: torch.Tensor, shift: torch.Tensor,
             yaw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The rotations and points with each ankle moved and each foot turned, hips fixed.

    Each ankle moves by ``shift`` ``(B, 2, 3)`` towards a target raised where the straight
    leg cannot reach it (the horizontal position is what the lock holds); the knee stays in
    its bending plane; each foot turns by ``yaw`` ``(B, 2)`` about the vertical through its
    ankle and keeps its world orientation otherwise.

    Args:
        legs: the legs.
        rotations: ``(B, J, 4)`` local rotations.
        points: ``(B, P, 3)`` their world positions.
        shift: ``(B, 2, 3)`` move of each ankle, metres.
        yaw: ``(B, 2)`` turn of each foot, radians.

    Returns:
        The rotations ``(B, J, 4)`` and points ``(B, P, 3)``.
    """
    rot, pts = _two_bone(legs, _last(rotations), _last(points), _last(shift), _last(yaw))
    return _first(rot), _first(pts)


def lock_step(legs: LegIndex, state: LockTensors, rotations: torch.Tensor, points: torch.Tensor,
              body_speed: torch.Tensor, fps: float, settings
              ) -> tuple[torch.Tensor, torch.Tensor, LockTensors]:
    """Hold this frame's planted feet still (the method of :mod:`emotive.ik.foot_lock`).

    Args:
        legs: the legs (:class:`LegIndex`).
        state: the agents' state after the previous frame.
        rotations: ``(B, J, 4)`` local rotations, the root joints carrying the placement.
        points: ``(B, P, 3)`` their world positions, metres.
        body_speed: ``(B,)`` each agent's walking speed, m/s.
        fps: frames per second.
        settings: a :class:`~emotive.ik.foot_lock.LockSettings`.

    Returns:
        The locked rotations and points and the new state.
    """
    rotations, points, state = lock_batch_last(legs, state, _last(rotations), _last(points),
                                               body_speed, fps, settings)
    return _first(rotations), _first(points), state


def lock_batch_last(legs: LegIndex, state: LockTensors, rotations: torch.Tensor,
                    points: torch.Tensor, body_speed: torch.Tensor, fps: float, settings
                    ) -> tuple[torch.Tensor, torch.Tensor, LockTensors]:
    """:func:`lock_step` on rotations ``(J, 4, B)`` and points ``(P, 3, B)``, agents last.

    The state is given and returned as :func:`lock_step`'s (agents first).
    """
    state = LockTensors(*(_last_view(x) for x in state))
    ix = legs.index
    feet = torch.stack((points.index_select(0, ix["ankle"]),
                        points.index_select(0, ix["toe"])), 1)
    xz = feet[:, :, 0::2]
    planted = _contacts(legs, state, feet, body_speed, fps, settings)
    correction, anchor, planted, released, factor = _corrections(
        state, xz, planted, settings.release_frames, settings.max_correction * legs.leg_length)
    yaw_correction, yaw_anchor = _yaw_corrections(state, feet, planted.any(1), factor)
    zero = torch.zeros_like(correction[:, 0])
    shift = torch.stack((correction[:, 0], zero, correction[:, 1]), 1)
    rotations, points = _two_bone(legs, rotations, points, shift, yaw_correction)
    new = (feet, planted, anchor, correction, yaw_anchor, yaw_correction, released)
    return rotations, points, LockTensors(*(_first(x) for x in new))
