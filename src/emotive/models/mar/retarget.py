"""Motion retargeting between rigs through the joint roles (paper section 5.1).

Motion retargeting between rigs through the joint roles (paper section 5.1, after Monzani
et al. 2000: an intermediate skeleton and inverse kinematics).

The source clip's role points are scaled by the ratio of the leg lengths, and the end points
(hand tips, toes) laid again from the wrist or ankle at the target rig's own hand and foot
length (rigs end their limbs at different points: a Bandai hand ends on its wrist, a CMU one
at the index finger), so that the IK targets fit the target rig; the target rig's
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

#: DLS damping of the retargeting IK, metres (the solver's default is 0.01). Role points of
#: another rig are not exactly reachable (its feet and hands end at other points: the Bandai
#: toe is a joint, a CMU or Mixamo toe an end site beyond it), so the legs solve a compromise,
#: often at full stretch in stance. With light damping the solver then crosses the straight
#: knee into the wrong branch: on a CMU-style relayout of a real walk, retargeting a happy
#: transfer back put a foot 0.83 m off its target and legs above the hips; at 0.05 every frame
#: stays within 3.1 cm of the compromise.
DAMPING = 0.05

#: Solver settings of the retargeting IK (the solver's defaults: segments of 32 frames with 8
#: burn-in frames, 12 iterations, retries above 1 cm). The role points of another rig are
#: reachable only as a compromise (within 3.1 cm at :data:`DAMPING`), so the solver runs every
#: frame to its iteration cap and most frames missed 1 cm: the cost was the sequential steps of
#: one segment times the cap, plus retries that could not help: five chains there and back
#: took 6,205 kernel evaluations on a 195-frame walk, 4.1 times the database rig's own foot
#: pinning (1,519). Short segments (solved side by side), 8 iterations from the warm start
#: and retries only for gross misses (a wrong knee branch) take 843.
SEGMENT = 4
BURN_IN = 2
MAX_ITER = 8
RETRY_ABOVE = 0.1

#: ``(base, tip)`` roles: each tip target is laid from its base target along the source's
#: base-to-tip direction at the target rig's base-to-tip length.
TIPS: tuple[tuple[str, str], ...] = (
    ("l_wrist", "l_handtip"), ("r_wrist", "r_handtip"), ("l_ankle", "l_toe"), ("r_ankle", "r_toe"),
)
#: Shortest base-to-tip segment with a direction, metres.
_TINY = 1e-3


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


def bone_directions(motion: Motion, joints: np.ndarray) -> np.ndarray:
    """``(T, N, 3)`` unit world direction of each joint's own bone, continued past it.

    The direction from a joint's parent to it, turned by the joint's own rotation: where a
    hand or foot ends on its joint (the Bandai hands' end sites sit on the wrist), the way
    it points.

    Args:
        motion: the clip.
        joints: ``(N,)`` joint indices (not roots).
    """
    grot, _ = motion.global_transforms()
    bone = motion.positions[:, joints]
    bone = bone / np.maximum(np.linalg.norm(bone, axis=-1, keepdims=True), 1e-12)
    return quaternion_apply(grot[:, joints], bone)


def relay_tips(points: np.ndarray, target: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    """Role points whose tips lie at the target rig's hand and foot lengths (:data:`TIPS`).

    Args:
        points: ``(T, P, 3)`` scaled source role points, in :data:`ROLES` order, metres.
        target: ``(P, 3)`` role points of the target rig in one pose, same order.
        fallback: ``(T, len(TIPS), 3)`` unit directions used where a source tip sits on its
            base (:func:`bone_directions` of the bases).

    Returns:
        ``(T, P, 3)`` points with the tips moved; every other point unchanged.
    """
    slot = {r: i for i, r in enumerate(ROLES)}
    out = points.copy()
    for i, (base, tip) in enumerate(TIPS):
        b, t = slot[base], slot[tip]
        seg = points[:, t] - points[:, b]
        norm = np.linalg.norm(seg, axis=-1, keepdims=True)
        direction = np.where(norm > _TINY, seg / np.maximum(norm, _TINY), fallback[:, i])
        out[:, t] = points[:, b] + direction * np.linalg.norm(target[t] - target[b])
    return out


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
    bases = np.array([src_roles.index[b] for b, _ in TIPS])
    if np.any(bases >= source.skeleton.num_joints):
        raise RigMappingError(f"cannot retarget {source.metadata.get('name', 'the input')}: "
                              "the wrist and ankle roles must be joints, not end sites")
    pts = relay_tips(src_all[:, src_roles.indices(ROLES)] * scale,
                     tgt_all[0, tgt_roles.indices(ROLES)], bone_directions(source, bases))

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
                        role_map=target_roles, damping=DAMPING, segment=SEGMENT,
                        burn_in=BURN_IN, max_iter=MAX_ITER, retry_above=RETRY_ABOVE).motion
