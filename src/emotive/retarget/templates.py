"""Rig templates: any humanoid rig rebuilt standing in a T-pose or an A-pose.

A template keeps a rig's joint names, hierarchy, end sites and bone lengths and redirects
every bone to a canonical direction by the body part it belongs to (found through the roles),
so that its rest pose (every rotation at the identity) is a standing T- or A-pose facing +Z
(Y up, the character's left on +X) with its lowest point on the ground ``y = 0``. Lengths may
be scaled per part (longer legs, shorter arms) and the rotation order changed, which makes
target rigs whose rest pose, proportions and channels all differ from the source's: the
tests and demos of retargeting build their Mixamo, CMU or Unreal characters this way from
:func:`emotive.core.rig_layouts.to_layout` layouts of a Bandai Namco clip.

Canonical directions: the spine, neck and head point up; each hip hangs out sideways and a
little down from the root; each clavicle rises sideways from the chest; arms point sideways
(T-pose) or 45 degrees down (A-pose); legs point down; the foot points forward and down from
the ankle to the toe role and forward beyond it. A joint on no role path (fingers, twist and
helper bones, end sites) continues its parent's bone.

Legend: ``J`` joints, ``E`` end sites.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import ROLES, resolve_roles
from emotive.core.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton
from emotive.errors import RigError
from emotive.io.bvh_limits import UNITS
from emotive.retarget.rest import ROLE_PARENT, path_between, point_joint, rest_points

RoleMap = str | Path | dict[str, str] | None

#: Rest poses a template can stand in.
POSES = ("t", "a")
#: Body parts whose bone lengths :func:`rest_template` can scale.
PARTS = ("spine", "head", "arms", "legs", "feet")

UP = np.array([0.0, 1.0, 0.0])
DOWN = -UP
FORWARD = np.array([0.0, 0.0, 1.0])

#: Part of each role bone (parent role -> role), by the child role without its side.
_PART = {"spine": "spine", "chest": "spine", "neck": "spine", "head": "head",
         "shoulder": "spine", "elbow": "arms", "wrist": "arms", "handtip": "arms",
         "hip": "spine", "knee": "legs", "ankle": "legs", "toe": "feet"}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _directions(role: str, n: int, pose: str) -> list[np.ndarray]:
    """Canonical directions of the ``n`` bones of the path from ``role``'s parent to it."""
    side = 1.0 if role.startswith("l_") else -1.0
    kind = role.split("_", 1)[-1]
    if kind in ("elbow", "wrist", "handtip"):
        arm = [side, 0.0, 0.0] if pose == "t" else [side, -1.0, 0.0]
        return [_unit(np.array(arm))] * n
    if kind == "shoulder":
        # Clavicle joints rise sideways from the chest; the last bone reaches the shoulder.
        return [_unit(np.array([0.4 * side, 1.0, 0.0]))] * (n - 1) + [
            np.array([side, 0.0, 0.0]) if n > 1 else _unit(np.array([side, 0.5, 0.0]))]
    if kind == "hip":
        return [_unit(np.array([side, -0.35, 0.0]))] * n
    if kind in ("knee", "ankle"):
        return [DOWN] * n
    if kind == "toe":
        return [_unit(np.array([0.0, -0.5, 1.0]))] + [FORWARD] * (n - 1)
    return [UP] * n


def _label_paths(skeleton: Skeleton, points: dict[str, int], pose: str
                 ) -> tuple[dict[int, np.ndarray], dict[int, str]]:
    """Direction and part of every point (``J + E`` index) on a role path, first path wins."""
    direction: dict[int, np.ndarray] = {}
    part: dict[int, str] = {}
    for role in ROLES:
        parent = ROLE_PARENT.get(role)
        if parent is None or points[role] == points[parent]:
            continue
        path = path_between(skeleton, point_joint(skeleton, points[parent]), points[role])
        if points[role] >= skeleton.num_joints:
            path = [*path, points[role]]
        for point, d in zip(path, _directions(role, len(path), pose), strict=True):
            if point not in direction:
                direction[point] = d
                part[point] = _PART[role.split("_", 1)[-1]]
    return direction, part


