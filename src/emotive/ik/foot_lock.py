"""Causal foot locking: planted feet held still frame by frame, for streams of many agents.

The offline cleanup (:func:`emotive.ik.api.pin_feet`) pins each contact to its mean position
over the whole contact, which needs the future. A live stream has only the frames so far, so
:func:`lock_feet` decides from the current and the previous frame alone (no latency):

1. **Contacts with hysteresis.** Each foot has two points, the heel (ankle joint) and the toe.
   A point *plants* when it is low (under ``height_on`` leg lengths above its height in the
   standing pose) and slow (under ``speed_on`` leg lengths per second, backward difference of
   the unlocked stream), and stays planted until it is clearly lifted or moving (``height_off``,
   ``speed_off``). A foot is in contact while either point is planted.
2. **One horizontal correction and one yaw per foot.** While the heel is planted the
   correction keeps the heel where it was when it planted; when only the toe is planted
   (heel off) it keeps the toe where it was when the heel lifted; a foot in contact also
   keeps its heading (the yaw of heel -> toe) from when the contact began. Anchors are taken
   from the *corrected* foot, so the corrections never jump. In swing the corrections fade
   out along a smoothstep over :attr:`LockSettings.release_frames` frames (the factor
   ``1 - (3 x^2 - 2 x^3)``, ``x`` the frames since the contact ended over that count), so the
   released foot starts and ends its catch-up with zero relative velocity.
3. **Two-bone IK per leg.** The ankle is moved by the correction (heights are left as
   predicted, except that an ankle the straight leg cannot reach is lifted until it can) by
   an analytic hip-knee-ankle solve that keeps the knee in its current bending plane and the
   foot's world orientation (turned by the yaw correction); everything below the ankle moves
   with it.

Everything is batched over agents and legs with plain NumPy (:mod:`emotive.transforms.fast_np`).

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``P = J + E`` points.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from emotive.core.roles import JointRoles
from emotive.core.skeleton import Skeleton
from emotive.transforms.fast_np import cross, qapply, qmul, qnormalize


@dataclass(frozen=True)
class LockSettings:
    """Contact and release settings (heights in leg lengths, speeds in leg lengths per second).

    The heights and base speeds are those of
    :class:`emotive.features.contacts.ContactThresholds`; the speed thresholds grow with the
    body's walking speed because the unlocked stream's planted feet slide with the body
    (0.3-0.5 m/s measured on happy and angry walks), while swinging feet move at 1-4 m/s.

    Attributes:
        height_on: a point may plant below this height above its standing height.
        height_off: a planted point lifts above this height.
        speed_on: a point may plant below this speed plus ``body_on`` times the body's.
        speed_off: a planted point is released above this speed plus ``body_off`` times the
            body's.
        body_on: share of the body's walking speed added to ``speed_on``: a planted foot of
            the unlocked stream slides at up to about half the body's speed, a swinging one
            moves at about twice it.
        body_off: share of the body's walking speed added to ``speed_off``.
        max_correction: a foot whose correction would exceed this many leg lengths is released
            (a foot dragged along, not planted). 0.35 holds the toes of slow sad walks, whose
            unlocked planted feet drift up to about 0.3 m over a stance, until they lift; at
            0.25 they were let go while still on the floor, a one-frame slide of about 8 cm.
        release_frames: frames over which a released foot's correction fades to zero.
    """

    height_on: float = 0.03
    height_off: float = 0.05
    speed_on: float = 0.8
    speed_off: float = 1.2
    body_on: float = 1.3
    body_off: float = 1.8
    max_correction: float = 0.35
    release_frames: int = 6


@dataclass(frozen=True)
class LegRig:
    """Indices and constants of the two legs (left, right) of a rig.

    Attributes:
        chain: ``(2, 4)`` joint indices per leg: hip's parent, hip, knee, ankle.
        toe: ``(2,)`` index of each toe point in the ``P`` points.
        below: ``(2, P)`` bool, the points that move with each ankle (the ankle included).
        ground: ``(2, 2)`` standing height of each leg's heel and toe (metres).
        leg_length: hip -> knee -> ankle length of the standing pose (metres).
        parents: ``(J,)`` the rig's parents.
    """

    chain: np.ndarray
    toe: np.ndarray
    below: np.ndarray
    ground: np.ndarray
    leg_length: float
    parents: np.ndarray


def leg_rig(skeleton: Skeleton, roles: JointRoles, standing: np.ndarray) -> LegRig:
    """The legs of a rig whose hip, knee and ankle are parent and child in turn.

    Args:
        skeleton: the rig.
        roles: its roles.
        standing: ``(P, 3)`` world positions of the standing pose (joints then end sites).

    Raises:
        ValueError: a leg's knee is not the hip's child or the ankle not the knee's.
    """
    n = skeleton.num_joints
    chain, toe, below, ground, length = [], [], [], [], []
    owner = np.concatenate((np.arange(n), skeleton.end_site_parents))
    for side in ("l", "r"):
        hip, knee, ankle = (roles.index[f"{side}_{r}"] for r in ("hip", "knee", "ankle"))
        if skeleton.parents[knee] != hip or skeleton.parents[ankle] != knee:
            raise ValueError(f"causal foot locking needs {side}_hip -> {side}_knee -> "
                             f"{side}_ankle as parent and child; the rig has joints between")
        chain.append((skeleton.parents[hip], hip, knee, ankle))
        toe.append(roles.index[f"{side}_toe"])
        sub = np.zeros(n, dtype=bool)
        sub[ankle] = True
        for j in range(ankle + 1, n):
            sub[j] = sub[skeleton.parents[j]]
        below.append(sub[owner])
        ground.append((standing[ankle, 1], standing[toe[-1], 1]))
        length.append(np.linalg.norm(standing[knee] - standing[hip])
                      + np.linalg.norm(standing[ankle] - standing[knee]))
    return LegRig(np.array(chain), np.array(toe), np.array(below), np.array(ground),
                  float(np.mean(length)), np.asarray(skeleton.parents))


class LockState(NamedTuple):
    """Per-agent state of :func:`lock_feet` (one row per agent).

    Attributes:
        previous: ``(B, 2, 2, 3)`` unlocked heel and toe positions of the previous frame per
            leg (NaN before the first frame).
        planted: ``(B, 2, 2)`` whether each heel and toe is planted.
        anchor: ``(B, 2, 2)`` ``(x, z)`` the planted point is held at.
        correction: ``(B, 2, 2)`` current horizontal correction of each foot, metres.
        yaw_anchor: ``(B, 2)`` world yaw (radians) each foot in contact is held at.
        yaw_correction: ``(B, 2)`` current yaw correction of each foot, radians.
        released: ``(B, 2)`` frames since each foot's contact ended (0 while in contact).
    """

    previous: np.ndarray
    planted: np.ndarray
    anchor: np.ndarray
    correction: np.ndarray
    yaw_anchor: np.ndarray
    yaw_correction: np.ndarray
    released: np.ndarray


def initial_lock_state(agents: int) -> LockState:
    """The state of ``agents`` new agents: nothing planted, no correction."""
    return LockState(np.full((agents, 2, 2, 3), np.nan), np.zeros((agents, 2, 2), dtype=bool),
                     np.zeros((agents, 2, 2)), np.zeros((agents, 2, 2)), np.zeros((agents, 2)),
                     np.zeros((agents, 2)), np.zeros((agents, 2)))


def _fade(released: np.ndarray, frames: int) -> np.ndarray:
    """``(B, 2)`` factor taking a correction from ``released - 1`` to ``released`` frames.

    The correction left ``k`` frames after a contact ended is ``c0 * s(k)``, ``s`` the
    smoothstep from 1 to 0 over ``frames`` frames, so one frame scales it by
    ``s(k) / s(k - 1)``.
    """

    def left(k: np.ndarray) -> np.ndarray:
        x = np.clip(k / max(frames, 1), 0.0, 1.0)
        return 1.0 - x * x * (3.0 - 2.0 * x)

    before = left(released - 1.0)
    return np.where(before > 0, left(released) / np.maximum(before, 1e-12), 0.0)


def _conj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(..., 4)`` shortest rotation taking direction ``u`` to direction ``v``."""
    u = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    v = v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)
    w = 1.0 + (u * v).sum(-1, keepdims=True)
    q = np.concatenate((w, cross(u, v)), -1)
    return qnormalize(np.where(w > 1e-9, q, np.array([1.0, 0.0, 0.0, 0.0])))


