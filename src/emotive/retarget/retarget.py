"""Retargeting: a clip from one humanoid rig played on another.

The method, in order:

1. **Rest alignment per bone.** Bones are paired by role (:mod:`emotive.retarget.rest`). For
   each role joint of the target, the rotation ``D`` that carries its rest bone directions
   onto the source's (the shortest arc for a joint with one child role; for the hips and the
   chest, the spine's continuation exactly and the hips or shoulders as well as they fit,
   for the twist about it) aligns the two rest poses, so the
   method does not care whether either rig rests in a T-pose, an A-pose or Maya-style along
   its bone axes.
2. **Global rotations transferred.** The target joint's world rotation is the source joint's
   times ``D``; a joint with one child role is then swung so that its bone points exactly
   where the source bone points in that frame (the twist stays the source's). A joint whose
   bone has no length on one rig (Bandai's hand and toe tips are zero-length end sites) takes
   the alignment of its parent role. An intermediate joint just below the hips or the chest
   (CMU's ``LowerBack`` and ``LeftShoulder``, Bandai's ``Shoulder_L``) is swung so that the
   next role joint lies along the source bone, which carries spine bends and shrugs across.
   Every other joint of the target (fingers, twist and helper bones, the joints above the
   root role) keeps its rest rotation.
3. **Lengths and root motion.** Bones keep the target's lengths; the root's world position
   is the source's times the leg-length ratio ``target / source`` (hip -> knee -> ankle,
   :func:`emotive.features.contacts.leg_length`), so speed relative to leg length, stride
   and hip height are kept.
4. **Feet.** Feet planted in the source (:func:`emotive.features.contacts.foot_contacts`)
   follow the source's feet on the target, scaled like the root, by an analytic two-bone
   solve of each leg over all frames at once (:func:`emotive.retarget.feet.plant_feet`): a
   planted source foot gives a planted target foot. The clip is then moved vertically so
   that its ankles come as low as the source's, scaled: a source standing on ``y = 0``
   gives a target standing on ``y = 0``.

The result carries the target's joint names, hierarchy, offsets and channel layout (so its
rotation orders), at the source's frame rate or ``fps``.

Legend: ``T`` frames, ``J`` source joints, ``K`` target joints, ``E`` end sites.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.core.roles import ROLES, JointRoles, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError
from emotive.features.contacts import foot_contacts, leg_length
from emotive.retarget.feet import lowest_ankle_height, move_up, plant_feet
from emotive.retarget.rest import (
    MIN_BONE,
    ROLE_CHILDREN,
    ROLE_PARENT,
    RoleBones,
    has_bone,
    path_between,
    role_bones,
)
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_between,
    quaternion_continuity,
    quaternion_invert,
    quaternion_multiply,
    quaternion_normalize,
)

RoleMap = str | Path | dict[str, str] | None

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
#: Child roles aligned exactly at a joint with several child roles.
PRIMARY = ("spine", "chest", "neck")


@dataclass(frozen=True)
class Pairing:
    """Both rigs' roles and role bones, resolved once.

    Attributes:
        source_roles: resolved roles of the source rig.
        target_roles: resolved roles of the target rig.
        source: role bones of the source rig.
        target: role bones of the target rig.
    """

    source_roles: JointRoles
    target_roles: JointRoles
    source: RoleBones
    target: RoleBones


def resolve_rig(skeleton: Skeleton, role_map: RoleMap = None, which: str = "target",
                flag: str = "--to-roles") -> tuple[JointRoles, RoleBones]:
    """A rig's roles and role bones, with errors that say which rig and which flag.

    Args:
        skeleton: the rig.
        role_map: its role map (see :func:`emotive.core.roles.resolve_roles`).
        which: the rig's part in the message (``"source"``, ``"target"``, ``"primer"``).
        flag: the command-line option that supplies its role map, named in the message.

    Raises:
        RigError: the rig lacks roles or its roles do not nest as a humanoid's.
    """
    try:
        roles = resolve_roles(skeleton, role_map)
        return roles, role_bones(skeleton, roles)
    except RigError as exc:
        message = re.sub(r"--roles\b(?!-)", flag, str(exc))
        raise RigError(f"{which} rig ({skeleton.names[0]}, {skeleton.num_joints} joints): "
                       f"{message}") from None


def pair_rigs(source: Skeleton, target: Skeleton, source_roles: RoleMap = None,
              target_roles: RoleMap = None) -> Pairing:
    """Resolve the roles and role bones of a source and a target rig.

    Args:
        source: the rig of the clip.
        target: the rig to retarget onto.
        source_roles: role map of the source (see :func:`emotive.core.roles.resolve_roles`).
        target_roles: role map of the target.

    Raises:
        RigError: a rig lacks roles (the message names the rig, the roles and the flag that
            supplies them) or its roles do not nest as a humanoid's.
    """
    s_roles, s_bones = resolve_rig(source, source_roles, "source", "--roles")
    t_roles, t_bones = resolve_rig(target, target_roles, "target", "--to-roles")
    return Pairing(s_roles, t_roles, s_bones, t_bones)


def leg_scale(motion: Motion, pairing: Pairing) -> float:
    """Leg length of the target's rest pose over the source clip's (median over frames).

    Args:
        motion: the source clip.
        pairing: the source's and the target's roles (:func:`pair_rigs`).

    Raises:
        RigError: either leg has no length.
    """
    source = leg_length(motion.positions_with_end_sites(), pairing.source_roles)
    rest = leg_length(pairing.target.rest[None], pairing.target_roles)
    if not (source > MIN_BONE and rest > MIN_BONE):
        raise RigError(f"cannot scale the root motion: leg length {source:.3g} m on the source, "
                       f"{rest:.3g} m on the target; map hip, knee and ankle to distinct joints")
    return rest / source


def _to_quaternion(rotation: Rotation) -> np.ndarray:
    """``(4,)`` ``w, x, y, z`` of a SciPy rotation (SciPy stores ``x, y, z, w``)."""
    x, y, z, w = rotation.as_quat()
    return np.array([w, x, y, z])


def _alignment(pairing: Pairing, role: str, children: tuple[str, ...]) -> np.ndarray:
    """``(4,)`` rotation carrying the target's rest bone directions onto the source's."""
    t = np.stack([pairing.target.vector(role, c) for c in children])
    s = np.stack([pairing.source.vector(role, c) for c in children])
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    s /= np.linalg.norm(s, axis=-1, keepdims=True)
    if len(children) == 1:
        return quaternion_between(t[0], s[0])
    # The spine's continuation (spine from the root, neck from the chest) is aligned exactly;
    # the hips and shoulders only fix the twist about it.
    weights = [np.inf if c in PRIMARY else 1.0 for c in children]
    if not np.isinf(weights).any():
        weights[0] = np.inf
    return _to_quaternion(Rotation.align_vectors(s, t, weights=weights)[0])


def _driving_roles(pairing: Pairing, num_joints: int) -> dict[int, str]:
    """Target joint -> the first role whose point is that joint (roles at end sites drive none)."""
    out: dict[int, str] = {}
    for role in ROLES:
        point = pairing.target.points[role]
        if point < num_joints and point not in out:
            out[point] = role
    return out


def _children_of_joint(pairing: Pairing, joint: int, role: str) -> tuple[str, ...]:
    """Child roles of every role at target ``joint`` with a bone from ``role`` on both rigs."""
    at = [r for r in ROLES if pairing.target.points[r] == joint]
    kids = [c for r in at for c in ROLE_CHILDREN[r] if c not in at]
    return tuple(c for c in kids
                 if has_bone(pairing.source, role, c) and has_bone(pairing.target, role, c))


@dataclass(frozen=True)
class _Drive:
    """How one target joint is driven: its role, child roles and rest alignment."""

    role: str
    children: tuple[str, ...]
    align: np.ndarray


def _drives(pairing: Pairing, target: Skeleton) -> dict[int, _Drive]:
    """Target role joint -> its drive, parents first (a leaf inherits its parent's alignment)."""
    drives: dict[int, _Drive] = {}
    by_role: dict[str, np.ndarray] = {}
    for joint, role in sorted(_driving_roles(pairing, target.num_joints).items()):
        children = _children_of_joint(pairing, joint, role)
        if children:
            align = _alignment(pairing, role, children)
        else:
            parent = ROLE_PARENT.get(role)
            while parent is not None and parent not in by_role:
                parent = ROLE_PARENT.get(parent)
            align = by_role[parent] if parent is not None else IDENTITY
        by_role[role] = align
        drives[joint] = _Drive(role, children, align)
    return drives


def _intermediate_swings(pairing: Pairing, target: Skeleton,
                         drives: dict[int, _Drive]) -> dict[int, tuple[int, str, str]]:
    """First intermediate joint below a multi-child role joint -> (role joint, role, child).

    Only intermediates on exactly one child's path are swung (a joint shared by two paths
    cannot point at both).
    """
    found: dict[int, list[tuple[int, str, str]]] = {}
    for joint, drive in drives.items():
        if len(drive.children) < 2:
            continue
        for child in drive.children:
            point = pairing.target.points[child]
            path = path_between(target, joint, point)
            between = path[:-1] if point < target.num_joints else path
            if between and between[0] not in drives:
                found.setdefault(between[0], []).append((joint, drive.role, child))
    return {j: uses[0] for j, uses in found.items() if len(uses) == 1}


def _mover(target: Skeleton, root: int) -> int:
    """The joint that carries the world translation.

    The root role, or its nearest ancestor with position channels.

    Raises:
        RigError: neither the root role nor any joint above it has position channels.
    """
    animated = target.animated_translation
    j = root
    while j >= 0 and not animated[j]:
        j = int(target.parents[j])
    if j < 0:
        raise RigError(f"target rig: neither {target.names[root]} (the root role) nor a joint "
                       "above it has position channels, so it cannot move through the world; "
                       "give the root joint Xposition Yposition Zposition channels")
    return j


class _TargetPose:
    """World rotations and positions of the target, built joint by joint."""

    def __init__(self, target: Skeleton, frames: int) -> None:
        self.target = target
        self.grot = np.tile(IDENTITY, (frames, target.num_joints, 1))
        self.gpos = np.zeros((frames, target.num_joints, 3))
        self.local_pos = np.broadcast_to(target.offsets, self.gpos.shape).copy()

    def place(self, joint: int, world_rotation: np.ndarray | None) -> None:
        """Set a joint's world position from its parent, and its world rotation.

        ``world_rotation`` ``(T, 4)``, or ``None`` for the parent's (the rest rotation).
        """
        p = int(self.target.parents[joint])
        if p >= 0:
            self.gpos[:, joint] = self.gpos[:, p] + quaternion_apply(
                self.grot[:, p], self.local_pos[:, joint])
            parent_rot = self.grot[:, p]
        else:
            self.gpos[:, joint] = self.local_pos[:, joint]
            parent_rot = np.broadcast_to(IDENTITY, self.grot[:, joint].shape)
        self.grot[:, joint] = parent_rot if world_rotation is None else world_rotation

    def local_rotations(self) -> np.ndarray:
        """``(T, K, 4)`` local rotations, continuous in time."""
        parents = self.target.parents
        rot = self.grot.copy()
        inner = parents >= 0
        rot[:, inner] = quaternion_multiply(quaternion_invert(self.grot[:, parents[inner]]),
                                            self.grot[:, inner])
        return quaternion_continuity(quaternion_normalize(rot), 0)


def _root_translation(pose: _TargetPose, pairing: Pairing, root_world: np.ndarray) -> None:
    """Put the target's root role at ``root_world`` ``(T, 3)`` through the mover joint.

    Joints above the root role keep their rest rotation, so the mover's translation is the
    root's world position minus the rest offsets below it.
    """
    target = pose.target
    root = pairing.target.joints["root"]
    mover = _mover(target, root)
    below = path_between(target, mover, root) if mover != root else []
    lift = target.offsets[below].sum(0) if below else np.zeros(3)
    above = pairing.target.rest[int(target.parents[mover])] if target.parents[mover] >= 0 \
        else np.zeros(3)
    pose.local_pos[:, mover] = root_world - lift - above


def transfer_pose(motion: Motion, target: Skeleton, pairing: Pairing, scale: float) -> Motion:
    """Steps 1-3 of the module docstring: the source's pose on the target, feet not pinned.

    Args:
        motion: the source clip, ``T`` frames on ``J`` joints.
        target: the target rig, ``K`` joints.
        pairing: both rigs' roles (:func:`pair_rigs`).
        scale: multiplier of the root's world position (:func:`leg_scale`).

    Returns:
        The clip on the target rig: rotations ``(T, K, 4)``, positions ``(T, K, 3)``.
    """
    grot_s, _ = motion.global_transforms()
    pts_s = motion.positions_with_end_sites()
    src = pairing.source
    drives = _drives(pairing, target)
    swings = _intermediate_swings(pairing, target, drives)
    pose = _TargetPose(target, motion.num_frames)
    _root_translation(pose, pairing, scale * pts_s[:, src.points["root"]])
    for joint in range(target.num_joints):
        if joint in drives:
            drive = drives[joint]
            world = quaternion_multiply(grot_s[:, src.joints[drive.role]], drive.align)
            if len(drive.children) == 1:
                child = drive.children[0]
                bone = quaternion_apply(world, pairing.target.vector(drive.role, child))
                aim = pts_s[:, src.points[child]] - pts_s[:, src.points[drive.role]]
                world = quaternion_multiply(quaternion_between(bone, aim), world)
            pose.place(joint, world)
        elif joint in swings:
            pose.place(joint, None)
            pose.place(joint, _swing(pose, pairing, joint, swings[joint], pts_s))
        else:
            pose.place(joint, None)
    return Motion(target, pose.local_rotations(), pose.local_pos, motion.fps,
                  dict(motion.metadata))


def _swing(pose: _TargetPose, pairing: Pairing, joint: int, use: tuple[int, str, str],
           pts_s: np.ndarray) -> np.ndarray:
    """``(T, 4)`` world rotation of an intermediate joint aimed along the source bone.

    The intermediate can put the next role joint anywhere on a sphere about itself; the point
    taken is where the source bone's line from the role joint leaves that sphere, or the
    sphere's point nearest the line where they do not meet.
    """
    role_joint, role, child = use
    tgt = pairing.target
    aim = pts_s[:, pairing.source.points[child]] - pts_s[:, pairing.source.points[role]]
    aim /= np.maximum(np.linalg.norm(aim, axis=-1, keepdims=True), MIN_BONE)
    below = tgt.rest[tgt.points[child]] - tgt.rest[joint]
    radius = np.linalg.norm(below)
    centre = pose.gpos[:, joint]
    start = pose.gpos[:, role_joint] - centre
    b = (aim * start).sum(-1, keepdims=True)
    disc = b**2 - (start**2).sum(-1, keepdims=True) + radius**2
    along = start + aim * (-b + np.sqrt(np.maximum(disc, 0.0)))
    now = quaternion_apply(pose.grot[:, joint], np.broadcast_to(below, aim.shape))
    return quaternion_multiply(quaternion_between(now, along), pose.grot[:, joint])


def _metadata(motion: Motion, target: Skeleton | Motion, scale: float) -> dict:
    meta = dict(motion.metadata)
    meta["leg_scale"] = scale
    if isinstance(target, Motion) and "file_unit" in target.metadata:
        meta["file_unit"] = target.metadata["file_unit"]
    return meta


def retarget(
    motion: Motion,
    target: Skeleton | Motion,
    source_roles: RoleMap = None,
    target_roles: RoleMap = None,
    fps: float | None = None,
) -> Motion:
    """Play a clip on another humanoid rig (the method of the module docstring).

    Args:
        motion: the source clip, ``T`` frames, any humanoid rig.
        target: the rig to play it on: a :class:`Skeleton`, or a clip of that rig (a rig
            file read with :func:`emotive.io.bvh.read_bvh`; its frames are not used, its
            ``file_unit`` becomes the output's, so the output is written in the rig's unit).
        source_roles: role map of the source (see :func:`emotive.core.roles.resolve_roles`;
            ``None`` detects it).
        target_roles: role map of the target.
        fps: resample the clip to this frame rate first (``None`` keeps the source's).

    Returns:
        The clip on the target rig: rotations ``(T', K, 4)``, positions ``(T', K, 3)``, the
        source's metadata with the target's ``file_unit`` and ``leg_scale`` added.

    Raises:
        RigError: either rig lacks roles (naming the rig and the roles), its roles do not nest,
            or the target's root cannot translate.
        MotionError: ``fps`` is not a positive number.
    """
    rig = target.skeleton if isinstance(target, Motion) else target
    if fps is not None:
        motion = resample(motion, fps)
    pairing = pair_rigs(motion.skeleton, rig, source_roles, target_roles)
    if motion.num_frames == 0:
        return Motion(rig, np.zeros((0, rig.num_joints, 4)), np.zeros((0, rig.num_joints, 3)),
                      motion.fps, _metadata(motion, target, 1.0))
    scale = leg_scale(motion, pairing)
    moved = transfer_pose(motion, rig, pairing, scale)
    src_points = motion.positions_with_end_sites()
    contacts = foot_contacts(src_points, pairing.source_roles, motion.fps)
    if contacts.any():
        moved = plant_feet(moved, src_points, pairing.source_roles, contacts, scale,
                           target_roles)
    ground = scale * lowest_ankle_height(src_points, pairing.source_roles)
    lift = ground - lowest_ankle_height(moved.positions_with_end_sites(), pairing.target_roles)
    moved = move_up(moved, lift, _mover(rig, pairing.target.joints["root"]))
    return moved.replace(metadata=_metadata(motion, target, scale))
