"""Exact relayouts of a Bandai-rig clip onto the joint layouts of other rig families.

:func:`to_layout` re-expresses a clip on the Bandai Namco rig (``joint_Root``, ``Hips``,
``Spine``, ``Chest``, ``Neck``, ``Head``, ``Shoulder_L``, ``UpperArm_L``, ``LowerArm_L``,
``Hand_L``, ``UpperLeg_L``, ``LowerLeg_L``, ``Foot_L``, ``Toes_L`` and the ``_R`` side) on the
layout of another family (:data:`LAYOUTS`) without changing the pose: every joint that has a
counterpart on the Bandai rig keeps its world position and world rotation in every frame.

- Inserted joints split a bone: they sit on the segment from a Bandai joint to one of its
  children, with the local rotation of the identity, so the bone's offset is shared between
  them (CMU's ``LowerBack``, Unreal's ``spine_02``..``spine_04``, ``neck_02``, ...). The
  Bandai ``Chest`` (the shoulders' parent) becomes the joint each family hangs the clavicles
  from (Unreal ``spine_05``, Unity ``UpperChest``, SMPL ``spine3``), so the roles of
  :mod:`emotive.core.roles` land on the same points as on the Bandai rig.
- Extra leaf bones (fingers, twist and helper bones, ``HeadTop_End``-like ends, eyes) carry
  the identity local rotation; they are laid along the bone they hang from or along the
  parent's end site, with a small sideways spread for thumbs and eyes.
- Each layout has its own joint names, rotation channel order (``Skeleton.channels``, so
  :func:`emotive.io.bvh.write_bvh` writes in that order) and file unit
  (``metadata["file_unit"]``, e.g. inches for Mixamo, CMU's ASF unit for CMU).

It is test-fixture machinery (other rigs built by the project's own code from real clips) and
also a way to export a clip onto a named layout. Clips lacking ``joint_Root`` or the
``Shoulder_*`` joints (small synthetic rigs) are accepted: a missing ``joint_Root`` becomes a
root at the origin, a missing shoulder a joint inserted on the chest-to-upper-arm bone.

Shapes: ``T`` frames, ``J`` source joints, ``K`` target joints. Lengths are in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import POSITION_CHANNELS, Skeleton
from emotive.errors import RigError
from emotive.transforms.fast_np import CONJUGATE, qapply, qmul
from emotive.transforms.kinematics import forward_kinematics_np

#: Local translations that vary less than this over the clip (metres) are written as
#: constant offsets; more, and the joint gets position channels.
_STATIC_TOL_M = 1e-7
#: Bandai end sites have zero offsets; an ``X/end`` reference then stands for the joint's own
#: bone continued by this factor (a hand about 0.8 forearms, a head top 2.5 necks up).
_END_FALLBACK = {"Head": 2.5, "Hand_L": 0.8, "Hand_R": 0.8, "Toes_L": 0.5, "Toes_R": 0.5}
_TINY_M = 1e-6
_SIDES = (("L", 1.0), ("R", -1.0))


@dataclass(frozen=True)
class Along:
    """A point laid along a Bandai bone, in the frame of the joint the bone starts from.

    Attributes:
        ref: a Bandai joint (its offset from its parent, in the parent's frame) or
            ``"Name/end"`` (the joint's end-site offset, in its own frame).
        frac: the fraction of that vector.
        side: a sideways component, in lengths of the vector, along the rig's left-right axis
            (positive towards the character's left).
    """

    ref: str
    frac: float
    side: float = 0.0


#: A target joint at the Bandai rig's origin with the identity rotation (a missing root).
ORIGIN = "<origin>"


@dataclass(frozen=True)
class JointSpec:
    """One joint of a layout.

    Attributes:
        name: the joint's name on the layout (before any prefix).
        parent: the parent's layout name, ``None`` for the root.
        source: the Bandai joint it stands for, an :class:`Along` point for an inserted or
            extra joint, or :data:`ORIGIN`.
        end: the joint's end site: ``None`` (none), ``"src"`` (the Bandai joint's end sites)
            or an :class:`Along` offset in the joint's frame.
    """

    name: str
    parent: str | None
    source: str | Along
    end: str | Along | None = None


@dataclass(frozen=True)
class Layout:
    """A rig family's joint layout.

    Attributes:
        joints: the joints in topological order.
        rotation_order: Euler order of every joint's rotation channels (``"ZYX"``).
        file_unit: the unit files of this family are written in (a key of
            :data:`emotive.io.bvh_limits.UNITS`).
        prefix: the namespace put before every joint name by default (``"mixamorig:"``).
    """

    joints: tuple[JointSpec, ...]
    rotation_order: str
    file_unit: str
    prefix: str = ""


def _finger(names: tuple[str, ...], parent: str, hand: str, fracs: tuple[float, ...],
            side: float) -> list[JointSpec]:
    """A finger chain along ``hand``'s end site; the last fraction is its end site."""
    out, up = [], parent
    for k, name in enumerate(names):
        s = side if k == 0 else 0.0
        end = Along(f"{hand}/end", fracs[-1]) if k == len(names) - 1 else None
        out.append(JointSpec(name, up, Along(f"{hand}/end", fracs[k], s), end))
        up = name
    return out


def _cmu(full: bool) -> tuple[JointSpec, ...]:
    J = JointSpec
    out = [J("Hips", None, "Hips")]
    for b, _ in _SIDES:
        side = "Left" if b == "L" else "Right"
        up = "Hips"
        if full:
            out.append(J(f"{b}HipJoint", "Hips", Along(f"UpperLeg_{b}", 0.5)))
            up = f"{b}HipJoint"
        out += [J(f"{side}UpLeg", up, f"UpperLeg_{b}"), J(f"{side}Leg", f"{side}UpLeg",
                f"LowerLeg_{b}"), J(f"{side}Foot", f"{side}Leg", f"Foot_{b}"),
                J(f"{side}ToeBase", f"{side}Foot", f"Toes_{b}", "src")]
    if full:
        out.append(J("LowerBack", "Hips", Along("Spine", 0.5)))
    out += [J("Spine", "LowerBack" if full else "Hips", "Spine"), J("Spine1", "Spine", "Chest"),
            J("Neck", "Spine1", "Neck")]
    if full:
        out.append(J("Neck1", "Neck", Along("Head", 0.5)))
    out.append(J("Head", "Neck1" if full else "Neck", "Head", "src"))
    for b, s in _SIDES:
        side = "Left" if b == "L" else "Right"
        hand = f"Hand_{b}"
        out += [J(f"{side}Shoulder", "Spine1", f"Shoulder_{b}"),
                J(f"{side}Arm", f"{side}Shoulder", f"UpperArm_{b}"),
                J(f"{side}ForeArm", f"{side}Arm", f"LowerArm_{b}"),
                J(f"{side}Hand", f"{side}ForeArm", hand),
                J(f"{side}FingerBase", f"{side}Hand", Along(f"{hand}/end", 0.55)),
                J(f"{side}HandIndex1", f"{side}FingerBase", Along(f"{hand}/end", 0.25),
                  Along(f"{hand}/end", 0.2)),
                J(f"{b}Thumb", f"{side}Hand", Along(f"{hand}/end", 0.3, -0.3 * s),
                  Along(f"{hand}/end", 0.2))]
    return tuple(out)


def _mixamo() -> tuple[JointSpec, ...]:
    J = JointSpec
    out = [J("Hips", None, "Hips"), J("Spine", "Hips", "Spine"),
           J("Spine1", "Spine", Along("Chest", 0.5)), J("Spine2", "Spine1", "Chest"),
           J("Neck", "Spine2", "Neck"), J("Head", "Neck", "Head"),
           J("HeadTop_End", "Head", Along("Head/end", 1.0), Along("Head/end", 0.05))]
    for b, s in _SIDES:
        side = "Left" if b == "L" else "Right"
        hand = f"Hand_{b}"
        out += [J(f"{side}Shoulder", "Spine2", f"Shoulder_{b}"),
                J(f"{side}Arm", f"{side}Shoulder", f"UpperArm_{b}"),
                J(f"{side}ForeArm", f"{side}Arm", f"LowerArm_{b}"),
                J(f"{side}Hand", f"{side}ForeArm", hand)]
        out += _finger(tuple(f"{side}HandThumb{k}" for k in (1, 2, 3)), f"{side}Hand", hand,
                       (0.25, 0.2, 0.15, 0.1), -0.3 * s)
        out += _finger(tuple(f"{side}HandIndex{k}" for k in (1, 2, 3)), f"{side}Hand", hand,
                       (0.5, 0.2, 0.15, 0.15), 0.0)
    for b, _ in _SIDES:
        side = "Left" if b == "L" else "Right"
        out += [J(f"{side}UpLeg", "Hips", f"UpperLeg_{b}"),
                J(f"{side}Leg", f"{side}UpLeg", f"LowerLeg_{b}"),
                J(f"{side}Foot", f"{side}Leg", f"Foot_{b}"),
                J(f"{side}ToeBase", f"{side}Foot", f"Toes_{b}"),
                J(f"{side}Toe_End", f"{side}ToeBase", Along(f"Toes_{b}/end", 1.0),
                  Along(f"Toes_{b}/end", 0.1))]
    return tuple(out)


def _unreal() -> tuple[JointSpec, ...]:
    J = JointSpec
    out = [J("root", None, "joint_Root"), J("pelvis", "root", "Hips"),
           J("spine_01", "pelvis", "Spine"), J("spine_02", "spine_01", Along("Chest", 0.25)),
           J("spine_03", "spine_02", Along("Chest", 0.25)),
           J("spine_04", "spine_03", Along("Chest", 0.25)),
           J("spine_05", "spine_04", "Chest"), J("neck_01", "spine_05", "Neck"),
           J("neck_02", "neck_01", Along("Head", 0.5)), J("head", "neck_02", "Head", "src")]
    for b, s in _SIDES:
        x, hand = b.lower(), f"Hand_{b}"
        out += [J(f"clavicle_{x}", "spine_05", f"Shoulder_{b}"),
                J(f"upperarm_{x}", f"clavicle_{x}", f"UpperArm_{b}"),
                J(f"upperarm_twist_01_{x}", f"upperarm_{x}", Along(f"LowerArm_{b}", 0.5),
                  Along(f"LowerArm_{b}", 0.1)),
                J(f"lowerarm_{x}", f"upperarm_{x}", f"LowerArm_{b}"),
                J(f"lowerarm_twist_01_{x}", f"lowerarm_{x}", Along(hand, 0.5),
                  Along(hand, 0.1)),
                J(f"hand_{x}", f"lowerarm_{x}", hand)]
        out += _finger(tuple(f"thumb_0{k}_{x}" for k in (1, 2, 3)), f"hand_{x}", hand,
                       (0.25, 0.2, 0.15, 0.1), -0.3 * s)
        out += _finger(tuple(f"index_0{k}_{x}" for k in (1, 2, 3)), f"hand_{x}", hand,
                       (0.45, 0.25, 0.15, 0.15), 0.0)
    for b, _ in _SIDES:
        x = b.lower()
        out += [J(f"thigh_{x}", "pelvis", f"UpperLeg_{b}"),
                J(f"thigh_twist_01_{x}", f"thigh_{x}", Along(f"LowerLeg_{b}", 0.5),
                  Along(f"LowerLeg_{b}", 0.1)),
                J(f"calf_{x}", f"thigh_{x}", f"LowerLeg_{b}"),
                J(f"calf_twist_01_{x}", f"calf_{x}", Along(f"Foot_{b}", 0.5),
                  Along(f"Foot_{b}", 0.1)),
                J(f"foot_{x}", f"calf_{x}", f"Foot_{b}"),
                J(f"ball_{x}", f"foot_{x}", f"Toes_{b}", "src")]
    return tuple(out)


def _humanoid(camel: bool) -> tuple[JointSpec, ...]:
    """Unity humanoid (``camel=False``: ``LeftUpperArm``) or VRM (``leftUpperArm``) names."""
    def n(name: str) -> str:
        return name[0].lower() + name[1:] if camel else name

    J = JointSpec
    out = [J(n("Hips"), None, "Hips"), J(n("Spine"), n("Hips"), "Spine"),
           J(n("Chest"), n("Spine"), Along("Chest", 0.5)),
           J(n("UpperChest"), n("Chest"), "Chest"),
           J(n("Neck"), n("UpperChest"), "Neck"), J(n("Head"), n("Neck"), "Head", "src")]
    for b, s in _SIDES:
        side, hand = ("Left" if b == "L" else "Right"), f"Hand_{b}"
        if camel:
            out.append(J(n(f"{side}Eye"), n("Head"), Along("Head/end", 0.5, 0.25 * s),
                         Along("Head/end", 0.1)))
        thumb = ("Metacarpal", "Proximal", "Distal") if camel else (
            "Proximal", "Intermediate", "Distal")
        out += [J(n(f"{side}Shoulder"), n("UpperChest"), f"Shoulder_{b}"),
                J(n(f"{side}UpperArm"), n(f"{side}Shoulder"), f"UpperArm_{b}"),
                J(n(f"{side}LowerArm"), n(f"{side}UpperArm"), f"LowerArm_{b}"),
                J(n(f"{side}Hand"), n(f"{side}LowerArm"), hand)]
        out += _finger(tuple(n(f"{side}Thumb{p}") for p in thumb), n(f"{side}Hand"), hand,
                       (0.25, 0.2, 0.15, 0.1), -0.3 * s)
        out += _finger(tuple(n(f"{side}Index{p}") for p in ("Proximal", "Intermediate",
                                                          "Distal")),
                       n(f"{side}Hand"), hand, (0.45, 0.25, 0.15, 0.15), 0.0)
    for b, _ in _SIDES:
        side = "Left" if b == "L" else "Right"
        out += [J(n(f"{side}UpperLeg"), n("Hips"), f"UpperLeg_{b}"),
                J(n(f"{side}LowerLeg"), n(f"{side}UpperLeg"), f"LowerLeg_{b}"),
                J(n(f"{side}Foot"), n(f"{side}LowerLeg"), f"Foot_{b}"),
                J(n(f"{side}Toes"), n(f"{side}Foot"), f"Toes_{b}", "src")]
    return tuple(out)


#: SMPL-X finger chains: (name, fractions of the hand's end site, sideways spread).
_SMPLX_FINGERS = (
    ("index", (0.4, 0.2, 0.15, 0.15), 0.1), ("middle", (0.45, 0.25, 0.15, 0.15), 0.0),
    ("pinky", (0.35, 0.15, 0.1, 0.1), -0.2), ("ring", (0.4, 0.2, 0.15, 0.1), -0.1),
    ("thumb", (0.2, 0.2, 0.15, 0.1), 0.35),
)


def _smpl(hands: bool) -> tuple[JointSpec, ...]:
    """SMPL (``hands=False``: 24 joints in SMPL's order) or SMPL-X (jaw, eyes, fingers)."""
    J = JointSpec
    sides = (("left", "L"), ("right", "R"))
    out = [J("pelvis", None, "Hips")]
    out += [J(f"{s}_hip", "pelvis", f"UpperLeg_{b}") for s, b in sides]
    out.append(J("spine1", "pelvis", "Spine"))
    out += [J(f"{s}_knee", f"{s}_hip", f"LowerLeg_{b}") for s, b in sides]
    out.append(J("spine2", "spine1", Along("Chest", 0.5)))
    out += [J(f"{s}_ankle", f"{s}_knee", f"Foot_{b}") for s, b in sides]
    out.append(J("spine3", "spine2", "Chest"))
    out += [J(f"{s}_foot", f"{s}_ankle", f"Toes_{b}", "src") for s, b in sides]
    out.append(J("neck", "spine3", "Neck"))
    out += [J(f"{s}_collar", "spine3", f"Shoulder_{b}") for s, b in sides]
    out.append(J("head", "neck", "Head", None if hands else "src"))
    out += [J(f"{s}_shoulder", f"{s}_collar", f"UpperArm_{b}") for s, b in sides]
    out += [J(f"{s}_elbow", f"{s}_shoulder", f"LowerArm_{b}") for s, b in sides]
    out += [J(f"{s}_wrist", f"{s}_elbow", f"Hand_{b}") for s, b in sides]
    if not hands:
        out += [J(f"{s}_hand", f"{s}_wrist", Along(f"Hand_{b}/end", 0.6),
                  Along(f"Hand_{b}/end", 0.4)) for s, b in sides]
        return tuple(out)
    out += [J("jaw", "head", Along("Head/end", 0.2), Along("Head/end", 0.1)),
            J("left_eye_smplhf", "head", Along("Head/end", 0.5, 0.25), Along("Head/end", 0.1)),
            J("right_eye_smplhf", "head", Along("Head/end", 0.5, -0.25),
              Along("Head/end", 0.1))]
    for (s, b), sign in zip(sides, (1.0, -1.0), strict=True):
        for finger, fracs, spread in _SMPLX_FINGERS:
            out += _finger(tuple(f"{s}_{finger}{k}" for k in (1, 2, 3)), f"{s}_wrist",
                           f"Hand_{b}", fracs, spread * sign)
    return tuple(out)


def _depth_first(joints: tuple[JointSpec, ...]) -> tuple[JointSpec, ...]:
    """The joints in depth-first order (a BVH file's order; SMPL lists them breadth-first)."""
    kids: dict[str | None, list[JointSpec]] = {}
    for joint in joints:
        kids.setdefault(joint.parent, []).append(joint)
    out: list[JointSpec] = []
    stack = list(reversed(kids[None]))
    while stack:
        joint = stack.pop()
        out.append(joint)
        stack.extend(reversed(kids.get(joint.name, [])))
    return tuple(out)


#: Every layout by name, joints in depth-first order.
LAYOUT_TABLE: dict[str, Layout] = {
    "cmu": Layout(_cmu(full=True), "ZYX", "cmu"),
    "cmu-plain": Layout(_cmu(full=False), "ZYX", "cmu"),
    "mixamo": Layout(_mixamo(), "XYZ", "in", "mixamorig:"),
    "unreal": Layout(_unreal(), "XZY", "cm"),
    "unity": Layout(_humanoid(camel=False), "ZXY", "m"),
    "smpl": Layout(_depth_first(_smpl(hands=False)), "XYZ", "m"),
    "smplx": Layout(_depth_first(_smpl(hands=True)), "XYZ", "m"),
    "vrm": Layout(_depth_first(_humanoid(camel=True)), "YXZ", "m"),
}

#: The layout names :func:`to_layout` accepts.
LAYOUTS: tuple[str, ...] = tuple(LAYOUT_TABLE)

#: Bandai joints a source may lack, and what stands in for them.
_SUBSTITUTES: dict[str, str | Along] = {
    "joint_Root": ORIGIN,
    "Shoulder_L": Along("UpperArm_L", 0.4), "Shoulder_R": Along("UpperArm_R", 0.4),
}
_REQUIRED = (
    "Hips", "Spine", "Chest", "Neck", "Head", "UpperArm_L", "LowerArm_L", "Hand_L",
    "UpperArm_R", "LowerArm_R", "Hand_R", "UpperLeg_L", "LowerLeg_L", "Foot_L", "Toes_L",
    "UpperLeg_R", "LowerLeg_R", "Foot_R", "Toes_R",
)


class _Source:
    """The Bandai clip's world transforms and rest geometry, for building a layout."""

    def __init__(self, motion: Motion) -> None:
        sk = motion.skeleton
        missing = [n for n in _REQUIRED if n not in sk.names]
        if missing:
            name = motion.metadata.get("name", "the clip")
            raise RigError(
                f"to_layout needs a clip on the Bandai rig; {name} lacks the joints {missing}: "
                "pass a clip read from the Bandai Namco data sets"
            )
        self.skeleton = sk
        ident = np.zeros((1, sk.num_joints, 4))
        ident[..., 0] = 1.0
        # Frame 0 is the rest pose (identity rotations, rest offsets), then the clip's frames.
        self.rot, self.pos = forward_kinematics_np(
            np.concatenate((ident, motion.rotations)),
            np.concatenate((sk.offsets[None], motion.positions)), sk.parents,
        )
        rest = self.pos[0]
        lateral = rest[sk.index("UpperLeg_L")] - rest[sk.index("UpperLeg_R")]
        self.lateral = lateral / max(float(np.linalg.norm(lateral)), _TINY_M)

    def vector(self, along: Along) -> tuple[np.ndarray, int]:
        """``(3,)`` offset of an :class:`Along` point and the Bandai joint whose frame it is in."""
        sk = self.skeleton
        if along.ref.endswith("/end"):
            joint = sk.index(along.ref[: -len("/end")])
            ends = np.flatnonzero(sk.end_site_parents == joint)
            vec = sk.end_site_offsets[ends[0]] if len(ends) else np.zeros(3)
            if np.linalg.norm(vec) < _TINY_M:
                vec = sk.offsets[joint] * _END_FALLBACK.get(sk.names[joint], 0.5)
            frame = joint
        else:
            joint = sk.index(along.ref)
            vec, frame = sk.offsets[joint], int(sk.parents[joint])
        length = float(np.linalg.norm(vec))
        return along.frac * vec + along.side * length * self.lateral, frame


def _place(src: _Source, spec: JointSpec, parent: int, drivers: list[int],
           rot: list[np.ndarray], pos: list[np.ndarray]) -> None:
    """Append the world rotation, position and driving Bandai joint of one target joint."""
    source = spec.source
    if isinstance(source, str) and source not in src.skeleton.names:
        source = _SUBSTITUTES[source]
    frames = src.rot.shape[0]
    if source == ORIGIN:
        q = np.zeros((frames, 4))
        q[:, 0] = 1.0
        drivers.append(-1)
        rot.append(q)
        pos.append(np.zeros((frames, 3)))
        return
    if isinstance(source, str):
        j = src.skeleton.index(source)
        expected = int(src.skeleton.parents[j])
        if parent >= 0 and drivers[parent] != expected:
            raise AssertionError(f"layout joint {spec.name} does not hang from its Bandai parent")
        drivers.append(j)
        rot.append(src.rot[:, j])
        pos.append(src.pos[:, j])
        return
    vec, frame = src.vector(source)
    if drivers[parent] != frame:
        raise AssertionError(f"layout joint {spec.name} is not laid along its parent's bone")
    drivers.append(drivers[parent])
    rot.append(rot[parent])
    pos.append(pos[parent] + qapply(rot[parent], np.broadcast_to(vec, (frames, 3))))


def _end_sites(src: _Source, layout: Layout, drivers: list[int]) -> tuple[list[int], list]:
    """End-site parents and offsets of the target joints (in each joint's own frame)."""
    sk = src.skeleton
    parents, offsets = [], []
    for k, spec in enumerate(layout.joints):
        if spec.end == "src":
            for e in np.flatnonzero(sk.end_site_parents == drivers[k]):
                parents.append(k)
                offsets.append(sk.end_site_offsets[e])
        elif isinstance(spec.end, Along):
            vec, frame = src.vector(spec.end)
            if frame != drivers[k]:
                raise AssertionError(f"end site of {spec.name} is not laid along its bone")
            parents.append(k)
            offsets.append(vec)
    return parents, offsets


def to_layout(motion: Motion, layout: str, prefix: str | None = None) -> Motion:
    """Re-express a Bandai-rig clip on another rig family's layout, keeping the pose exactly.

    Args:
        motion: a clip on the Bandai rig (``(T, J, 4)`` rotations, ``(T, J, 3)`` positions,
            metres); ``joint_Root`` and ``Shoulder_*`` may be missing.
        layout: one of :data:`LAYOUTS`.
        prefix: put before every joint name (``"mixamorig1:"``); ``None`` for the layout's
            own (``"mixamorig:"`` for Mixamo, none for the others).

    Returns:
        The clip on the layout: ``(T, K, 4)`` rotations, ``(T, K, 3)`` positions, the same fps,
        the layout's rotation order on every joint, position channels on the root and on any
        joint whose translation the clip animates, and ``metadata`` with ``file_unit`` set to
        the family's unit and ``layout`` to its name. Joints standing for a Bandai joint have
        its world positions and rotations in every frame.

    Raises:
        RigError: ``layout`` is unknown, or the clip is not on the Bandai rig.
    """
    if layout not in LAYOUT_TABLE:
        raise RigError(f"unknown rig layout {layout!r}: choose one of {', '.join(LAYOUTS)}")
    spec = LAYOUT_TABLE[layout]
    src = _Source(motion)
    index: dict[str, int] = {}
    parents: list[int] = []
    drivers: list[int] = []
    rot: list[np.ndarray] = []
    pos: list[np.ndarray] = []
    for joint in spec.joints:
        parent = index[joint.parent] if joint.parent is not None else -1
        _place(src, joint, parent, drivers, rot, pos)
        index[joint.name] = len(parents)
        parents.append(parent)
    grot, gpos = np.stack(rot, axis=1), np.stack(pos, axis=1)
    par = np.array(parents)
    inv = grot[:, np.maximum(par, 0)] * CONJUGATE
    is_root = par < 0
    local_rot = np.where(is_root[None, :, None], grot, qmul(inv, grot))
    local_pos = np.where(is_root[None, :, None], gpos,
                         qapply(inv, gpos - gpos[:, np.maximum(par, 0)]))
    rest_pos, local_rot, local_pos = local_pos[0], local_rot[1:], local_pos[1:]
    anim = local_pos if len(local_pos) else rest_pos[None]
    mean = anim.mean(axis=0)
    moving = is_root | (np.abs(anim - mean).max(axis=(0, 2)) > _STATIC_TOL_M)
    offsets = np.where(moving[:, None], rest_pos, mean)
    positions = np.where(moving[None, :, None], local_pos, offsets)
    rot_channels = tuple(f"{axis}rotation" for axis in spec.rotation_order)
    channels = tuple((*POSITION_CHANNELS, *rot_channels) if m else rot_channels for m in moving)
    end_parents, end_offsets = _end_sites(src, spec, drivers)
    pre = spec.prefix if prefix is None else prefix
    skeleton = Skeleton(
        tuple(pre + j.name for j in spec.joints), par, offsets, channels,
        np.array(end_parents, dtype=np.int64), np.array(end_offsets).reshape(-1, 3),
    )
    metadata = {**motion.metadata, "file_unit": spec.file_unit, "layout": layout}
    return Motion(skeleton, local_rot, positions, motion.fps, metadata)
