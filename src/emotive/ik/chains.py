"""The five IK chains (two legs, two arms, head-torso): joints by role, DOF and limits.

Each chain joint is driven by a 3-vector ``theta`` of angles about three axes fixed in the
joint's local frame (columns of ``axes``): the local rotation is ``ref * exp(axes @ theta)``.

Consecutive chain joints need not be parent and child: any number of *intermediate* joints
may sit between them (CMU's ``Neck1`` between ``Neck`` and ``Head``, Mixamo's ``Spine1``
between ``Spine`` and ``Spine2``, Unreal's ``spine_02``). Intermediates are not solved: they
keep the local rotation of the clip being solved (a rebuild from scratch keeps the clip's
rotations for them, as for every joint outside the chains), and the chain's forward
kinematics goes through them (:func:`link_transforms` folds each run of intermediates into one
fixed transform per frame). Joints between the chain's base and its first joint (CMU's
``LHipJoint``, ``LowerBack``) are above the chain: the base is the first joint's parent.
The first axis of a ball or swing joint is its bone (the twist axis); a hinge has its single
axis first and the other two locked (``lower == upper == 0``). Limits are boxes on ``theta``.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``k`` chain joints, ``M`` chain targets.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import JointRoles, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import EmotiveError, RigError
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_invert,
    quaternion_mean,
    quaternion_multiply,
    quaternion_to_axis_angle,
)


class IKError(EmotiveError):
    """IK input that cannot be solved: NaN targets, wrong shapes, unknown chains."""


@dataclass(frozen=True)
class JointSpec:
    """DOF and limits of one chain joint, by role.

    Attributes:
        role: the joint's role (see :mod:`emotive.core.roles`).
        dof: ``"ball"`` (3 DOF: twist + two swings), ``"swing"`` (2 DOF, twist locked) or
            ``"hinge"`` (1 DOF flexion about an axis calibrated from a reference motion).
        lower: ``(twist, swing, swing)`` lower limits in degrees (hinge: ``(flexion, 0, 0)``).
        upper: upper limits, same layout.
    """

    role: str
    dof: str
    lower: tuple[float, float, float]
    upper: tuple[float, float, float]


@dataclass(frozen=True)
class ChainSpec:
    """A chain by roles.

    Attributes:
        name: ``left_leg``, ``right_leg``, ``left_arm``, ``right_arm`` or ``head_torso``.
        joints: the solved joints, parent first; each joint hangs below the previous one,
            directly or through intermediate joints.
        targets: ``(role, weight)`` of each position target (end effector last).
        frame: role whose world frame the chain's trajectories are expressed in.
    """

    name: str
    joints: tuple[JointSpec, ...]
    targets: tuple[tuple[str, float], ...]
    frame: str


def _ball(role: str, twist: float, swing: float) -> JointSpec:
    return JointSpec(role, "ball", (-twist, -swing, -swing), (twist, swing, swing))


def _leg(side: str, name: str) -> ChainSpec:
    s = side
    return ChainSpec(
        name,
        (
            _ball(f"{s}_hip", 60.0, 120.0),
            JointSpec(f"{s}_knee", "hinge", (-5.0, 0.0, 0.0), (150.0, 0.0, 0.0)),
            JointSpec(f"{s}_ankle", "swing", (0.0, -70.0, -70.0), (0.0, 70.0, 70.0)),
        ),
        ((f"{s}_ankle", 1.0), (f"{s}_toe", 1.0)),
        "root",
    )


def _arm(side: str, name: str) -> ChainSpec:
    s = side
    return ChainSpec(
        name,
        (
            _ball(f"{s}_shoulder", 100.0, 160.0),
            JointSpec(f"{s}_elbow", "hinge", (-5.0, 0.0, 0.0), (155.0, 0.0, 0.0)),
            JointSpec(f"{s}_wrist", "swing", (0.0, -85.0, -85.0), (0.0, 85.0, 85.0)),
        ),
        ((f"{s}_elbow", 0.5), (f"{s}_wrist", 1.0), (f"{s}_handtip", 1.0)),
        "chest",
    )


#: The five chains of the paper's Figure 3, solved in this order (arms hang off the torso).
CHAIN_SPECS: tuple[ChainSpec, ...] = (
    ChainSpec(
        "head_torso",
        (
            _ball("spine", 40.0, 50.0),
            _ball("chest", 40.0, 50.0),
            _ball("neck", 70.0, 60.0),
            _ball("head", 80.0, 70.0),
        ),
        # Shoulders play for the torso the part elbows play for the arms: they pin the chest's
        # twist, which the head alone leaves free and the arms' frame depends on.
        (("l_shoulder", 0.5), ("r_shoulder", 0.5), ("neck", 1.0), ("head", 1.0)),
        "root",
    ),
    _arm("l", "left_arm"),
    _arm("r", "right_arm"),
    _leg("l", "left_leg"),
    _leg("r", "right_leg"),
)

CHAIN_NAMES: tuple[str, ...] = tuple(c.name for c in CHAIN_SPECS)


@dataclass(frozen=True, eq=False)
class Chain:
    """A chain resolved on a rig.

    Attributes:
        name: chain name.
        joints: ``(k,)`` joint indices, parent first.
        base: index of the parent joint of ``joints[0]`` (its world transform is given).
        frame: joint index whose world frame the chain's trajectories use.
        targets: ``(M,)`` indices into the ``(J + E)`` joint-then-end-site array.
        target_roles: role of each target.
        anchors: ``(M,)`` position in ``joints`` of the deepest chain joint each target hangs
            from (targets move rigidly with it).
        weights: ``(M,)`` least-squares weight of each target.
        reach: ``(M,)`` longest possible distance from ``joints[0]`` to each target, metres.
        ref: ``(k, 4)`` local rotations at ``theta = 0``.
        neutral: ``(k, 4)`` default pose (initial guess and posture), inside the limits.
        axes: ``(k, 3, 3)`` parameter axes (columns) in each joint's local frame.
        lower: ``(k, 3)`` lower limits in radians.
        upper: ``(k, 3)`` upper limits in radians.
        between: per chain joint, ``(n_i,)`` indices of the intermediate joints between the
            previous chain joint (nothing for the first) and it, parent first; all empty on
            a rig whose chain joints are parent and child.
    """

    name: str
    joints: np.ndarray
    base: int
    frame: int
    targets: np.ndarray
    target_roles: tuple[str, ...]
    anchors: np.ndarray
    weights: np.ndarray
    reach: np.ndarray
    ref: np.ndarray
    neutral: np.ndarray
    axes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    between: tuple[np.ndarray, ...] = ()

    @property
    def has_intermediates(self) -> bool:
        """Whether any intermediate joint sits between two chain joints."""
        return any(len(b) for b in self.between)

    @property
    def dof(self) -> int:
        """Number of free parameters (axes whose limits are not both zero)."""
        return int(np.count_nonzero(self.upper > self.lower))


def _point_parent_and_offset(skeleton: Skeleton, point: int) -> tuple[int, np.ndarray]:
    n = skeleton.num_joints
    if point < n:
        return int(skeleton.parents[point]), skeleton.offsets[point]
    e = point - n
    return int(skeleton.end_site_parents[e]), skeleton.end_site_offsets[e]


def _frame_axes(bone: np.ndarray, first: np.ndarray | None = None) -> np.ndarray:
    """``(3, 3)`` orthonormal columns, the first along ``first`` (or ``bone``)."""
    a = first if first is not None else bone
    norm = np.linalg.norm(a)
    a = a / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    b = np.cross(a, helper)
    b /= np.linalg.norm(b)
    return np.stack((a, b, np.cross(a, b)), axis=1)


#: Angle between the bones above and below a hinge at its identity rotation under which the
#: limb counts as straight there (radians, 1 degree).
STRAIGHT = np.radians(1.0)


def _angle_about(axis: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Signed angle (radians) that turns ``a`` onto ``b`` about the unit ``axis``."""
    a = a - (a @ axis) * axis
    b = b - (b @ axis) * axis
    return float(np.arctan2(axis @ np.cross(a, b), a @ b))


