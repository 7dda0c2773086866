"""Joint-name tables of the common humanoid rig families, for :mod:`emotive.core.roles`.

Each :class:`Family` lists, per role, the joint names that can play it, best first (a name
ending in ``/end`` means the first end site below that joint, or the joint itself when it has
none), and the family's other joint names (``known``: twist, finger and helper bones, inserted
spine joints), which play no role but tell the family apart when the role names are shared.
Names are compared by :func:`normalize` (case, separators and namespaces ignored).

The choice of ``spine`` and ``chest`` on rigs with several spine joints follows one rule:
``chest`` is the joint the clavicles (shoulders) hang from, as the Bandai rig's ``Chest``, and
``spine`` the first spine joint above the hips. So Unreal's ``spine_01``..``spine_05`` give
``spine=spine_01`` and ``chest=spine_05`` (``spine_03`` on the three-joint UE4 spine), Mixamo's
``Spine``/``Spine1``/``Spine2`` give ``Spine`` and ``Spine2``, SMPL's ``spine1..3`` give
``spine1`` and ``spine3``, Unity's and VRM's ``UpperChest`` (when present) is the chest.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: Separators dropped by :func:`normalize`.
_SEPARATORS = re.compile(r"[\s_.\-]+")


def normalize(name: str) -> str:
    """A joint name for matching: the namespace dropped, lower case, no separators.

    ``"mixamorig1:LeftArm"`` and ``"Armature|mixamorig:LeftArm"`` become ``"leftarm"``,
    ``"upperarm_l"`` becomes ``"upperarml"``.
    """
    base = re.split(r"[:|]", name)[-1]
    return _SEPARATORS.sub("", base).lower()


@dataclass(frozen=True)
class Family:
    """One rig family's names.

    Attributes:
        roles: role -> joint names that can play it, best first (``"X/end"`` allowed).
        known: the family's other joint names (no role).
        namespace: pattern of the namespace the family's exporter puts before every joint
            name (Mixamo's ``mixamorig:``, ``mixamorig1:``), matched in full against each
            namespace of a name; it tells apart families whose names coincide (a Mixamo rig
            without ``Spine2`` and fingers has only CMU's names).
    """

    roles: dict[str, tuple[str, ...]]
    known: tuple[str, ...] = ()
    namespace: str | None = None

    def namespaced(self, names: tuple[str, ...]) -> int:
        """How many of ``names`` carry the family's namespace (``"Armature|mixamorig:Hips"``)."""
        if self.namespace is None:
            return 0
        pattern = re.compile(self.namespace, re.IGNORECASE)
        return sum(any(pattern.fullmatch(part) for part in re.split(r"[:|]", n)[:-1])
                   for n in names)

    def vocabulary(self) -> frozenset[str]:
        """Every normalized joint name of the family."""
        names = [n.removesuffix("/end") for c in self.roles.values() for n in c]
        return frozenset(normalize(n) for n in (*names, *self.known))


def _sided(table: dict[str, tuple[str, ...]], left: str, right: str) -> dict[str, tuple[str, ...]]:
    """Roles of both sides from ``l_*`` entries whose names hold ``{s}`` for the side.

    ``{t}`` stands for the side's capital initial (``L_Hip``).
    """
    out: dict[str, tuple[str, ...]] = {}
    for role, names in table.items():
        if role.startswith("l_"):
            out[role] = tuple(n.format(s=left, t=left[0].upper()) for n in names)
            out["r_" + role[2:]] = tuple(n.format(s=right, t=right[0].upper()) for n in names)
        else:
            out[role] = names
    return out


def _both(names: tuple[str, ...], left: str, right: str) -> tuple[str, ...]:
    return tuple(n.format(s=s) for n in names for s in (left, right))


_FINGERS = ("Thumb", "Index", "Middle", "Ring", "Pinky")

BANDAI_FAMILY = Family(
    _sided({
        "root": ("Hips",), "spine": ("Spine",), "chest": ("Chest",), "neck": ("Neck",),
        "head": ("Head",), "l_shoulder": ("UpperArm_{s}",), "l_elbow": ("LowerArm_{s}",),
        "l_wrist": ("Hand_{s}",), "l_handtip": ("Hand_{s}/end",), "l_hip": ("UpperLeg_{s}",),
        "l_knee": ("LowerLeg_{s}",), "l_ankle": ("Foot_{s}",), "l_toe": ("Toes_{s}/end",),
    }, "L", "R"),
    ("joint_Root", "Shoulder_L", "Shoulder_R"),
)

CMU_FAMILY = Family(
    _sided({
        "root": ("Hips",), "spine": ("Spine",), "chest": ("Spine1",), "neck": ("Neck",),
        "head": ("Head",), "l_shoulder": ("{s}Arm",), "l_elbow": ("{s}ForeArm",),
        "l_wrist": ("{s}Hand",),
        "l_handtip": ("{s}HandIndex1/end", "{s}FingerBase/end", "{s}Hand/end"),
        "l_hip": ("{s}UpLeg",), "l_knee": ("{s}Leg",), "l_ankle": ("{s}Foot",),
        "l_toe": ("{s}ToeBase/end",),
    }, "Left", "Right"),
    ("LHipJoint", "RHipJoint", "LowerBack", "Neck1", "LThumb", "RThumb",
     *_both(("{s}Shoulder", "{s}FingerBase"), "Left", "Right")),
)

MIXAMO_FAMILY = Family(
    _sided({
        "root": ("Hips",), "spine": ("Spine",), "chest": ("Spine2", "Spine1"),
        "neck": ("Neck",), "head": ("Head",), "l_shoulder": ("{s}Arm",),
        "l_elbow": ("{s}ForeArm",), "l_wrist": ("{s}Hand",),
        "l_handtip": ("{s}HandMiddle4", "{s}HandIndex4", "{s}HandMiddle3/end",
                      "{s}HandIndex3/end", "{s}Hand/end"),
        "l_hip": ("{s}UpLeg",), "l_knee": ("{s}Leg",), "l_ankle": ("{s}Foot",),
        "l_toe": ("{s}Toe_End", "{s}ToeBase/end"),
    }, "Left", "Right"),
    ("HeadTop_End", *_both(("{s}Shoulder",), "Left", "Right"),
     *_both(tuple(f"{{s}}Hand{f}{k}" for f in _FINGERS for k in (1, 2, 3, 4)), "Left", "Right")),
    namespace=r"mixamorig\d*",
)

UNREAL_FAMILY = Family(
    _sided({
        "root": ("pelvis",), "spine": ("spine_01",), "chest": ("spine_05", "spine_04", "spine_03"),
        "neck": ("neck_01",), "head": ("head",), "l_shoulder": ("upperarm_{s}",),
        "l_elbow": ("lowerarm_{s}",), "l_wrist": ("hand_{s}",),
        "l_handtip": ("middle_03_{s}/end", "index_03_{s}/end", "hand_{s}/end"),
        "l_hip": ("thigh_{s}",), "l_knee": ("calf_{s}",), "l_ankle": ("foot_{s}",),
        "l_toe": ("ball_{s}/end",),
    }, "l", "r"),
    ("root", "spine_02", "neck_02", "ik_foot_root", "ik_hand_root",
     *_both(("clavicle_{s}", "upperarm_twist_01_{s}", "upperarm_twist_02_{s}",
             "lowerarm_twist_01_{s}", "lowerarm_twist_02_{s}", "thigh_twist_01_{s}",
             "thigh_twist_02_{s}", "calf_twist_01_{s}", "calf_twist_02_{s}", "ik_foot_{s}",
             *(f"{f.lower()}_0{k}_{{s}}" for f in _FINGERS for k in (1, 2, 3)),
             *(f"{f.lower()}_metacarpal_{{s}}" for f in _FINGERS[1:])), "l", "r")),
)


def _humanoid(camel: bool) -> Family:
    def n(name: str) -> str:
        return name[0].lower() + name[1:] if camel else name

    roles = _sided({
        "root": (n("Hips"),), "spine": (n("Spine"),), "chest": (n("UpperChest"), n("Chest")),
        "neck": (n("Neck"),), "head": (n("Head"),), "l_shoulder": (n("{s}UpperArm"),),
        "l_elbow": (n("{s}LowerArm"),), "l_wrist": (n("{s}Hand"),),
        "l_handtip": (n("{s}MiddleDistal/end"), n("{s}IndexDistal/end"), n("{s}Hand/end")),
        "l_hip": (n("{s}UpperLeg"),), "l_knee": (n("{s}LowerLeg"),), "l_ankle": (n("{s}Foot"),),
        "l_toe": (n("{s}Toes/end"), n("{s}Foot/end")),
    }, "Left", "Right")
    parts = ("Metacarpal", "Proximal", "Intermediate", "Distal")
    known = _both((n("{s}Shoulder"), n("{s}Eye"),
                   *(n(f"{{s}}{f}{p}") for f in _FINGERS for p in parts)), "Left", "Right")
    return Family(roles, (n("Jaw"), *known))


UNITY_FAMILY = _humanoid(camel=False)
VRM_FAMILY = _humanoid(camel=True)


def _smpl(hands: bool) -> Family:
    """SMPL or SMPL-X joint names (``left_hip``; BVH exports also write ``L_Hip``)."""
    roles = _sided({
        "root": ("pelvis",), "spine": ("spine1",), "chest": ("spine3", "spine2"),
        "neck": ("neck",), "head": ("head",), "l_shoulder": ("{s}_shoulder", "{t}_Shoulder"),
        "l_elbow": ("{s}_elbow", "{t}_Elbow"), "l_wrist": ("{s}_wrist", "{t}_Wrist"),
        "l_handtip": ("{s}_hand/end", "{s}_middle3/end", "{s}_index3/end", "{t}_Hand/end",
                      "{s}_wrist/end", "{t}_Wrist/end"),
        "l_hip": ("{s}_hip", "{t}_Hip"), "l_knee": ("{s}_knee", "{t}_Knee"),
        "l_ankle": ("{s}_ankle", "{t}_Ankle"), "l_toe": ("{s}_foot/end", "{t}_Foot/end"),
    }, "left", "right")
    known = ("spine2", *_both(("{s}_collar",), "left", "right"), "L_Collar", "R_Collar")
    if hands:
        known += ("jaw", *_both(("{s}_eye_smplhf", "{s}_eye"), "left", "right"),
                  *_both(tuple(f"{{s}}_{f.lower()}{k}" for f in _FINGERS for k in (1, 2, 3)),
                         "left", "right"))
    return Family(roles, known)


#: Every family by name, in the order they are tried (ties go to the earlier one).
FAMILIES: dict[str, Family] = {
    "bandai": BANDAI_FAMILY, "cmu": CMU_FAMILY, "mixamo": MIXAMO_FAMILY,
    "unreal": UNREAL_FAMILY, "unity": UNITY_FAMILY, "vrm": VRM_FAMILY,
    "smpl": _smpl(hands=False), "smplx": _smpl(hands=True),
}
