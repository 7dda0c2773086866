"""Joint roles: map any rig onto the named body parts features and models use.

A role names a body part (``root``, ``l_wrist``, ...). A rig is mapped onto roles by joint
names, with built-in maps for the Bandai Namco rig and CMU-style naming, or a user JSON file
``{"role": "JointName", ...}``. Roles may point at a joint or at an end site: positions for
roles are looked up in the array of joint positions followed by end-site positions
(``(T, J + E, 3)``, see :meth:`emotive.core.Motion.positions_with_end_sites`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

#: Every role, in a stable order.
ROLES: tuple[str, ...] = (
    "root", "spine", "chest", "neck", "head",
    "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
    "l_handtip", "r_handtip",
    "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe",
)

#: Roles a rig may lack; each falls back to the listed role.
FALLBACKS: dict[str, str] = {"chest": "spine", "l_handtip": "l_wrist", "r_handtip": "r_wrist"}

#: Suffix ``/end`` means "the first end site below this joint".
END_SITE = "/end"

BANDAI: dict[str, str] = {
    "root": "Hips", "spine": "Spine", "chest": "Chest", "neck": "Neck", "head": "Head",
    "l_shoulder": "UpperArm_L", "r_shoulder": "UpperArm_R",
    "l_elbow": "LowerArm_L", "r_elbow": "LowerArm_R",
    "l_wrist": "Hand_L", "r_wrist": "Hand_R",
    "l_handtip": "Hand_L/end", "r_handtip": "Hand_R/end",
    "l_hip": "UpperLeg_L", "r_hip": "UpperLeg_R",
    "l_knee": "LowerLeg_L", "r_knee": "LowerLeg_R",
    "l_ankle": "Foot_L", "r_ankle": "Foot_R",
    "l_toe": "Toes_L/end", "r_toe": "Toes_R/end",
}

CMU: dict[str, str] = {
    "root": "Hips", "spine": "Spine", "chest": "Spine1", "neck": "Neck", "head": "Head",
    "l_shoulder": "LeftArm", "r_shoulder": "RightArm",
    "l_elbow": "LeftForeArm", "r_elbow": "RightForeArm",
    "l_wrist": "LeftHand", "r_wrist": "RightHand",
    "l_handtip": "LeftHandIndex1", "r_handtip": "RightHandIndex1",
    "l_hip": "LeftUpLeg", "r_hip": "RightUpLeg",
    "l_knee": "LeftLeg", "r_knee": "RightLeg",
    "l_ankle": "LeftFoot", "r_ankle": "RightFoot",
    "l_toe": "LeftToeBase", "r_toe": "RightToeBase",
}

BUILTIN_MAPS: dict[str, dict[str, str]] = {"bandai": BANDAI, "cmu": CMU}


@dataclass(frozen=True)
class JointRoles:
    """Resolved roles of one rig.

    Attributes:
        index: role name -> index into the ``(J + E)`` array of joint then end-site positions.
        names: role name -> joint name it resolved to (``"Hand_L/end"`` for an end site).
        map_name: which map produced it (``"bandai"``, ``"cmu"`` or a file path).
    """

    index: dict[str, int]
    names: dict[str, str]
    map_name: str

    def indices(self, roles: tuple[str, ...] = ROLES) -> np.ndarray:
        """``(len(roles),)`` indices of the given roles, in that order."""
        return np.array([self.index[r] for r in roles], dtype=np.int64)


def load_role_map(path: str | Path) -> dict[str, str]:
    """Read a user role map: a JSON object ``{"role": "JointName"}``."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise RigError(f"role map {path} does not exist: check the path") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"role map {path} is not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not all(isinstance(v, str) for v in data.values()):
        raise RigError(f'role map {path} must be a JSON object {{"role": "JointName", ...}}')
    unknown = sorted(set(data) - set(ROLES))
    if unknown:
        raise RigError(f"role map {path} names unknown roles {unknown}; valid roles: {list(ROLES)}")
    return data


def _lookup(skeleton: Skeleton, joint: str) -> int | None:
    """Index in the joint-then-end-site array, or None if the rig lacks it."""
    if joint.endswith(END_SITE):
        base = joint[: -len(END_SITE)]
        if base not in skeleton.names:
            return None
        j = skeleton.names.index(base)
        ends = np.flatnonzero(skeleton.end_site_parents == j)
        return skeleton.num_joints + int(ends[0]) if len(ends) else j
    return skeleton.names.index(joint) if joint in skeleton.names else None


def _try_map(skeleton: Skeleton, mapping: dict[str, str]) -> tuple[dict[str, int], list[str]]:
    index: dict[str, int] = {}
    missing: list[str] = []
    for role in ROLES:
        found = _lookup(skeleton, mapping[role]) if role in mapping else None
        if found is None and role in FALLBACKS and FALLBACKS[role] in mapping:
            found = _lookup(skeleton, mapping[FALLBACKS[role]])
        if found is None:
            missing.append(role)
        else:
            index[role] = found
    return index, missing


def point_name(skeleton: Skeleton, index: int) -> str:
    """Name of an entry of the ``(J + E)`` joint-then-end-site array (``"Hand_L/end"``)."""
    n = skeleton.num_joints
    if index < n:
        return skeleton.names[index]
    return f"{skeleton.names[skeleton.end_site_parents[index - n]]}{END_SITE}"


def _candidates(role_map: str | Path | dict[str, str] | None) -> list[tuple[str, dict[str, str]]]:
    if role_map is None:
        return list(BUILTIN_MAPS.items())
    if isinstance(role_map, dict):
        return [("user", role_map)]
    if str(role_map) in BUILTIN_MAPS:
        return [(str(role_map), BUILTIN_MAPS[str(role_map)])]
    return [(str(role_map), load_role_map(role_map))]


def match_roles(
    skeleton: Skeleton, role_map: str | Path | dict[str, str] | None = None
) -> tuple[str, dict[str, int], list[str]]:
    """The candidate map that resolves the most roles of a rig, without raising on gaps.

    Args:
        skeleton: the rig.
        role_map: as for :func:`resolve_roles`.

    Returns:
        The map's name, role -> index into the ``(J + E)`` array for the roles found, and the
        missing roles (empty when the rig is complete).
    """
    best: tuple[str, dict[str, int], list[str]] | None = None
    for name, mapping in _candidates(role_map):
        index, missing = _try_map(skeleton, mapping)
        if best is None or len(missing) < len(best[2]):
            best = (name, index, missing)
        if not missing:
            break
    assert best is not None
    return best


def missing_roles_message(map_name: str, missing: list[str]) -> str:
    """The one-line explanation of a rig that lacks ``missing`` roles under ``map_name``."""
    return (
        f"the rig lacks the roles {missing} (closest map: {map_name}); pass a JSON role map "
        '{"role": "JointName", ...} with --roles to name the joints that play them'
    )


def resolve_roles(
    skeleton: Skeleton, role_map: str | Path | dict[str, str] | None = None
) -> JointRoles:
    """Map a rig onto :data:`ROLES`.

    Args:
        skeleton: the rig.
        role_map: ``None`` to try the built-in maps, a built-in name (``"bandai"``, ``"cmu"``),
            a mapping ``{role: joint name}``, or the path of a JSON file holding one.

    Raises:
        RigError: the rig lacks roles; the message lists the missing roles and how to supply them.
    """
    name, index, missing = match_roles(skeleton, role_map)
    if missing:
        raise RigError(missing_roles_message(name, missing))
    return JointRoles(index, {r: point_name(skeleton, i) for r, i in index.items()}, name)