def _hinge_fit(
    local: np.ndarray | None, above: np.ndarray, below: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Zero rotation, axis and median flexion of a hinge (knee, elbow).

    A rig whose limb is straight at the hinge's identity rotation (the Bandai rig, CMU's
    T-pose) takes the axis from the rotation vectors (:func:`_hinge_axis`), zero at the
    identity. On other rigs (joint frames aligned with the world in a bent rest pose, or
    turned off the bone), the hinge is fitted around the mean rotation of the clip and its zero
    moved to where the limb is straight, so that the limits (flexion from straight) mean the
    same on every rig.

    Args:
        local: ``(T, 4)`` local rotations of the hinge in the reference clip, or ``None``.
        above: ``(3,)`` the bone into the hinge, in the hinge's parent frame.
        below: ``(3,)`` the bone out of the hinge, in its own frame.

    Returns:
        ``(4,)`` rotation at zero flexion (the straight limb), ``(3,)`` unit axis in the frame
        after it (flexion positive in the clip), and the median flexion in radians.
    """
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    unit_above = above / max(np.linalg.norm(above), 1e-12)
    unit_below = below / max(np.linalg.norm(below), 1e-12)
    if local is None or np.arccos(np.clip(unit_above @ unit_below, -1.0, 1.0)) < STRAIGHT:
        axis, flex = _hinge_axis(local)
        return ident, axis, flex
    mean = quaternion_mean(local)
    target = quaternion_apply(quaternion_invert(mean), unit_above)
    v = quaternion_to_axis_angle(quaternion_multiply(quaternion_invert(mean)[None], local))
    if np.median(np.linalg.norm(v, axis=-1)) < np.radians(2.0):
        # A still clip shows no axis: bend in the plane of the two bones.
        axis = np.cross(target, unit_below)
        norm = np.linalg.norm(axis)
        axis = axis / norm if norm > 1e-9 else _frame_axes(unit_below)[:, 1]
        proj = np.zeros(len(v))
    else:
        axis = np.linalg.eigh(v.T @ v)[1][:, -1]
        proj = v @ axis
    straight = _angle_about(axis, unit_below, target)
    if np.median(proj) - straight < 0:
        axis, proj, straight = -axis, -proj, -straight
    zero = quaternion_multiply(mean, np.array([np.cos(straight / 2),
                                               *(np.sin(straight / 2) * axis)]))
    return zero, axis, float(np.median(proj) - straight)


def _hinge_axis(local: np.ndarray | None) -> tuple[np.ndarray, float]:
    """Hinge axis (local frame) and median flexion from ``(T, 4)`` local rotations.

    The axis is the principal direction of the rotation vectors, signed so that the typical
    flexion is positive; without data (or with a straight limb) it falls back to local Z.
    """
    if local is None:
        return np.array([0.0, 0.0, 1.0]), 0.0
    v = quaternion_to_axis_angle(local)
    if np.median(np.linalg.norm(v, axis=-1)) < np.radians(2.0):
        return np.array([0.0, 0.0, 1.0]), 0.0
    _, vecs = np.linalg.eigh(v.T @ v)
    axis = vecs[:, -1]
    proj = v @ axis
    if np.median(proj) < 0:
        axis, proj = -axis, -proj
    return axis, float(np.median(proj))


def _intermediates(skeleton: Skeleton, name: str, joints: np.ndarray) -> tuple[np.ndarray, ...]:
    """Per chain joint, the ``(n_i,)`` joints between the previous chain joint and it.

    Raises:
        RigError: a chain joint does not hang below the previous one.
    """
    out = [np.zeros(0, dtype=np.int64)]
    for a, b in itertools.pairwise(joints):
        path = skeleton.between(a, b)
        if path is None:
            raise RigError(
                f"chain {name}: {skeleton.names[b]} does not hang below {skeleton.names[a]}; "
                "map the roles to joints along one parent-to-child path (intermediate joints "
                "between them are allowed)"
            )
        out.append(np.array(path, dtype=np.int64))
    return tuple(out)


def build_chain(
    skeleton: Skeleton,
    spec: ChainSpec,
    roles: JointRoles,
    reference: Motion | None = None,
) -> Chain:
    """Resolve one :class:`ChainSpec` on a rig.

    Args:
        skeleton: the rig.
        spec: the chain by roles.
        roles: the rig's resolved roles.
        reference: a clip of this rig whose mean pose is the neutral pose and the zero of the
            ball and swing limits, and from which hinge axes are calibrated; ``None`` uses the
            rest pose (identity rotations) and local Z hinges.

    Raises:
        RigError: the roles do not lie along one parent-to-child path on this rig.
    """
    n = skeleton.num_joints
    joints = np.array([roles.index[j.role] for j in spec.joints], dtype=np.int64)
    if np.any(joints >= n):
        raise RigError(f"chain {spec.name}: every chain joint must be a joint, not an end site")
    between = _intermediates(skeleton, spec.name, joints)
    targets = np.array([roles.index[r] for r, _ in spec.targets], dtype=np.int64)
    anchors, reach = [], []
    for t in targets:
        length, node = 0.0, int(t)
        # Walk up to the deepest chain joint, summing bone lengths for the reach.
        while node not in joints:
            parent, offset = _point_parent_and_offset(skeleton, node)
            if parent < 0:
                raise RigError(f"chain {spec.name}: target {node} does not hang from the chain")
            length += float(np.linalg.norm(offset))
            node = parent
        pos = int(np.flatnonzero(joints == node)[0])
        anchors.append(pos)
        path = [int(j) for i in range(1, pos + 1) for j in (*between[i], joints[i])]
        length += float(sum(np.linalg.norm(skeleton.offsets[j]) for j in path))
        reach.append(length)
    k = len(joints)
    ref = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
    neutral = ref.copy()
    axes = np.zeros((k, 3, 3))
    lower = np.radians([j.lower for j in spec.joints])
    upper = np.radians([j.upper for j in spec.joints])
    children = skeleton.children
    # Bones between consecutive chain joints at rest, through the intermediates' first-frame
    # rotations: ``links[i]`` is joint i in the previous joint's frame, ``turns[i]`` the
    # rotation of joint i's parent frame in it.
    rest_rot = np.zeros((1, n, 4))
    rest_rot[..., 0] = 1.0
    if reference is not None:
        rest_rot = reference.rotations[:1]
    links, turns = _fold(joints, between, rest_rot, skeleton.offsets[None])
    links, turns = links[0], turns[0]
    for i, (j, js) in enumerate(zip(joints, spec.joints, strict=True)):
        local = None if reference is None else reference.rotations[:, j]
        if i + 1 < k:
            bone = links[i + 1]
        else:
            bone = skeleton.offsets[children[j][0]] if children[j] else np.array([1.0, 0, 0])
        if js.dof == "hinge":
            # The limb above the hinge, in the hinge's parent frame.
            above = quaternion_apply(quaternion_invert(turns[i]), links[i])
            hinge_ref, axis, flex = _hinge_fit(local, above, bone)
            axes[i] = _frame_axes(bone, axis)
            # A straight limb is singular (no joint moves the tip along the limb), so the
            # neutral pose keeps the hinge bent by at least 15 degrees.
            flex = float(np.clip(flex, lower[i, 0] + np.radians(15.0), upper[i, 0]))
            ref[i] = hinge_ref
            neutral[i] = quaternion_multiply(
                hinge_ref, np.array([np.cos(flex / 2), *(np.sin(flex / 2) * axis)]))
        else:
            axes[i] = _frame_axes(bone)
            if local is not None:
                ref[i] = neutral[i] = quaternion_mean(local)
    base = int(skeleton.parents[joints[0]])
    if base < 0:
        raise RigError(f"chain {spec.name}: the first chain joint needs a parent")
    return Chain(
        spec.name, joints, base, roles.index[spec.frame], targets,
        tuple(r for r, _ in spec.targets), np.array(anchors, dtype=np.int64),
        np.array([w for _, w in spec.targets]), np.array(reach), ref, neutral, axes,
        lower, upper, between,
    )


def resolve_chains(
    skeleton: Skeleton,
    reference: Motion | None = None,
    role_map: str | Path | dict[str, str] | None = None,
    names: tuple[str, ...] = CHAIN_NAMES,
) -> dict[str, Chain]:
    """The named chains on a rig, in solving order (torso before arms).

    Args:
        skeleton: the rig.
        reference: clip for the neutral pose and hinge axes (see :func:`build_chain`).
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        names: which chains.

    Raises:
        IKError: an unknown chain name.
        RigError: the rig lacks the roles.
    """
    unknown = sorted(set(names) - set(CHAIN_NAMES))
    if unknown:
        raise IKError(f"unknown chains {unknown}; valid chains: {list(CHAIN_NAMES)}")
    roles = resolve_roles(skeleton, role_map)
    return {
        s.name: build_chain(skeleton, s, roles, reference) for s in CHAIN_SPECS if s.name in names
    }


def theta_from_rotations(chain: Chain, local: np.ndarray) -> np.ndarray:
    """Chain parameters of local rotations (projected onto the chain's DOF, not clamped).

    Args:
        chain: the chain.
        local: ``(..., k, 4)`` local rotations of the chain joints.

    Returns:
        ``(..., k, 3)`` parameters ``theta``.
    """
    rel = quaternion_multiply(quaternion_invert(np.broadcast_to(chain.ref, local.shape)), local)
    v = quaternion_to_axis_angle(rel)
    theta = np.einsum("kab,...ka->...kb", chain.axes, v)
    return np.where(chain.upper > chain.lower, theta, 0.0)


def link_transforms(
    chain: Chain, rotations: np.ndarray, positions: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """Each chain joint's translation and parent-frame rotation in the previous joint's frame.

    Folds the intermediate joints between consecutive chain joints into one transform per
    frame: chain joint ``i`` sits at ``local_pos[:, i]`` in the frame of chain joint ``i - 1``
    (the base for ``i = 0``), and its parent's frame is that frame turned by
    ``link_rot[:, i]``. Without intermediates these are the joints' own local translations
    and the identity.

    Args:
        chain: the chain.
        rotations: ``(T, J, 4)`` local rotations of the clip (the intermediates' are used).
        positions: ``(T, J, 3)`` local translations of the clip.

    Returns:
        ``(T, k, 3)`` translations in metres and ``(T, k, 4)`` rotations, or ``None`` for the
        rotations when the chain has no intermediates.
    """
    if not chain.has_intermediates:
        return positions[:, chain.joints].copy(), None
    return _fold(chain.joints, chain.between, rotations, positions)


def _fold(
    joints: np.ndarray, between: tuple[np.ndarray, ...], rotations: np.ndarray,
    positions: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`link_transforms` of ``(T, J, 4)`` rotations and ``(T, J, 3)`` translations."""
    local_pos = positions[:, joints].copy()
    link_rot = np.zeros((*local_pos.shape[:-1], 4))
    link_rot[..., 0] = 1.0
    for i, path in enumerate(between):
        if not len(path):
            continue
        rot, pos = rotations[:, path[0]], positions[:, path[0]]
        for m in path[1:]:
            pos = pos + quaternion_apply(rot, positions[:, m])
            rot = quaternion_multiply(rot, rotations[:, m])
        local_pos[:, i] = pos + quaternion_apply(rot, positions[:, joints[i]])
        link_rot[:, i] = rot
    return local_pos, link_rot