def _channels(skeleton: Skeleton, rotation_order: str | None) -> tuple[tuple[str, ...], ...]:
    if rotation_order is None:
        return skeleton.channels
    order = rotation_order.upper()
    if sorted(order) != ["X", "Y", "Z"]:
        raise RigError(f"rotation order {rotation_order!r}: use three distinct axes, e.g. XYZ")
    rot = tuple(f"{a}rotation" for a in order)
    return tuple(
        (*(c for c in ch if c in POSITION_CHANNELS), *(rot if any(
            c in ROTATION_CHANNELS for c in ch) else ()))
        for ch in skeleton.channels
    )


def rest_template(
    skeleton: Skeleton,
    role_map: RoleMap = None,
    *,
    pose: str = "t",
    proportions: Mapping[str, float] | None = None,
    rotation_order: str | None = None,
) -> Skeleton:
    """The rig standing in a canonical T- or A-pose (see the module docstring).

    Args:
        skeleton: any humanoid rig.
        role_map: its role map (see :func:`emotive.core.roles.resolve_roles`).
        pose: ``"t"`` (arms sideways) or ``"a"`` (arms 45 degrees down).
        proportions: length factors by part (:data:`PARTS`), e.g. ``{"legs": 1.15,
            "arms": 0.9}``; parts not named keep their lengths.
        rotation_order: Euler order of every joint's rotation channels (``"XYZ"``, ...);
            ``None`` keeps the rig's channels.

    Returns:
        The template: same names, hierarchy and end sites, offsets ``(J, 3)`` redirected and
        scaled, the root role standing so that the lowest point is on ``y = 0``; the joints
        above the root role sit at the origin.

    Raises:
        RigError: the rig lacks roles, a role does not hang below its parent role, an unknown
            pose, part or rotation order.
    """
    if pose not in POSES:
        raise RigError(f"pose {pose!r}: use one of {', '.join(POSES)}")
    factors = dict(proportions or {})
    unknown = sorted(set(factors) - set(PARTS))
    if unknown:
        raise RigError(f"proportions name unknown parts {unknown}; parts: {', '.join(PARTS)}")
    roles = resolve_roles(skeleton, role_map)
    points = {r: int(roles.index[r]) for r in ROLES}
    direction, part = _label_paths(skeleton, points, pose)
    n = skeleton.num_joints
    bones = np.concatenate((skeleton.offsets, skeleton.end_site_offsets))
    parents = np.concatenate((skeleton.parents, skeleton.end_site_parents))
    root = point_joint(skeleton, points["root"])
    above = set(path_between(skeleton, -1, root))
    new = np.zeros_like(bones)
    for point in range(len(bones)):
        p = int(parents[point])
        if point in above or p < 0:
            continue
        if point not in direction:
            inherit = direction.get(p, UP)
            direction[point] = FORWARD if part.get(p) == "feet" else inherit
            part[point] = part.get(p, "spine")
        new[point] = direction[point] * np.linalg.norm(bones[point]) * factors.get(part[point], 1)
    standing = Skeleton(skeleton.names, skeleton.parents, new[:n], _channels(skeleton,
                        rotation_order), skeleton.end_site_parents, new[n:])
    lowest = rest_points(standing)[:, 1].min()
    offsets = new[:n].copy()
    offsets[root] = [0.0, -lowest, 0.0]
    return Skeleton(standing.names, standing.parents, offsets, standing.channels,
                    standing.end_site_parents, standing.end_site_offsets)


def rest_clip(skeleton: Skeleton, unit: str = "cm", fps: float = 30.0, frames: int = 1,
              name: str = "rig") -> Motion:
    """A clip holding a rig's rest pose, ready for :func:`emotive.io.bvh.write_bvh`.

    Args:
        skeleton: the rig.
        unit: the file unit it is written in (``m``, ``cm``, ``mm``, ``in``).
        fps: frame rate.
        frames: number of frames, at least one.
        name: the clip's name (metadata).

    Returns:
        Rotations ``(frames, J, 4)`` at the identity and positions ``(frames, J, 3)`` at the
        offsets.

    Raises:
        RigError: an unknown unit or fewer than one frame.
    """
    if unit not in UNITS:
        raise RigError(f"unit {unit!r}: use one of {', '.join(UNITS)}")
    if frames < 1:
        raise RigError(f"a rig clip needs at least one frame, got {frames}")
    rotations = np.tile([1.0, 0.0, 0.0, 0.0], (frames, skeleton.num_joints, 1))
    positions = np.broadcast_to(skeleton.offsets, (frames, skeleton.num_joints, 3)).copy()
    return Motion(skeleton, rotations, positions, fps, {"name": name, "file_unit": unit})
