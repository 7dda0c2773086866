"""Feet kept above the floor: a heel or toe lower than where it stands on level ground is lifted.

The floor is the plane ``y = 0`` of the bodies' world. A rig's foot points do not lie on it
when its foot stands flat: the ankle joint (the heel of
:data:`emotive.features.contacts.FOOT_ROLES`) sits centimetres above the sole and the toe
point anywhere from the ball of the foot to the tip (on the Bandai Namco rig 11.8 cm and
4.5 cm). So each point has its own *floor height*, the height it has when its foot stands on
the floor, and it is *below the floor* by how much lower it goes: a toe 2 cm under its floor
height has the sole of the toes 2 cm under ``y = 0``. A floor height comes from a standing
pose (:func:`standing_floor`, the gait generator's, which its foot lock calls the ground) or
from a clip's own feet (:func:`clip_floor`, each point's 5th percentile over the clip, as
:func:`emotive.features.contacts.ground_heights` takes it).

:func:`keep_above_floor` lifts each foot, in the frames where its heel or toe is more than
:data:`FLOOR_ALLOWANCE` below the floor, by what its lower point is deeper than that, spread
over a few frames so that the lift adds no kink to the foot's path (real feet dip a few
millimetres under their floor height as the toes bend and the foot rolls: those dips are
left alone); on rigs whose hip, knee and ankle are parent and child the legs follow by
the analytic two-bone solve of the foot lock (:func:`emotive.ik.foot_lock.move_ankles`: the
ankle moves straight up, the foot keeps its orientation, the hips and the horizontal position
of the foot stay, so planted feet stay planted). Other rigs lift the whole body, through the
root, by the deeper foot's lift.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``P = J + E`` points.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from emotive.core.motion import Motion
from emotive.core.roles import JointRoles, resolve_roles
from emotive.features.contacts import FOOT_ROLES, ContactThresholds
from emotive.ik.foot_lock import leg_rig, move_ankles
from emotive.transforms.np_rotations import quaternion_apply, quaternion_invert

RoleMap = str | Path | dict[str, str] | None

__all__ = [
    "FLOOR_ALLOWANCE",
    "FLOOR_TOLERANCE",
    "LIFT_SECONDS",
    "clip_floor",
    "depth_below_floor",
    "keep_above_floor",
    "lift_feet",
    "spread_lifts",
    "standing_floor",
]

#: How far (metres) a foot point may go below its floor height in what ``emotive generate``
#: and ``emotive transfer`` write (what their tests check).
FLOOR_TOLERANCE = 0.01
#: Depth below the floor (metres) that :func:`keep_above_floor` leaves as it is: half the
#: tolerance. Real walks dip up to about 6 mm under their standing pose's toe height (Bandai
#: Namco ``walk_normal_001``), which is the foot rolling, not sinking.
FLOOR_ALLOWANCE = 0.005
#: Seconds over which a lift is spread (a running maximum over this window, then a Gaussian
#: of a third of it): 0.15 s is 4-5 frames at 30 fps, shorter than a stance.
LIFT_SECONDS = 0.15
#: A lift smaller than this (metres) is not applied.
MIN_LIFT = 1e-6


def standing_floor(standing: np.ndarray, roles: JointRoles) -> np.ndarray:
    """``(2, 2)`` floor heights from a pose standing on the floor.

    Args:
        standing: ``(P, 3)`` world positions of the standing pose, joints then end sites.
        roles: the rig's resolved roles.

    Returns:
        Heights (metres) of the left then right foot's heel then toe.
    """
    return np.asarray(standing)[roles.indices(FOOT_ROLES), 1].reshape(2, 2).copy()


def clip_floor(points: np.ndarray, roles: JointRoles,
               percentile: float = ContactThresholds.ground_percentile) -> np.ndarray:
    """``(2, 2)`` floor heights of a clip's own feet: each point's low percentile.

    Args:
        points: ``(T, P, 3)`` world positions, joints then end sites, ``T >= 1``.
        roles: the rig's resolved roles.
        percentile: the percentile of each point's height taken as its floor height (that of
            the contact detection by default: it assumes each foot touches the floor at
            least that share of the clip, as in every gait).

    Returns:
        Heights (metres) of the left then right foot's heel then toe.
    """
    heights = np.asarray(points)[:, roles.indices(FOOT_ROLES), 1]
    return np.percentile(heights, percentile, axis=0).reshape(2, 2)


def depth_below_floor(points: np.ndarray, roles: JointRoles, floor: np.ndarray) -> np.ndarray:
    """``(..., T, 2, 2)`` how far (metres) each heel and toe is below its floor height.

    ``max(0, floor - y)`` per point: 0 on or above the floor.

    Args:
        points: ``(..., T, P, 3)`` world positions, joints then end sites.
        roles: the rig's resolved roles.
        floor: ``(2, 2)`` floor heights (:func:`standing_floor`, :func:`clip_floor`).
    """
    heights = np.asarray(points)[..., roles.indices(FOOT_ROLES), 1]
    heights = heights.reshape(*heights.shape[:-1], 2, 2)
    return np.maximum(np.asarray(floor, dtype=np.float64) - heights, 0.0)


def spread_lifts(depth: np.ndarray, fps: float) -> np.ndarray:
    """``(T, 2)`` lift of each foot: ``depth`` spread over :data:`LIFT_SECONDS`, never less.

    A running maximum then a Gaussian of a third of its width starts the lift before the
    foot reaches the floor and ends it after; the maximum with the depth itself keeps the
    peak of a one-frame dip, which the Gaussian alone would shave.

    Args:
        depth: ``(T, 2)`` how far each foot must rise in each frame, metres.
        fps: frames per second.
    """
    width = max(1, round(LIFT_SECONDS * fps))
    spread = maximum_filter1d(depth, width, axis=0, mode="nearest")
    if width > 1:
        spread = gaussian_filter1d(spread, width / 3.0, axis=0, mode="nearest")
    return np.maximum(spread, depth)


def keep_above_floor(motion: Motion, floor: np.ndarray, role_map: RoleMap = None,
                     allowance: float = FLOOR_ALLOWANCE) -> Motion:
    """The clip with no heel or toe more than ``allowance`` below its floor height.

    See the module docstring.

    Args:
        motion: the clip (world placement in its root joints; Y up, metres).
        floor: ``(2, 2)`` floor heights of the left then right foot's heel then toe
            (:func:`standing_floor`, :func:`clip_floor`).
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).
        allowance: depth below the floor left as it is, metres.

    Returns:
        The clip with its feet lifted where they were below the floor (itself when none was).

    Raises:
        ValueError: ``floor`` is not ``(2, 2)``.
    """
    floor = np.asarray(floor, dtype=np.float64)
    if floor.shape != (2, 2):
        raise ValueError(f"floor must be (2, 2) heights (left, right x heel, toe), got "
                         f"{floor.shape}")
    if motion.num_frames == 0:
        return motion
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    depth = depth_below_floor(points, roles, floor).max(-1)
    return lift_feet(motion, spread_lifts(np.maximum(depth - allowance, 0.0), motion.fps),
                     role_map)


def lift_feet(motion: Motion, lift: np.ndarray, role_map: RoleMap = None) -> Motion:
    """Each foot moved straight up by its ``lift``, the hips kept (see the module docstring).

    Args:
        motion: the clip.
        lift: ``(T, 2)`` metres, left then right foot (e.g. from :func:`spread_lifts`).
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).

    Returns:
        The clip with its legs re-posed by the two-bone solve, or on rigs with joints
        between hip, knee and ankle the whole body lifted through the root by the larger
        lift of each frame; itself when nothing moves.

    Raises:
        ValueError: ``lift`` is not ``(T, 2)``.
    """
    lift = np.asarray(lift, dtype=np.float64)
    if lift.shape != (motion.num_frames, 2):
        raise ValueError(f"lift must be ({motion.num_frames}, 2) (frames, left and right), "
                         f"got {lift.shape}")
    moving = lift.max(1, initial=0.0) > MIN_LIFT
    if not moving.any():
        return motion
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    try:
        legs = leg_rig(motion.skeleton, roles, points[0])
    except ValueError:
        return _lift_root(motion, roles, lift.max(1))
    shift = np.zeros((motion.num_frames, 2, 3))
    shift[..., 1] = lift
    rotations = motion.rotations.copy()
    rotations[moving], _ = move_ankles(legs, rotations[moving], points[moving], shift[moving],
                                       np.zeros((int(moving.sum()), 2)))
    return motion.replace(rotations=rotations)


def _lift_root(motion: Motion, roles: JointRoles, lift: np.ndarray) -> Motion:
    """The whole body moved up by ``lift`` ``(T,)`` metres through the root joint."""
    root = roles.index["root"]
    up = np.zeros((motion.num_frames, 3))
    up[:, 1] = lift
    parent = int(motion.skeleton.parents[root])
    if parent >= 0:
        up = quaternion_apply(quaternion_invert(motion.global_transforms()[0][:, parent]), up)
    positions = motion.positions.copy()
    positions[:, root] += up
    return motion.replace(positions=positions)