def _world_rotations(rotations: np.ndarray, parents: np.ndarray, upto: np.ndarray
                     ) -> np.ndarray:
    """``(B, J, 4)`` world rotations of the joints on the paths to ``upto`` (others identity)."""
    need = np.zeros(len(parents), dtype=bool)
    for j in upto.ravel():
        while j >= 0 and not need[j]:
            need[j] = True
            j = parents[j]
    world = np.zeros_like(rotations)
    world[..., 0] = 1.0
    for j in np.flatnonzero(need):
        p = parents[j]
        world[:, j] = rotations[:, j] if p < 0 else qmul(world[:, p], rotations[:, j])
    return world


def _contacts(rig: LegRig, state: LockState, feet: np.ndarray, body: np.ndarray, fps: float,
              settings: LockSettings) -> np.ndarray:
    """``(B, 2, 2)`` planted heels and toes after this frame's hysteresis."""
    scale = rig.leg_length
    height = feet[..., 1] - rig.ground
    speed = np.linalg.norm(feet - state.previous, axis=-1) * fps
    speed = np.where(np.isfinite(speed), speed, np.inf)
    body = body[:, None, None]
    on = (height < settings.height_on * scale) & (
        speed < settings.speed_on * scale + settings.body_on * body)
    off = (height > settings.height_off * scale) | (
        speed > settings.speed_off * scale + settings.body_off * body)
    return on | (state.planted & ~off)


