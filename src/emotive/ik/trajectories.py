"""Pelvis, end-effector and elbow trajectories in the frames of their chains.

The pelvis trajectory is stored as per-frame ground displacement and yaw change in the
character's heading frame plus height and tilt, so it does not depend on where the character
stands or faces; :func:`integrate_pelvis` places it back in the world. Chain targets are
expressed in the world frame of the chain's ``frame`` joint (pelvis for legs and head-torso,
chest for arms), which makes them invariant to world position and heading as well.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``M`` targets of a chain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.motion import Motion
from emotive.core.ops import heading
from emotive.core.roles import resolve_roles
from emotive.ik.chains import Chain
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_invert,
    quaternion_multiply,
    yaw_quaternion,
)


@dataclass(frozen=True)
class PelvisTrajectory:
    """The pelvis (root role) path, invariant to world position and heading.

    Attributes:
        height: ``(T,)`` pelvis height (Y), metres.
        displacement: ``(T, 2)`` ground step ``(x, z)`` from the previous frame, in the previous
            frame's heading frame (zero at frame 0), metres.
        turn: ``(T,)`` heading change from the previous frame, radians (zero at frame 0).
        tilt: ``(T, 4)`` pelvis world rotation with the heading yaw removed.
        start: ``(3,)`` world position at frame 0 (only used to put the path back).
        start_heading: heading at frame 0, radians.
    """

    height: np.ndarray
    displacement: np.ndarray
    turn: np.ndarray
    tilt: np.ndarray
    start: np.ndarray
    start_heading: float


@dataclass(frozen=True)
class Trajectories:
    """Everything :func:`extract_trajectories` returns.

    Attributes:
        pelvis: the pelvis path.
        targets: chain name -> ``(T, M, 3)`` target positions in the chain's frame.
    """

    pelvis: PelvisTrajectory
    targets: dict[str, np.ndarray]


def _rotate_ground(yaw: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate ``(T, 2)`` ground vectors ``(x, z)`` by ``yaw`` about +Y."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack((c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]), -1)


def pelvis_trajectory(motion: Motion, root: int, role_map=None) -> PelvisTrajectory:
    """The pelvis path of a clip.

    Args:
        motion: the clip.
        root: joint index of the pelvis (role ``root``).
        role_map: how to find the hips and shoulders that define the heading.

    Returns:
        The trajectory.
    """
    grot, gpos = motion.global_transforms()
    yaw = heading(motion, role_map)
    pos = gpos[:, root]
    step = np.diff(pos[:, [0, 2]], axis=0, prepend=pos[:1, [0, 2]])
    prev_yaw = np.concatenate((yaw[:1], yaw[:-1]))
    disp = _rotate_ground(-prev_yaw, step)
    turn = np.angle(np.exp(1j * (yaw - prev_yaw)))
    tilt = quaternion_multiply(yaw_quaternion(-yaw), grot[:, root])
    return PelvisTrajectory(pos[:, 1], disp, turn, tilt, pos[0].copy(), float(yaw[0]))


def integrate_pelvis(
    traj: PelvisTrajectory, start: np.ndarray | None = None, start_heading: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """World pelvis positions ``(T, 3)`` and rotations ``(T, 4)`` of a trajectory.

    Args:
        traj: the trajectory.
        start: world ground position at frame 0 (only ``x, z`` are used); ``traj.start`` if None.
        start_heading: heading at frame 0 in radians; ``traj.start_heading`` if None.
    """
    start = traj.start if start is None else np.asarray(start, dtype=np.float64)
    h0 = traj.start_heading if start_heading is None else start_heading
    yaw = h0 + np.cumsum(traj.turn)
    prev_yaw = np.concatenate(([h0], yaw[:-1]))
    ground = start[[0, 2]] + np.cumsum(_rotate_ground(prev_yaw, traj.displacement), 0)
    pos = np.stack((ground[:, 0], traj.height, ground[:, 1]), -1)
    return pos, quaternion_multiply(yaw_quaternion(yaw), traj.tilt)


def to_frame(points: np.ndarray, frame_rot: np.ndarray, frame_pos: np.ndarray) -> np.ndarray:
    """``(T, M, 3)`` world points in the frame ``(T, 4)`` rotation, ``(T, 3)`` origin."""
    inv = np.broadcast_to(quaternion_invert(frame_rot)[:, None], (*points.shape[:-1], 4))
    return quaternion_apply(inv, points - frame_pos[:, None])


def to_world(points: np.ndarray, frame_rot: np.ndarray, frame_pos: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_frame`: ``(T, M, 3)`` frame points to world points."""
    rot = np.broadcast_to(frame_rot[:, None], (*points.shape[:-1], 4))
    return quaternion_apply(rot, points) + frame_pos[:, None]


def chain_targets(motion: Motion, chain: Chain, frame: bool = True) -> np.ndarray:
    """``(T, M, 3)`` positions of a chain's targets, in its frame (or the world).

    Args:
        motion: the clip.
        chain: the chain.
        frame: express them in the chain's frame joint; ``False`` keeps world coordinates.
    """
    pts = motion.positions_with_end_sites()[:, chain.targets]
    if not frame:
        return pts
    grot, gpos = motion.global_transforms()
    return to_frame(pts, grot[:, chain.frame], gpos[:, chain.frame])


def extract_trajectories(motion: Motion, chains: dict[str, Chain], role_map=None) -> Trajectories:
    """Pelvis path and every chain's targets (end effectors, elbows) in their chain frames.

    Args:
        motion: the clip.
        chains: from :func:`emotive.ik.chains.resolve_chains`.
        role_map: how to find the roles (for the heading).

    Returns:
        The trajectories; chains whose frame is the pelvis use the pelvis's full rotation.
    """
    root = resolve_roles(motion.skeleton, role_map).index["root"]
    grot, gpos = motion.global_transforms()
    all_pts = motion.positions_with_end_sites()
    targets = {
        name: to_frame(all_pts[:, c.targets], grot[:, c.frame], gpos[:, c.frame])
        for name, c in chains.items()
    }
    return Trajectories(pelvis_trajectory(motion, root, role_map), targets)
