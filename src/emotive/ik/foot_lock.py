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

Everything is batched over agents and legs. The computation is the torch kernels of
:mod:`emotive.ik.foot_lock_kernel` (which the exported gait step traces); the functions here
are their NumPy face, in float64.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``P = J + E`` points.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import torch

from emotive.core.roles import JointRoles
from emotive.core.skeleton import Skeleton
from emotive.ik.foot_lock_kernel import LegIndex, LockTensors, lock_step, two_bone


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
    rot, pts = two_bone(leg_index(rig), *_tensors(rotations, points, shift, yaw))
    return rot.numpy(), pts.numpy()


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
    rotations = np.asarray(rotations, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64)
    legs = leg_index(rig)
    previous = LockTensors(*(torch.from_numpy(np.asarray(x)) for x in state))
    body = torch.from_numpy(np.asarray(body_speed, dtype=np.float64).reshape(-1))
    rot, pts = torch.from_numpy(rotations), torch.from_numpy(points)
    locked, moved, new = lock_step(legs, previous, rot, pts, body, fps, settings)
    state = LockState(*(x.numpy() for x in new))
    if not bool((new.correction != 0).any() | (new.yaw_correction != 0).any()):
        return rotations, points, state  # nothing to move: the frame exactly as it came
    return locked.numpy(), moved.numpy(), state


def leg_index(rig: LegRig) -> LegIndex:
    """The legs of ``rig`` as the constants of :mod:`emotive.ik.foot_lock_kernel`."""
    return LegIndex(tuple(tuple(int(j) for j in c) for c in rig.chain),
                    tuple(int(t) for t in rig.toe), torch.from_numpy(np.asarray(rig.below)),
                    torch.from_numpy(np.asarray(rig.ground, dtype=np.float64)),
                    float(rig.leg_length), tuple(int(p) for p in rig.parents))


def _tensors(*arrays: np.ndarray) -> tuple[torch.Tensor, ...]:
    return tuple(torch.from_numpy(np.asarray(a, dtype=np.float64)) for a in arrays)