def _corrections(state: LockState, feet: np.ndarray, planted: np.ndarray, fade: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """This frame's ``(B, 2, 2)`` corrections and anchors (see the module docstring)."""
    xz = feet[..., [0, 2]]
    heel, toe = planted[..., 0], planted[..., 1]
    was_heel = state.planted[..., 0]
    was_held = state.planted.any(-1)
    held_heel = heel & was_heel
    held_toe = toe & ~heel & was_held & ~was_heel
    # A new anchor is where the corrected planted point stands now.
    ref = np.where(heel[..., None], xz[..., 0, :], xz[..., 1, :])
    fresh = ref + state.correction
    anchor = np.where((held_heel | held_toe)[..., None], state.anchor, fresh)
    correction = np.where((heel | toe)[..., None], anchor - ref, fade[..., None] * state.correction)
    return correction, anchor


def _yaws(feet: np.ndarray) -> np.ndarray:
    """``(B, 2)`` world yaw of each foot's heel -> toe direction (0 faces +Z)."""
    d = feet[..., 1, :] - feet[..., 0, :]
    return np.arctan2(d[..., 0], d[..., 2])


def _yaw_corrections(state: LockState, yaw: np.ndarray, contact: np.ndarray, fade: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """This frame's ``(B, 2)`` yaw corrections and anchors.

    A foot in contact keeps the yaw it had (corrected) when the contact began; in swing the
    correction fades out.
    """
    fresh = yaw + state.yaw_correction
    anchor = np.where(contact & state.planted.any(-1), state.yaw_anchor, fresh)
    gap = np.angle(np.exp(1j * (anchor - yaw)))
    return np.where(contact, gap, fade * state.yaw_correction), anchor


def _reachable(hip: np.ndarray, target: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """``(..., 3)`` targets beyond a leg's reach raised until the leg reaches them.

    The horizontal position is what the lock holds, so an ankle the straight leg cannot
    reach (at heel strike and toe-off) is lifted rather than left sliding.
    """
    flat = np.linalg.norm((target - hip)[..., [0, 2]], axis=-1)
    lowest = hip[..., 1] - np.sqrt(np.maximum(reach**2 - flat**2, 0.0))
    out = target.copy()
    out[..., 1] = np.maximum(target[..., 1], lowest)
    return out


def _two_bone(rig: LegRig, rotations: np.ndarray, points: np.ndarray, shift: np.ndarray,
              yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotations and points with each ankle moved and each foot turned, hips fixed.

    Each ankle moves by ``shift`` ``(B, 2, 3)`` and each foot turns by ``yaw`` ``(B, 2)``
    about the vertical through its ankle. Both legs are solved at once: every array below
    carries a leg axis after the agents' (``(B, 2, ...)``).
    """
    parents_world = _world_rotations(rotations, rig.parents, rig.chain[:, 3])
    rotations, points = rotations.copy(), points.copy()
    up, hip, knee, ankle = rig.chain.T
    h, k, a = points[:, hip], points[:, knee], points[:, ankle]
    la = np.linalg.norm(k - h, axis=-1)
    lb = np.linalg.norm(a - k, axis=-1)
    target = _reachable(h, a + shift, la + lb - 1e-6)
    reach = target - h
    d = np.clip(np.linalg.norm(reach, axis=-1), np.abs(la - lb) + 1e-6, la + lb - 1e-6)
    u = reach / np.maximum(np.linalg.norm(reach, axis=-1, keepdims=True), 1e-12)
    side = (k - h) - ((k - h) * u).sum(-1, keepdims=True) * u
    v = side / np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-12)
    along = (la**2 - lb**2 + d**2) / (2 * d)
    k_new = h + along[..., None] * u + np.sqrt(np.maximum(la**2 - along**2, 0))[..., None] * v
    a_new = h + d[..., None] * u
    g_up, g_hip = parents_world[:, up], parents_world[:, hip]
    g_knee, g_ankle = parents_world[:, knee], parents_world[:, ankle]
    r1 = _between(k - h, k_new - h)
    g_hip2 = qmul(r1, g_hip)
    r2 = _between(qapply(r1, a - k), a_new - k_new)
    g_knee2 = qmul(r2, qmul(r1, g_knee))
    half = 0.5 * yaw
    turn = np.stack((np.cos(half), np.zeros_like(half), np.sin(half), np.zeros_like(half)), -1)
    rotations[:, hip] = qnormalize(qmul(_conj(g_up), g_hip2))
    rotations[:, knee] = qnormalize(qmul(_conj(g_hip2), g_knee2))
    rotations[:, ankle] = qnormalize(qmul(_conj(g_knee2), qmul(turn, g_ankle)))
    points[:, knee] = k_new
    for leg in range(2):
        below = rig.below[leg]
        moved = points[:, below] - a[:, leg, None]
        points[:, below] = a_new[:, leg, None] + qapply(turn[:, leg, None], moved)
    return rotations, points


def move_ankles(rig: LegRig, rotations: np.ndarray, points: np.ndarray, shift: np.ndarray,
                yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each ankle moved and each foot turned by the analytic two-bone solve of step 3.

    The solve :func:`lock_feet` applies, for callers that compute their own corrections
    (a whole clip at once: the frames stand in for the agents).

    Args:
        rig: the legs (:func:`leg_rig`).
        rotations: ``(B, J, 4)`` local rotations.
        points: ``(B, P, 3)`` their world positions, joints then end sites.
        shift: ``(B, 2, 3)`` move of each ankle (left, right), metres.
        yaw: ``(B, 2)`` turn of each foot about the vertical through its ankle, radians.

    Returns:
        The rotations ``(B, J, 4)`` and points ``(B, P, 3)``; the hips stay where they are.
    """
    return _two_bone(rig, rotations, points, shift, yaw)


def lock_feet(rig: LegRig, state: LockState, rotations: np.ndarray, points: np.ndarray,
              body_speed: np.ndarray, fps: float, settings: LockSettings | None = None
              ) -> tuple[np.ndarray, np.ndarray, LockState]:
    """Hold this frame's planted feet still (see the module docstring).

    Args:
        rig: the legs (:func:`leg_rig`).
        state: the agents' state after the previous frame.
        rotations: ``(B, J, 4)`` this frame's local rotations as the stream gives them (the
            root joints carrying the world placement).
        points: ``(B, P, 3)`` their world positions, joints then end sites.
        body_speed: ``(B,)`` each agent's walking speed this frame, m/s.
        fps: frames per second of the stream.
        settings: thresholds (:class:`LockSettings` defaults when ``None``).

    Returns:
        The locked rotations ``(B, J, 4)`` and points ``(B, P, 3)``, and the new state.
    """
    settings = settings or LockSettings()
    feet = np.stack((points[:, rig.chain[:, 3]], points[:, rig.toe]), 2)
    planted = _contacts(rig, state, feet, np.asarray(body_speed, dtype=np.float64), fps,
                        settings)
    released = np.where(planted.any(-1), 0.0, state.released + 1.0)
    fade = _fade(released, settings.release_frames)
    correction, anchor = _corrections(state, feet, planted, fade)
    dragged = np.linalg.norm(correction, axis=-1) > settings.max_correction * rig.leg_length
    if dragged.any():
        planted = planted & ~dragged[..., None]
        released = np.where(planted.any(-1), 0.0, state.released + 1.0)
        fade = _fade(released, settings.release_frames)
        correction, anchor = _corrections(state, feet, planted, fade)
    yaw_correction, yaw_anchor = _yaw_corrections(state, _yaws(feet), planted.any(-1), fade)
    shift = np.zeros((len(points), 2, 3))
    shift[..., 0], shift[..., 2] = correction[..., 0], correction[..., 1]
    if np.abs(shift).max(initial=0.0) > 0 or np.abs(yaw_correction).max(initial=0.0) > 0:
        rotations, points = _two_bone(rig, rotations, points, shift, yaw_correction)
    return rotations, points, LockState(feet, planted, anchor, correction, yaw_anchor,
                                        yaw_correction, released)
