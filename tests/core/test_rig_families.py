"""Rig-family detection of :mod:`emotive.core.roles`: names, prefixes, shape, bad rigs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from emotive.core import Skeleton
from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.core.roles import (
    ROLES,
    TEMPLATE_COMMAND,
    load_role_map,
    resolve_roles,
    role_template,
)
from emotive.errors import RigError
from layout_clips import bandai_clip, synthetic_clip

#: The family each layout is detected as (both CMU variants are CMU).
FAMILY = {layout: layout for layout in LAYOUTS} | {"cmu-plain": "cmu"}
PREFIXES = (None, "mixamorig1:", "Armature|mixamorig:", "Character1_", "Bip01 ")
#: Roles laid on extra tip bones (fingers, toe ends) whose place depends on the layout.
TIPS = ("l_handtip", "r_handtip", "l_toe", "r_toe")


def role_points(motion, roles, which=ROLES) -> np.ndarray:
    """``(T, R, 3)`` world positions of the given roles."""
    return motion.positions_with_end_sites()[:, roles.indices(which)]


def scrambled(skeleton: Skeleton) -> Skeleton:
    """The same rig with names no family knows."""
    return Skeleton(tuple(f"bone{k:03d}" for k in range(skeleton.num_joints)), skeleton.parents,
                    skeleton.offsets, skeleton.channels, skeleton.end_site_parents,
                    skeleton.end_site_offsets)


@pytest.fixture(scope="module")
def source():
    clip = synthetic_clip()
    return clip, role_points(clip, resolve_roles(clip.skeleton))


@pytest.mark.parametrize("prefix", PREFIXES)
@pytest.mark.parametrize("layout", LAYOUTS)
def test_every_family_is_detected_by_name(source, layout, prefix):
    clip, expected = source
    motion = to_layout(clip, layout, prefix=prefix)
    roles = resolve_roles(motion.skeleton)
    assert roles.map_name == FAMILY[layout] == roles.family
    # The roles land on the Bandai rig's points: features see the same body.
    np.testing.assert_allclose(role_points(motion, roles), expected, atol=1e-6)
    played = {n.removesuffix("/end") for n in roles.names.values()}
    assert set(roles.extras) == set(motion.skeleton.names) - played
    assert len(roles.extras) >= 3


@pytest.mark.parametrize("layout", LAYOUTS)
def test_a_family_named_with_roles(layout):
    motion = to_layout(synthetic_clip(frames=2), layout)
    assert resolve_roles(motion.skeleton, FAMILY[layout]).map_name == FAMILY[layout]


def test_real_clips_on_every_layout(bandai1_dir):
    clip = bandai_clip(bandai1_dir, frames=10)
    body = tuple(r for r in ROLES if r not in TIPS)
    expected = role_points(clip, resolve_roles(clip.skeleton), body)
    for layout in LAYOUTS:
        motion = to_layout(clip, layout)
        roles = resolve_roles(motion.skeleton)
        assert roles.map_name == FAMILY[layout], layout
        np.testing.assert_allclose(role_points(motion, roles, body), expected, atol=1e-6)


@pytest.mark.parametrize("layout", [*LAYOUTS, "bandai"])
def test_shape_alone_finds_every_role(source, layout):
    clip, expected = source
    motion = clip if layout == "bandai" else to_layout(clip, layout)
    named = resolve_roles(motion.skeleton)
    roles = resolve_roles(scrambled(motion.skeleton))
    assert roles.map_name == "topology"
    np.testing.assert_allclose(role_points(motion, roles), role_points(motion, named), atol=1e-6)
    np.testing.assert_allclose(role_points(motion, roles), expected, atol=1e-6)


def t_pose(skeleton: Skeleton) -> Skeleton:
    """The rig with its arms held out sideways (a T-pose rest)."""
    offsets = skeleton.offsets.copy()
    for side, sign in (("L", 1.0), ("R", -1.0)):
        for name in (f"LowerArm_{side}", f"Hand_{side}"):
            j = skeleton.index(name)
            offsets[j] = (sign * np.linalg.norm(offsets[j]), 0.0, 0.0)
    ends = skeleton.end_site_offsets.copy()
    for e, p in enumerate(skeleton.end_site_parents):
        if skeleton.names[p].startswith("Hand_"):
            ends[e] = (np.sign(offsets[p][0]) * np.linalg.norm(ends[e]), 0.0, 0.0)
    return Skeleton(skeleton.names, skeleton.parents, offsets, skeleton.channels,
                    skeleton.end_site_parents, ends)


def test_shape_of_a_t_pose_tells_left_from_right():
    sk = t_pose(synthetic_clip(frames=1).skeleton)
    roles = resolve_roles(scrambled(sk))
    for role, joint in (("l_wrist", "Hand_L"), ("r_elbow", "LowerArm_R"), ("l_knee", "LowerLeg_L"),
                        ("r_toe", "Toes_R"), ("head", "Head"), ("chest", "Chest")):
        k = roles.index[role]
        k = k if k < sk.num_joints else int(sk.end_site_parents[k - sk.num_joints])
        assert sk.names[k] == joint, role


def without(skeleton: Skeleton, drop: set[str]) -> Skeleton:
    """The rig without the joints in ``drop`` and everything below them."""
    keep = [j for j in range(skeleton.num_joints)]
    for j in range(skeleton.num_joints):
        p = skeleton.parents[j]
        if skeleton.names[j] in drop or (p >= 0 and p not in keep):
            keep.remove(j)
    new = {old: k for k, old in enumerate(keep)}
    ends = [e for e, p in enumerate(skeleton.end_site_parents) if p in new]
    return Skeleton(
        tuple(skeleton.names[j] for j in keep),
        [new[skeleton.parents[j]] if skeleton.parents[j] >= 0 else -1 for j in keep],
        skeleton.offsets[keep], tuple(skeleton.channels[j] for j in keep),
        [new[skeleton.end_site_parents[e]] for e in ends], skeleton.end_site_offsets[ends],
    )


def test_missing_roles_name_the_template_command():
    sk = without(to_layout(synthetic_clip(frames=1), "mixamo").skeleton, {"mixamorig:LeftArm"})
    with pytest.raises(RigError) as err:
        resolve_roles(sk)
    message = str(err.value)
    assert "\n" not in message and TEMPLATE_COMMAND in message
    assert all(r in message for r in ("l_shoulder", "l_elbow", "l_wrist"))
    assert "r_wrist" not in message and "closest map: mixamo" in message


def chain(names, offsets, ends=()) -> Skeleton:
    """A rig from ``(name, parent name)`` pairs and offsets."""
    order = [n for n, _ in names]
    parents = [order.index(p) if p else -1 for _, p in names]
    return Skeleton(tuple(order), parents, offsets, (), [order.index(e) for e, _ in ends],
                    np.array([o for _, o in ends]).reshape(-1, 3))


def quadruped() -> Skeleton:
    """Hind legs at the pelvis, front legs as long at the chest, a neck and head, no arms."""
    joints, offsets = [("pelvis", None), ("back", "pelvis"), ("withers", "back"),
                       ("neck", "withers"), ("skull", "neck")], [
        (0, 0.6, 0), (0, 0, 0.3), (0, 0, 0.3), (0, 0.2, 0.2), (0, 0.1, 0.15)]
    for hub, tag in (("pelvis", "hind"), ("withers", "fore")):
        for side, x in (("a", 0.12), ("b", -0.12)):
            joints += [(f"{tag}{side}1", hub), (f"{tag}{side}2", f"{tag}{side}1"),
                       (f"{tag}{side}3", f"{tag}{side}2"), (f"{tag}{side}4", f"{tag}{side}3")]
            offsets += [(x, 0, 0), (0, -0.25, 0), (0, -0.25, 0), (0, -0.08, 0.05)]
    return chain(joints, offsets)


@pytest.mark.parametrize(("rig", "words"), [
    (chain([("a", None), ("b", "a"), ("c", "b")], [(0, 1, 0), (0, 0.5, 0), (0, 0.5, 0)]),
     "no joint where two legs and a spine meet"),
    (quadruped(), "four legs and no arms"),
])
def test_non_humanoids_are_refused(rig, words):
    with pytest.raises(RigError) as err:
        resolve_roles(rig)
    message = str(err.value)
    assert "is not a humanoid" in message and words in message and "\n" not in message


def test_role_template_round_trip(tmp_path):
    sk = scrambled(to_layout(synthetic_clip(frames=1), "unreal").skeleton)
    template = role_template(sk)
    assert list(template) == list(ROLES) and all(template.values())
    path = tmp_path / "roles.json"
    path.write_text(json.dumps(template))
    roles = resolve_roles(sk, path)
    assert roles.index == resolve_roles(sk).index


def test_role_template_leaves_missing_roles_empty(tmp_path):
    sk = without(synthetic_clip(frames=1).skeleton, {"Head"})
    template = role_template(sk, "bandai")
    assert template["head"] is None and template["neck"] == "Neck"
    template["head"] = "Neck"
    path = tmp_path / "roles.json"
    path.write_text(json.dumps(template | {"l_toe": ""}))
    assert "l_toe" not in load_role_map(path)
    with pytest.raises(RigError, match="l_toe"):
        resolve_roles(sk, path)
    path.write_text(json.dumps(template))
    assert resolve_roles(sk, path).names["head"] == "Neck"


def test_smpl_as_bvh_exporters_capitalize_it(source):
    clip, expected = source
    motion = to_layout(clip, "smpl")
    sk = motion.skeleton

    def capital(name: str) -> str:
        for side in ("left", "right"):
            if name.startswith(side + "_"):
                return f"{side[0].upper()}_{name[len(side) + 1:].capitalize()}"
        return name.capitalize()

    rig = Skeleton(tuple(map(capital, sk.names)), sk.parents, sk.offsets, sk.channels,
                   sk.end_site_parents, sk.end_site_offsets)
    roles = resolve_roles(rig)
    assert roles.map_name == "smpl" and roles.names["l_knee"] == "L_Knee"
    np.testing.assert_allclose(role_points(motion, roles), expected, atol=1e-6)
