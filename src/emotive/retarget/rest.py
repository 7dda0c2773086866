"""Rest poses by role: where each role sits when every joint is at its rest rotation.

The rest pose of a rig is its offsets with every local rotation at the identity (BVH's zero
pose): a T-pose, an A-pose, or, on Maya-style rigs such as Bandai Namco's, every bone laid
along its own axis. Retargeting pairs bones by role, so this module describes a rig's rest
pose as *role bones*: for each role, the vectors from its point to the points of its child
roles in :data:`ROLE_PARENT`, in world coordinates (which are also the role joint's local
frame, every rest rotation being the identity).

Legend: ``J`` joints, ``E`` end sites, ``T`` frames, ``R`` roles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.roles import ROLE_PARENT, ROLES, JointRoles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

#: Role children of each role, in :data:`ROLES` order.
ROLE_CHILDREN: dict[str, tuple[str, ...]] = {
    role: tuple(r for r in ROLES if ROLE_PARENT.get(r) == role) for role in ROLES
}

#: Shorter vectors (metres) are treated as no bone at all (Bandai's zero-length end sites).
MIN_BONE = 1e-6


def rest_points(skeleton: Skeleton) -> np.ndarray:
    """``(J + E, 3)`` world positions of the joints then end sites in the rest pose, metres.

    Every local rotation is the identity and every joint sits at its offset, the root at its
    own offset.
    """
    pos = np.zeros((skeleton.num_joints, 3))
    for j, p in enumerate(skeleton.parents):
        pos[j] = skeleton.offsets[j] + (pos[p] if p >= 0 else 0.0)
    ends = pos[skeleton.end_site_parents] + skeleton.end_site_offsets
    return np.concatenate((pos, ends))


def point_joint(skeleton: Skeleton, point: int) -> int:
    """The joint of an entry of the ``(J + E)`` array: itself, or an end site's parent."""
    n = skeleton.num_joints
    return point if point < n else int(skeleton.end_site_parents[point - n])


def path_between(skeleton: Skeleton, top: int, point: int) -> list[int]:
    """Joints strictly below joint ``top`` down to ``point``'s joint, parent first.

    ``point`` indexes the ``(J + E)`` array; for an end site the path ends at its parent.

    Raises:
        RigError: ``point`` does not hang below ``top``.
    """
    joint = point_joint(skeleton, point)
    path = [] if joint == top else skeleton.between(top, joint)
    if path is None:
        raise RigError(
            f"{_point_label(skeleton, point)} does not hang below {skeleton.names[top]}: map "
            "the roles so that each role sits below its parent role (spine below root, elbow "
            "below shoulder, ...)"
        )
    return [*path, joint] if joint != top else []


def _point_label(skeleton: Skeleton, point: int) -> str:
    n = skeleton.num_joints
    return skeleton.names[point] if point < n else \
        f"the end site of {skeleton.names[skeleton.end_site_parents[point - n]]}"


@dataclass(frozen=True)
class RoleBones:
    """The role bones of one rig.

    Attributes:
        points: role -> index into the ``(J + E)`` joint-then-end-site array.
        joints: role -> joint index carrying the role (an end site's parent joint).
        rest: ``(J + E, 3)`` rest-pose world positions (:func:`rest_points`), metres.
    """

    points: dict[str, int]
    joints: dict[str, int]
    rest: np.ndarray

    def vector(self, role: str, child: str) -> np.ndarray:
        """``(3,)`` rest vector from ``role``'s point to ``child``'s, metres."""
        return self.rest[self.points[child]] - self.rest[self.points[role]]


def role_bones(skeleton: Skeleton, roles: JointRoles) -> RoleBones:
    """The role bones of a rig whose roles are resolved.

    Raises:
        RigError: a role does not hang below its parent role (:data:`ROLE_PARENT`).
    """
    points = {r: int(roles.index[r]) for r in ROLES}
    joints = {r: point_joint(skeleton, i) for r, i in points.items()}
    for role, parent in ROLE_PARENT.items():
        if points[role] != points[parent]:
            path_between(skeleton, joints[parent], points[role])
    return RoleBones(points, joints, rest_points(skeleton))


def has_bone(bones: RoleBones, role: str, child: str) -> bool:
    """Whether the rest vector from ``role`` to ``child`` has a length on this rig.

    A role that falls back onto its parent's joint (a rig without ``chest``) or an end site
    of zero length (Bandai's hand and toe tips) gives no direction to align.
    """
    return bool(np.linalg.norm(bones.vector(role, child)) > MIN_BONE)
