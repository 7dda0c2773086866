"""Joint roles: map any humanoid rig onto the named body parts features and models use.

A role names a body part (``root``, ``l_wrist``, ...). A rig is mapped onto roles by joint
names, detected among the families of :mod:`emotive.core.rig_names` (Bandai Namco, CMU with
or without ``LHipJoint``/``LowerBack``/``Neck1``, Mixamo, the Unreal mannequin, Unity
humanoid, VRM, SMPL and SMPL-X; case, separators and namespace prefixes such as
``mixamorig:``, ``Armature|`` or a ``Character1_`` shared by every joint are ignored), else
from the rig's shape (:mod:`emotive.core.rig_topology`), or given as a user map
``{"role": "JointName", ...}`` (a JSON file or a dict). Twist, finger and helper bones play no
role (:attr:`JointRoles.extras`) and are never required. Roles may point at a joint or at an
end site: positions for roles are looked up in the array of joint positions followed by
end-site positions (``(T, J + E, 3)``, see
:meth:`emotive.core.Motion.positions_with_end_sites`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from emotive.core.rig_names import FAMILIES, normalize
from emotive.core.rig_topology import topology_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

#: Every role, in a stable order.
ROLES: tuple[str, ...] = (
    "root", "spine", "chest", "neck", "head",
    "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
    "l_handtip", "r_handtip",
    "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe",
)

#: Parent of every role but the root in the role tree (arms from the chest, legs from the root).
ROLE_PARENT: dict[str, str] = {
    "spine": "root", "chest": "spine", "neck": "chest", "head": "neck",
    "l_shoulder": "chest", "l_elbow": "l_shoulder", "l_wrist": "l_elbow",
    "l_handtip": "l_wrist",
    "r_shoulder": "chest", "r_elbow": "r_shoulder", "r_wrist": "r_elbow",
    "r_handtip": "r_wrist",
    "l_hip": "root", "l_knee": "l_hip", "l_ankle": "l_knee", "l_toe": "l_ankle",
    "r_hip": "root", "r_knee": "r_hip", "r_ankle": "r_knee", "r_toe": "r_ankle",
}

#: Roles a rig may lack; each falls back to the listed role.
FALLBACKS: dict[str, str] = {"chest": "spine", "l_handtip": "l_wrist", "r_handtip": "r_wrist"}

#: Suffix ``/end`` means "the first end site below this joint".
END_SITE = "/end"

#: Each family's first choice per role, as plain maps (see :mod:`emotive.core.rig_names`).
BUILTIN_MAPS: dict[str, dict[str, str]] = {
    name: {role: names[0] for role, names in family.roles.items()}
    for name, family in FAMILIES.items()
}
BANDAI: dict[str, str] = BUILTIN_MAPS["bandai"]
CMU: dict[str, str] = BUILTIN_MAPS["cmu"]
#: What :func:`match_roles` calls a rig resolved from its shape, not its names.
TOPOLOGY = "topology"
#: The command that prints a role map to fill in (for error messages).
TEMPLATE_COMMAND = "emotive info FILE --roles-template"


@dataclass(frozen=True)
class JointRoles:
    """Resolved roles of one rig.

    Attributes:
        index: role name -> index into the ``(J + E)`` array of joint then end-site positions.
        names: role name -> joint name it resolved to (``"Hand_L/end"`` for an end site).
        map_name: which map produced it: a family (``"bandai"``, ``"cmu"``, ``"mixamo"``, ...),
            ``"topology"``, ``"user"`` (a dict) or a JSON file's path.
        extras: the joints that play no role (twist, finger, helper and inserted bones).
    """

    index: dict[str, int]
    names: dict[str, str]
    map_name: str
    extras: tuple[str, ...] = ()

    @property
    def family(self) -> str:
        """The rig family the roles were detected from (``"topology"`` or the map's name)."""
        return self.map_name

    def indices(self, roles: tuple[str, ...] = ROLES) -> np.ndarray:
        """``(len(roles),)`` indices of the given roles, in that order."""
        return np.array([self.index[r] for r in roles], dtype=np.int64)


def load_role_map(path: str | Path) -> dict[str, str]:
    """Read a user role map: a JSON object ``{"role": "JointName"}``.

    Roles left empty (``""`` or ``null``, as ``emotive info FILE --roles-template`` prints
    the roles it could not find) are dropped: the rig lacks them.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise RigError(f"role map {path} does not exist: check the path") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"role map {path} is not valid JSON ({exc})") from None
    if not isinstance(data, dict) or not all(isinstance(v, str | None) for v in data.values()):
        raise RigError(f'role map {path} must be a JSON object {{"role": "JointName", ...}}')
    unknown = sorted(set(data) - set(ROLES))
    if unknown:
        raise RigError(f"role map {path} names unknown roles {unknown}; valid roles: {list(ROLES)}")
    return {role: joint for role, joint in data.items() if joint}


def _strip_prefix(names: tuple[str, ...]) -> list[str]:
    """The names without their namespace and without a prefix every one of them shares.

    The shared prefix is cut after its last separator (``"Character1_"``, ``"Bip01 "``) and
    only when it leaves every name non-empty.
    """
    bases = [n.replace("|", ":").rsplit(":", 1)[-1] for n in names]
    common = min(bases, key=len) if len(bases) > 1 else ""
    while common and not all(b.startswith(common) for b in bases):
        common = common[:-1]
    cut = max(common.rfind(c) for c in "_ .-") + 1
    if cut > 0 and all(len(b) > cut for b in bases):
        return [b[cut:] for b in bases]
    return bases


class _Names:
    """A rig's joint names prepared for matching against the family tables."""

    def __init__(self, skeleton: Skeleton) -> None:
        self.skeleton = skeleton
        self.bases = _strip_prefix(skeleton.names)
        self.exact = {b: j for j, b in reversed(list(enumerate(self.bases)))}
        self.normal = {normalize(b): j for j, b in reversed(list(enumerate(self.bases)))}

    def find(self, joint: str) -> int | None:
        """Index of a joint named ``joint`` (exactly, else by :func:`normalize`), or None."""
        if joint in self.skeleton.names:
            return self.skeleton.names.index(joint)
        base = joint.replace("|", ":").rsplit(":", 1)[-1]
        return self.exact.get(base, self.normal.get(normalize(base)))


def _lookup(names: _Names, joint: str) -> int | None:
    """Index in the joint-then-end-site array, or None if the rig lacks it."""
    sk = names.skeleton
    if joint.endswith(END_SITE):
        j = names.find(joint[: -len(END_SITE)])
        if j is None:
            return None
        ends = np.flatnonzero(sk.end_site_parents == j)
        return sk.num_joints + int(ends[0]) if len(ends) else j
    return names.find(joint)


def _try_map(
    names: _Names, mapping: dict[str, tuple[str, ...]]
) -> tuple[dict[str, int], list[str]]:
    """Role -> index for the roles the candidates resolve, and the missing roles."""
    index: dict[str, int] = {}
    for role in ROLES:
        found = next((k for k in (_lookup(names, j) for j in mapping.get(role, ()))
                      if k is not None), None)
        if found is not None:
            index[role] = found
    missing = []
    for role in ROLES:
        if role not in index and FALLBACKS.get(role) in index:
            index[role] = index[FALLBACKS[role]]
        elif role not in index:
            missing.append(role)
    return index, missing


@cache
def _family_names(name: str) -> tuple[frozenset[str], frozenset[str]]:
    """A family's normalized vocabulary and its names as spelled."""
    family = FAMILIES[name]
    spelled = {n.removesuffix(END_SITE) for c in family.roles.values() for n in c}
    return family.vocabulary(), frozenset(spelled | set(family.known))


def _score(names: _Names, family: str, index: dict[str, int]) -> tuple[int, int, int, int]:
    """How well a family fits, compared in order.

    Roles found, joints named in its vocabulary, joints in its namespace
    (:attr:`~emotive.core.rig_names.Family.namespace`), exact spellings.
    """
    vocabulary, spelled = _family_names(family)
    hits = sum(normalize(b) in vocabulary for b in names.bases)
    exact = sum(b in spelled for b in names.bases)
    return len(index), hits, FAMILIES[family].namespaced(names.skeleton.names), exact


def point_name(skeleton: Skeleton, index: int) -> str:
    """Name of an entry of the ``(J + E)`` joint-then-end-site array (``"Hand_L/end"``)."""
    n = skeleton.num_joints
    if index < n:
        return skeleton.names[index]
    return f"{skeleton.names[skeleton.end_site_parents[index - n]]}{END_SITE}"


def _by_names(names: _Names) -> tuple[str, dict[str, int], list[str]]:
    """The family whose names fit the rig best (ties go to the earlier family)."""
    best, best_score = None, None
    for name, family in FAMILIES.items():
        index, missing = _try_map(names, family.roles)
        score = _score(names, name, index)
        if best_score is None or score > best_score:
            best, best_score = (name, index, missing), score
    assert best is not None
    return best


def _detect(skeleton: Skeleton) -> tuple[str, dict[str, int], list[str], str | None]:
    """Names first, then the shape; the last item is why the shape did not fit, if it did not."""
    name, index, missing = _by_names(_Names(skeleton))
    if not missing:
        return name, index, missing, None
    try:
        return TOPOLOGY, topology_roles(skeleton), [], None
    except RigError as exc:
        return name, index, missing, str(exc)


def _user_map(role_map: str | Path | dict[str, str]) -> tuple[str, dict[str, tuple[str, ...]]]:
    if isinstance(role_map, dict):
        return "user", {r: (j,) for r, j in role_map.items() if j}
    if str(role_map) in FAMILIES:
        return str(role_map), FAMILIES[str(role_map)].roles
    return str(role_map), {r: (j,) for r, j in load_role_map(role_map).items()}


def match_roles(
    skeleton: Skeleton, role_map: str | Path | dict[str, str] | None = None
) -> tuple[str, dict[str, int], list[str]]:
    """The map that resolves the most roles of a rig, without raising on gaps.

    Args:
        skeleton: the rig.
        role_map: as for :func:`resolve_roles`.

    Returns:
        The map's name (a family, ``"topology"``, ``"user"`` or a file path), role -> index
        into the ``(J + E)`` array for the roles found, and the missing roles (empty when the
        rig is complete).
    """
    if role_map is None:
        return _detect(skeleton)[:3]
    name, mapping = _user_map(role_map)
    return (name, *_try_map(_Names(skeleton), mapping))


def missing_roles_message(map_name: str, missing: list[str]) -> str:
    """The one-line explanation of a rig that lacks ``missing`` roles under ``map_name``."""
    return (
        f"the rig lacks the roles {missing} (closest map: {map_name}); run "
        f"`{TEMPLATE_COMMAND}` for a JSON role map to fill in and pass it with --roles"
    )


def extra_joints(skeleton: Skeleton, index: dict[str, int]) -> tuple[str, ...]:
    """The joints of ``skeleton`` that play none of the roles in ``index``, in rig order.

    A joint whose end site plays a role (``Toes_L/end``) plays a role.
    """
    n = skeleton.num_joints
    used = {k if k < n else int(skeleton.end_site_parents[k - n]) for k in index.values()}
    return tuple(n for j, n in enumerate(skeleton.names) if j not in used)


def role_template(
    skeleton: Skeleton, role_map: str | Path | dict[str, str] | None = None
) -> dict[str, str | None]:
    """A role map to edit: every role with the joint it resolved to, ``None`` when missing.

    Args:
        skeleton: the rig.
        role_map: as for :func:`resolve_roles`.

    Returns:
        role -> joint name (``"Hand_L/end"`` for an end site) or ``None``, in :data:`ROLES`
        order; :func:`load_role_map` reads it back once saved as JSON.
    """
    _, index, _ = match_roles(skeleton, role_map)
    return {r: point_name(skeleton, index[r]) if r in index else None for r in ROLES}


def resolve_roles(
    skeleton: Skeleton, role_map: str | Path | dict[str, str] | None = None
) -> JointRoles:
    """Map a rig onto :data:`ROLES`.

    Args:
        skeleton: the rig.
        role_map: ``None`` to detect the family by names (then by shape), a family's name
            (any of :data:`emotive.core.rig_names.FAMILIES`), a mapping
            ``{role: joint name}``, or the path of a JSON file holding one.

    Raises:
        RigError: the rig lacks roles (the message lists them and names the command that
            prints a role map to fill in), or it is not a humanoid (the message says what is
            missing).
    """
    problem = None
    if role_map is None:
        name, index, missing, problem = _detect(skeleton)
    else:
        name, index, missing = match_roles(skeleton, role_map)
    if missing:
        if problem and len(index) < len(ROLES) // 2:
            raise RigError(
                f"{problem}, and its joint names match no rig family (it lacks the roles "
                f"{missing}); if it is one, name its joints with --roles (template: "
                f"`{TEMPLATE_COMMAND}`)"
            )
        raise RigError(missing_roles_message(name, missing))
    names = {r: point_name(skeleton, i) for r, i in index.items()}
    return JointRoles(index, names, name, extra_joints(skeleton, index))
