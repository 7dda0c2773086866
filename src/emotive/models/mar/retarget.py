"""Motion retargeting between rigs through the joint roles (paper section 5.1).

Motion retargeting between rigs through the joint roles (paper section 5.1, after Monzani
et al. 2000: an intermediate skeleton and inverse kinematics).

The source clip's role points are scaled by the ratio of the leg lengths; the target rig's
pelvis takes the world orientation of the source's body frame (hips across, spine up), and the
five IK chains of :mod:`emotive.ik` (head-torso, arms with elbows, legs with toes) are solved
on the target rig to reach the scaled points. Joints outside the chains keep the template's
rotations. The same function maps an input onto the database rig and the output back onto
the input's rig.

Legend: ``T`` frames, ``J`` joints, ``P`` role points.
"""

from __future__ import annotations

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import ROLES, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError
from emotive.features.contacts import leg_length
from emotive.ik import resolve_chains, solve_chains
from emotive.models.mar.representation import RigMappingError
from emotive.transforms.np_rotations import (
    matrix_to_quaternion,
    quaternion_apply,
    quaternion_invert,
    quaternion_multiply,
)


def same_rig(a: Skeleton, b: Skeleton) -> bool:
    """Whether two rigs share joint names and hierarchy (their rotations mean the same)."""
    return a.names == b.names and np.array_equal(a.parents, b.parents)


def body_frames(points: np.ndarray) -> np.ndarray:
    """``(T, 3, 3)`` orthonormal body frames of role points.

    ``(T, 3, 3)`` orthonormal body frames (columns: left, up, forward) of role points
    ``(T, P, 3)`` in :data:`ROLES` order.
    """
    slot = {r: i for i, r in enumerate(ROLES)}
    left = points[:, slot["l_hip"]] - points[:, slot["r_hip"]]
    left /= np.maximum(np.linalg.norm(left, axis=-1, keepdims=True), 1e-12)
    up = points[:, slot["chest"]] - points[:, slot["root"]]
    up = up - (up * left).sum(-1, keepdims=True) * left
    up /= np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12)
    return np.stack((left, up, np.cross(left, up)), -1)


def retarget(source: Motion, template: Motion, source_roles=None, target_roles=None) -> Motion:
    """The source clip on the template's rig.

    Args:
        source: the clip to map, ``T`` frames.
        template: a clip on the target rig: its first frame gives the rotations of joints
            outside the IK chains (every frame when it also has ``T`` frames), and it
            calibrates the chains' hinges.
        source_roles: role map of the source rig (see :func:`emotive.core.roles.resolve_roles`).
        target_roles: role map of the target rig.

    Returns:
        ``T`` frames on the template's rig, at the source's frame rate, with the source's
        metadata.

    Raises:
        RigMappingError: either rig lacks the roles.
    """
    try:
        src_roles = resolve_roles(source.skeleton, source_roles)
        tgt_roles = resolve_roles(template.skeleton, target_roles)
    except RigError as exc:
        raise RigMappingError(f"cannot retarget {source.metadata.get('name', 'the input')}: "
                              f"{exc}") from None
    n = source.num_frames
    src_all = source.positions_with_end_sites()
    tgt_first = template.replace(rotations=template.rotations[:1], positions=template.positions[:1])
    tgt_all = tgt_first.positions_with_end_sites()
    scale = leg_length(tgt_all, tgt_roles) / max(leg_length(src_all[:1], src_roles), 1e-9)
    pts = src_all[:, src_roles.indices(ROLES)] * scale

    sk = template.skeleton
    if template.num_frames == n:
        rot, pos = template.rotations.copy(), template.positions.copy()
    else:
        rot = np.repeat(template.rotations[:1], n, axis=0)
        pos = np.repeat(template.positions[:1], n, axis=0)
    mover = int(tgt_roles.index["root"])
    grot0, gpos0 = tgt_first.global_transforms()
    ref_frame = body_frames(tgt_all[:, tgt_roles.indices(ROLES)])[0]
    frames = body_frames(pts)
    world = matrix_to_quaternion(frames @ ref_frame.T)
    world = quaternion_multiply(world, np.broadcast_to(grot0[0, mover], (n, 4)))
    root_pos = pts[:, list(ROLES).index("root")]
    parent = int(sk.parents[mover])
    if parent >= 0:
        inv = quaternion_invert(np.broadcast_to(grot0[0, parent], (n, 4)))
        rot[:, mover] = quaternion_multiply(inv, world)
        pos[:, mover] = quaternion_apply(inv, root_pos - gpos0[0, parent])
    else:
        rot[:, mover], pos[:, mover] = world, root_pos
    start = Motion(sk, rot, pos, source.fps, dict(source.metadata))
    chains = resolve_chains(sk, template, target_roles)
    slot = {r: i for i, r in enumerate(ROLES)}
    targets = {name: pts[:, [slot[r] for r in chain.target_roles]]
               for name, chain in chains.items()}
    return solve_chains(start, targets, chains, frame="world", init="neutral",
                        role_map=target_roles).motion
