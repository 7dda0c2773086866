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
    index: dict[str, torch.Tensor] = field(init=False, repr=False, compare=False)
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


def _unit(x: torch.Tensor, eps: float = 1e-12) -> torch.Tensor:
    return x / torch.sqrt((x * x).sum(-1, keepdim=True)).clamp_min(eps)


def _norm(x: torch.Tensor) -> torch.Tensor:
    return torch.sqrt((x * x).sum(-1))


def _conj(q: torch.Tensor) -> torch.Tensor:
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def _between(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``(..., 4)`` shortest rotation taking direction ``u`` to direction ``v``."""
    u, v = _unit(u), _unit(v)
    w = 1.0 + (u * v).sum(-1, keepdim=True)
    q = torch.cat((w, cross(u, v)), -1)
    q = torch.where(w > 1e-9, q, q.new_tensor([1.0, 0.0, 0.0, 0.0]))
    return _unit(q)


def wrap_angle(x: torch.Tensor) -> torch.Tensor:
    """Angles wrapped to ``(-pi, pi]``."""
    return torch.atan2(torch.sin(x), torch.cos(x))


def fade(released: torch.Tensor, frames: int) -> torch.Tensor:
    """``(B, 2)`` factor taking a correction from ``released - 1`` to ``released`` frames.

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


def contacts(legs: LegIndex, state: LockTensors, feet: torch.Tensor, body: torch.Tensor,
             fps: float, settings) -> torch.Tensor:
    """``(B, 2, 2)`` planted heels and toes after this frame's hysteresis.

    Args:
        legs: the legs.
        state: the lock's state after the previous frame.
        feet: ``(B, 2, 2, 3)`` heel and toe positions of each leg.
        body: ``(B,)`` the body's walking speed, m/s.
        fps: frames per second.
        settings: a :class:`~emotive.ik.foot_lock.LockSettings`.
    """
    scale = legs.leg_length
    height = feet[..., 1] - legs.ground.to(feet.dtype)
    speed = _norm(feet - state.previous) * fps
    speed = torch.where(torch.isnan(speed), torch.full_like(speed, NO_PREVIOUS_SPEED), speed)
    body = body[:, None, None]
    on = (height < settings.height_on * scale) & (
        speed < settings.speed_on * scale + settings.body_on * body)
    off = (height > settings.height_off * scale) | (
        speed > settings.speed_off * scale + settings.body_off * body)
    return on | (state.planted & ~off)


def corrections(state: LockTensors, feet: torch.Tensor, planted: torch.Tensor,
                factor: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """This frame's ``(B, 2, 2)`` horizontal corrections and anchors.

    While the heel is planted the heel is held where it planted; with only the toe planted,
    the toe where the heel lifted; new anchors are taken from the corrected foot; in swing
    the correction is scaled by ``factor`` ``(B, 2)`` (:func:`fade`).
    """
    xz = torch.stack((feet[..., 0], feet[..., 2]), -1)
    heel, toe = planted[..., 0], planted[..., 1]
    was_heel = state.planted[..., 0]
    was_held = state.planted.any(-1)
    held_heel = heel & was_heel
    held_toe = toe & ~heel & was_held & ~was_heel
    ref = torch.where(heel[..., None], xz[..., 0, :], xz[..., 1, :])
    fresh = ref + state.correction
    anchor = torch.where((held_heel | held_toe)[..., None], state.anchor, fresh)
    correction = torch.where((heel | toe)[..., None], anchor - ref,
                             factor[..., None] * state.correction)
    return correction, anchor


def yaw_corrections(state: LockTensors, feet: torch.Tensor, contact: torch.Tensor,
                    factor: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """This frame's ``(B, 2)`` yaw corrections and anchors (radians).

    A foot in contact keeps the yaw of its heel -> toe direction (0 faces +Z) it had,
    corrected, when the contact began; in swing the correction is scaled by ``factor``.
    """
    d = feet[..., 1, :] - feet[..., 0, :]
    yaw = torch.atan2(d[..., 0], d[..., 2])
    fresh = yaw + state.yaw_correction
    anchor = torch.where(contact & state.planted.any(-1), state.yaw_anchor, fresh)
    return torch.where(contact, wrap_angle(anchor - yaw), factor * state.yaw_correction), anchor


def _world_rotations(legs: LegIndex, rotations: torch.Tensor) -> dict[int, torch.Tensor]:
    """World rotations ``(B, 4)`` of the joints on the paths from the roots to the ankles."""
    world: dict[int, torch.Tensor] = {}
    for joints, parents in legs.world_levels:
        local = rotations[:, list(joints)]
        if parents[0] < 0:
            level = local
        else:
            level = quaternion_multiply(torch.stack([world[p] for p in parents], 1), local)
        for k, j in enumerate(joints):
            world[j] = level[:, k]
    return world


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
    world = _world_rotations(legs, rotations)
    ix = legs.index
    h, k, a = (points.index_select(1, ix[n]) for n in ("hip", "knee", "ankle"))
    la, lb = _norm(k - h), _norm(a - k)
    reach = la + lb - 1e-6
    target = a + shift
    flat = _norm(torch.stack((target[..., 0] - h[..., 0], target[..., 2] - h[..., 2]), -1))
    lowest = h[..., 1] - torch.sqrt((reach * reach - flat * flat).clamp_min(0.0))
    target = torch.stack((target[..., 0], torch.maximum(target[..., 1], lowest),
                          target[..., 2]), -1)
    to_target = target - h
    d = torch.minimum(torch.maximum(_norm(to_target), (la - lb).abs() + 1e-6), reach)
    u = _unit(to_target)
    side = (k - h) - ((k - h) * u).sum(-1, keepdim=True) * u
    v = _unit(side)
    along = (la * la - lb * lb + d * d) / (2 * d)
    k_new = h + along[..., None] * u + torch.sqrt((la * la - along * along).clamp_min(0.0))[
        ..., None] * v
    a_new = h + d[..., None] * u

    def per_leg(name: int) -> torch.Tensor:
        return torch.stack([world[c[name]] for c in legs.chain], 1)

    g_up, g_hip, g_knee, g_ankle = per_leg(0), per_leg(1), per_leg(2), per_leg(3)
    r1 = _between(k - h, k_new - h)
    g_hip2 = quaternion_multiply(r1, g_hip)
    r2 = _between(rotate(r1, a - k), a_new - k_new)
    g_knee2 = quaternion_multiply(r2, quaternion_multiply(r1, g_knee))
    half = 0.5 * yaw
    zero = torch.zeros_like(half)
    turn = torch.stack((torch.cos(half), zero, torch.sin(half), zero), -1)
    new = torch.cat((
        _unit(quaternion_multiply(_conj(g_up), g_hip2)),
        _unit(quaternion_multiply(_conj(g_hip2), g_knee2)),
        _unit(quaternion_multiply(_conj(g_knee2), quaternion_multiply(turn, g_ankle))),
    ), 1)
    rotations = torch.cat((rotations, new), 1).index_select(1, ix["rotation_source"])
    leg = ix["below_leg"]
    moved = a_new.index_select(1, leg) + rotate(
        turn.index_select(1, leg), points.index_select(1, ix["below"]) - a.index_select(1, leg))
    points = torch.cat((points, k_new, moved), 1).index_select(1, ix["point_source"])
    return rotations, points


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
    feet = torch.stack((points.index_select(1, legs.index["ankle"]),
                        points.index_select(1, legs.index["toe"])), 2)
    planted = contacts(legs, state, feet, body_speed, fps, settings)
    # A foot whose correction would be too long is dragged, not planted: release it.
    released = torch.where(planted.any(-1), torch.zeros_like(state.released),
                           state.released + 1.0)
    correction, _ = corrections(state, feet, planted, fade(released, settings.release_frames))
    dragged = _norm(correction) > settings.max_correction * legs.leg_length
    planted = planted & ~dragged[..., None]
    released = torch.where(planted.any(-1), torch.zeros_like(state.released),
                           state.released + 1.0)
    factor = fade(released, settings.release_frames)
    correction, anchor = corrections(state, feet, planted, factor)
    yaw_correction, yaw_anchor = yaw_corrections(state, feet, planted.any(-1), factor)
    zero = torch.zeros_like(correction[..., 0])
    shift = torch.stack((correction[..., 0], zero, correction[..., 1]), -1)
    rotations, points = two_bone(legs, rotations, points, shift, yaw_correction)
    return rotations, points, LockTensors(feet, planted, anchor, correction, yaw_anchor,
                                          yaw_correction, released)
