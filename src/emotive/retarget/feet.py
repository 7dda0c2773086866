"""Feet of a retargeted clip: where the ground is, how much the feet slide.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from emotive.core.motion import Motion
from emotive.core.roles import JointRoles, resolve_roles
from emotive.features.contacts import FOOT_ROLES, ground_heights
from emotive.ik import resolve_chains, solve_chains
from emotive.ik.api import fade_out
from emotive.ik.foot_lock import leg_rig, move_ankles
from emotive.transforms.np_rotations import quaternion_apply, quaternion_invert

RoleMap = str | Path | dict[str, str] | None

#: A foot target closer than this (metres) to where the foot is needs no IK.
MOVED = 1e-5
#: The leg chains of :mod:`emotive.ik`, left then right.
LEGS = ("left_leg", "right_leg")

#: A foot point this close to its floor (metres) counts as on the ground for :func:`foot_skate`.
SKATE_HEIGHT = 0.02
#: Frames over which a foot's lift to the source's clearance is spread (see plant_feet).
LIFT_SPREAD = 3


def lowest_ankle_height(points: np.ndarray, roles: JointRoles) -> float:
    """Lowest height (Y, metres) either ankle reaches over a clip.

    The ankle joint is the one foot point every rig places alike (toe joints and end sites
    sit anywhere from the ball of the foot to the tip), so it is what puts the two rigs'
    grounds in register.

    Args:
        points: ``(T, J + E, 3)`` world positions of joints then end sites, ``T >= 1``.
        roles: the rig's resolved roles.
    """
    return float(points[:, roles.indices(("l_ankle", "r_ankle")), 1].min())


def move_up(motion: Motion, height: float, mover: int) -> Motion:
    """The clip moved ``height`` metres up the world's Y axis through joint ``mover``.

    Args:
        motion: the clip.
        height: metres (negative moves down).
        mover: the joint whose translation carries the world placement (the root role or the
            animated joint above it).
    """
    if height == 0.0:
        return motion
    up = np.broadcast_to([0.0, height, 0.0], (motion.num_frames, 3))
    parent = int(motion.skeleton.parents[mover])
    if parent >= 0:
        up = quaternion_apply(quaternion_invert(motion.global_transforms()[0][:, parent]), up)
    positions = motion.positions.copy()
    positions[:, mover] += up
    return motion.replace(positions=positions)


def foot_skate(motion: Motion, role_map: RoleMap = None,
               height: float = SKATE_HEIGHT) -> float:
    """Mean horizontal speed (m/s) of heels and toes while they touch the floor.

    Each heel (``*_ankle``) and toe (``*_toe``) counts in the frames where it is within
    ``height`` of its own floor height (its 5th percentile over the clip, as in
    :func:`emotive.features.contacts.ground_heights`, which absorbs an ankle joint that sits
    centimetres above the sole); its speed is the central-difference ``(x, z)`` velocity.
    A clip whose points never come near the floor scores 0.

    Args:
        motion: the clip, ``T >= 2`` frames.
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).
        height: metres above the floor that count as touching it.

    Returns:
        The mean speed over every (point, frame) on the floor, m/s.
    """
    roles = resolve_roles(motion.skeleton, role_map)
    idx = roles.indices(FOOT_ROLES)
    feet = motion.positions_with_end_sites()[:, idx]
    if len(feet) < 2:
        return 0.0
    low = ground_heights(feet) < height
    speed = np.linalg.norm(np.gradient(feet[..., [0, 2]], axis=0), axis=-1) * motion.fps
    return float(speed[low].mean()) if low.any() else 0.0


def _runs(column: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of each run of ``True`` in a ``(T,)`` bool column."""
    edges = np.diff(np.concatenate(([0], column.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _planted_targets(world: np.ndarray, source: np.ndarray, contact: np.ndarray,
                     scale: float, blend: int) -> np.ndarray:
    """``(T, M, 3)`` foot targets: during each contact the source's horizontal motion, scaled.

    Over a contact run the target's heel and toe move as the source's do, times ``scale``,
    about their mean over the run; heights stay the target's. The correction fades out over
    ``blend`` frames either side of the run.
    """
    delta = np.zeros_like(world)
    for a, b in _runs(contact):
        wanted = world[a:b].mean(0) + scale * (source[a:b] - source[a:b].mean(0))
        delta[a:b, :, [0, 2]] = (wanted - world[a:b])[..., [0, 2]]
    return world + fade_out(delta, contact, blend)


def _yaw(heel: np.ndarray, toe: np.ndarray) -> np.ndarray:
    """``(...)`` world heading (radians, 0 facing +Z) of heel -> toe, ``(..., 3)`` points."""
    d = toe - heel
    return np.arctan2(d[..., 0], d[..., 2])


def plant_feet(motion: Motion, source_points: np.ndarray, source_roles: JointRoles,
               contacts: np.ndarray, scale: float, role_map: RoleMap = None,
               blend: int = 4) -> Motion:
    """Feet planted in the source kept planted on the target.

    While a source foot touches the ground, the target's heel and toe follow the source's
    heel and toe horizontally, scaled like the root (so a planted source foot gives a
    planted target foot, and the little a real foot rolls is kept); the correction fades in
    and out over ``blend`` frames. On rigs whose hip, knee and ankle are parent and child,
    each leg is solved for all frames at once by the analytic two-bone solve of the foot lock
    (:func:`emotive.ik.foot_lock.move_ankles`): the heel lands exactly on its target
    horizontally (an ankle the straight leg cannot reach is lifted until it can), the foot
    turns about the vertical so that its toe points at the toe's target, and the knee stays
    in its bending plane. Other rigs re-solve the leg chains by damped least squares
    (:func:`emotive.ik.solve_chains`) in the frames where a foot must move by more than
    :data:`MOVED` metres. A rig whose feet already follow the source's (the source's own)
    is left untouched.

    Args:
        motion: the retargeted clip, ``T`` frames.
        source_points: ``(T, J + E, 3)`` world positions of the source's joints then end sites.
        source_roles: the source's resolved roles.
        contacts: ``(T, 2)`` bool, left then right foot of the source.
        scale: the root motion's scale (target over source leg length).
        role_map: the target's role map (see :func:`emotive.core.roles.resolve_roles`).
        blend: frames over which the correction fades in and out.

    Returns:
        The clip with its legs re-posed where the feet had to move.
    """
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    try:
        legs = leg_rig(motion.skeleton, roles, points[0])
    except ValueError:
        return _plant_by_chains(motion, source_points, source_roles, contacts, scale,
                                role_map, blend)
    shift = np.zeros((motion.num_frames, 2, 3))
    yaw = np.zeros((motion.num_frames, 2))
    for side, prefix in enumerate(("l", "r")):
        feet = (f"{prefix}_ankle", f"{prefix}_toe")
        world = points[:, roles.indices(feet)]
        source = source_points[:, source_roles.indices(feet)]
        targets = _planted_targets(world, source, contacts[:, side], scale, blend)
        shift[:, side] = targets[:, 0] - world[:, 0]
        turn = _yaw(targets[:, 0], targets[:, 1]) - _yaw(world[:, 0], world[:, 1])
        flat = np.linalg.norm((targets[:, 1] - targets[:, 0])[:, [0, 2]], axis=-1)
        yaw[:, side] = np.where(flat > MOVED, np.angle(np.exp(1j * turn)), 0.0)
    moving = (np.abs(shift).max(axis=(1, 2)) > MOVED) | (np.abs(yaw).max(axis=1) > MOVED)
    if not moving.any():
        return motion
    rotations = motion.rotations.copy()
    rotations[moving], _ = move_ankles(legs, rotations[moving], points[moving],
                                       shift[moving], yaw[moving])
    source_feet = source_points[:, source_roles.indices(FOOT_ROLES)]
    clearance = scale * ground_heights(source_feet).reshape(-1, 2, 2)
    return _keep_clearance(motion.replace(rotations=rotations), legs, roles, clearance)


def _keep_clearance(motion: Motion, legs, roles: JointRoles, clearance: np.ndarray) -> Motion:
    """Each foot raised where its heel or toe is nearer the floor than the source's, scaled.

    A target foot longer or pitched unlike the source's brings its toe (or heel) down to
    the floor in frames where the source's is in the air: the toe scuffs the floor as it
    swings through, or touches down early, and slides along it. Each foot is lifted, keeping
    its orientation, by the most that its heel or toe is below the source's same point's
    height above its floor times the legs' scale; the leg follows by the two-bone solve.
    Where the source's heel is on the ground (within :data:`SKATE_HEIGHT`) the heel's plant
    is kept and a low toe is left as it is (the toe's share fades in over the next
    :data:`SKATE_HEIGHT`). The lift is spread over :data:`LIFT_SPREAD` frames (a running
    maximum, then a Gaussian of a third of that width), so it adds no kink to the ankle's
    path.

    Args:
        motion: the clip after the source's contacts were planted.
        legs: its legs (:func:`emotive.ik.foot_lock.leg_rig`).
        roles: its resolved roles.
        clearance: ``(T, 2, 2)`` metres, the source's heights above its floor times the
            scale: left then right foot, heel then toe (the order of :data:`FOOT_ROLES`).
    """
    points = motion.positions_with_end_sites()
    feet = ground_heights(points[:, roles.indices(FOOT_ROLES)]).reshape(-1, 2, 2)
    below = np.maximum(clearance - feet, 0.0)
    below[..., 1] *= np.clip(clearance[..., 0] / SKATE_HEIGHT - 1.0, 0.0, 1.0)
    lift = maximum_filter1d(below.max(axis=-1), LIFT_SPREAD, axis=0)
    shift = np.zeros((motion.num_frames, 2, 3))
    shift[..., 1] = gaussian_filter1d(lift, LIFT_SPREAD / 3, axis=0, mode="nearest")
    moving = shift[..., 1].max(axis=1) > MOVED
    if not moving.any():
        return motion
    rotations = motion.rotations.copy()
    rotations[moving], _ = move_ankles(legs, rotations[moving], points[moving], shift[moving],
                                       np.zeros((int(moving.sum()), 2)))
    return motion.replace(rotations=rotations)


def _plant_by_chains(motion: Motion, source_points: np.ndarray, source_roles: JointRoles,
                     contacts: np.ndarray, scale: float, role_map: RoleMap,
                     blend: int) -> Motion:
    """:func:`plant_feet` by damped least squares on the leg chains (any leg layout)."""
    chains = resolve_chains(motion.skeleton, motion, role_map, names=LEGS)
    points = motion.positions_with_end_sites()
    rotations = motion.rotations.copy()
    for side, name in enumerate(LEGS):
        chain = chains[name]
        world = points[:, chain.targets]
        source = source_points[:, source_roles.indices(chain.target_roles)]
        targets = _planted_targets(world, source, contacts[:, side], scale, blend)
        frames = np.flatnonzero(np.abs(targets - world).max(axis=(1, 2)) > MOVED)
        if len(frames) == 0:
            continue
        part = motion.replace(rotations=rotations[frames], positions=motion.positions[frames])
        solved = solve_chains(part, {name: targets[frames]}, {name: chain}, frame="world",
                              init="motion")
        rotations[frames] = solved.motion.rotations
    return motion.replace(rotations=rotations)
