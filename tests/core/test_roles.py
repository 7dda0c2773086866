"""Tests for emotive.core.roles."""

from __future__ import annotations

import json

import numpy as np
import pytest

from emotive.core.roles import BANDAI, CMU, ROLES, load_role_map, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

# The Bandai Namco rig (both data sets share it), in metres, with its five zero end sites.
BANDAI_JOINTS = [
    ("joint_Root", None, (0, 0, 0)),
    ("Hips", "joint_Root", (0.0459, 0.9149, -4.2724)),
    ("Spine", "Hips", (0.1574, 0, 0)),
    ("Chest", "Spine", (0.0898, -0.0041, 0)),
    ("Neck", "Chest", (0.1638, 0, 0)),
    ("Head", "Neck", (0.0646, 0, 0)),
    ("Shoulder_L", "Chest", (0.1299, -0.0024, 0.0498)),
    ("UpperArm_L", "Shoulder_L", (0.0535, 0, 0)),
    ("LowerArm_L", "UpperArm_L", (0.2433, 0, 0)),
    ("Hand_L", "LowerArm_L", (0.2229, 0, 0)),
    ("Shoulder_R", "Chest", (0.1299, -0.0024, -0.0498)),
    ("UpperArm_R", "Shoulder_R", (-0.0535, 0, 0)),
    ("LowerArm_R", "UpperArm_R", (-0.2433, 0, 0)),
    ("Hand_R", "LowerArm_R", (-0.2229, 0, 0)),
    ("UpperLeg_L", "Hips", (-0.0219, -0.0647, 0)),
    ("LowerLeg_L", "UpperLeg_L", (0.3908, 0, 0)),
    ("Foot_L", "LowerLeg_L", (0.4099, 0, 0)),
    ("Toes_L", "Foot_L", (0.1175, 0, 0)),
    ("UpperLeg_R", "Hips", (-0.0219, 0.0647, 0)),
    ("LowerLeg_R", "UpperLeg_R", (-0.3908, 0, 0)),
    ("Foot_R", "LowerLeg_R", (-0.4099, 0, 0)),
    ("Toes_R", "Foot_R", (-0.1175, 0, 0)),
]
BANDAI_ENDS = ["Head", "Hand_L", "Hand_R", "Toes_L", "Toes_R"]

CMU_JOINTS = [
    ("Hips", None), ("LeftUpLeg", "Hips"), ("LeftLeg", "LeftUpLeg"), ("LeftFoot", "LeftLeg"),
    ("LeftToeBase", "LeftFoot"), ("RightUpLeg", "Hips"), ("RightLeg", "RightUpLeg"),
    ("RightFoot", "RightLeg"), ("RightToeBase", "RightFoot"), ("Spine", "Hips"),
    ("Spine1", "Spine"), ("Neck", "Spine1"), ("Head", "Neck"), ("LeftShoulder", "Spine1"),
    ("LeftArm", "LeftShoulder"), ("LeftForeArm", "LeftArm"), ("LeftHand", "LeftForeArm"),
    ("RightShoulder", "Spine1"), ("RightArm", "RightShoulder"),
    ("RightForeArm", "RightArm"), ("RightHand", "RightForeArm"),
]


def build(joints, ends=()) -> Skeleton:
    names = tuple(j[0] for j in joints)
    parents = [names.index(j[1]) if j[1] else -1 for j in joints]
    offsets = [j[2] if len(j) > 2 else (0.0, 0.1, 0.0) for j in joints]
    esp = [names.index(e) for e in ends]
    return Skeleton(names, parents, offsets, (), esp, np.zeros((len(esp), 3)))


class TestResolveRoles:
    def test_bandai(self):
        sk = build(BANDAI_JOINTS, BANDAI_ENDS)
        roles = resolve_roles(sk)
        assert roles.map_name == "bandai"
        assert set(roles.index) == set(ROLES)
        assert roles.names["root"] == "Hips" and roles.index["root"] == sk.index("Hips")
        assert roles.index["l_hip"] == sk.index("UpperLeg_L")
        # Toe and hand tips are end sites: indices past the joints, in end-site order.
        j = sk.num_joints
        assert roles.index["l_toe"] == j + BANDAI_ENDS.index("Toes_L")
        assert roles.index["r_handtip"] == j + BANDAI_ENDS.index("Hand_R")
        assert roles.names["l_toe"] == "Toes_L/end"
        assert roles.indices().shape == (len(ROLES),)
        np.testing.assert_array_equal(roles.indices(("root", "head")), [1, 5])

    def test_bandai_by_name_and_end_site_fallback(self):
        # Without end sites, "Toes_L/end" resolves to the joint itself.
        roles = resolve_roles(build(BANDAI_JOINTS), "bandai")
        assert roles.index["l_toe"] == [j[0] for j in BANDAI_JOINTS].index("Toes_L")

    def test_cmu(self):
        sk = build(CMU_JOINTS)
        roles = resolve_roles(sk)
        assert roles.map_name == "cmu"
        assert roles.names["chest"] == "Spine1"
        # CMU rigs without finger joints fall back to the wrists.
        assert roles.index["l_handtip"] == sk.index("LeftHand")
        assert roles.index["r_toe"] == sk.index("RightToeBase")

    def test_chest_fallback(self):
        sk = build([(n, "Spine" if p == "Spine1" else p) for n, p in CMU_JOINTS if n != "Spine1"])
        roles = resolve_roles(sk, "cmu")
        assert roles.index["chest"] == roles.index["spine"]

    def test_user_json_map(self, tmp_path):
        # Names no family knows (a prefix shared by every joint would be ignored), on a rest
        # pose that does not tell left from right: neither names nor shape resolve it.
        renamed = {old: f"bone{k:02d}" for k, (old, _) in enumerate(CMU_JOINTS)}
        sk = build([(renamed[n], renamed[p] if p else None) for n, p in CMU_JOINTS])
        mapping = {}
        for role in ROLES:
            joint, _, end = CMU[role].partition("/")
            if joint in renamed:
                mapping[role] = renamed[joint] + ("/end" if end else "")
        path = tmp_path / "roles.json"
        path.write_text(json.dumps(mapping))
        with pytest.raises(RigError):
            resolve_roles(sk)
        roles = resolve_roles(sk, path)
        assert roles.map_name == str(path)
        assert roles.names["l_wrist"] == renamed["LeftHand"]
        assert resolve_roles(sk, mapping).map_name == "user"

    def test_missing_roles_listed(self):
        joints = [j for j in CMU_JOINTS if not j[0].startswith("Left")]
        with pytest.raises(RigError) as err:
            resolve_roles(build(joints))
        msg = str(err.value)
        for role in ("l_shoulder", "l_hip", "l_ankle", "l_toe"):
            assert role in msg
        assert "r_hip" not in msg
        assert "closest map: cmu" in msg and "JSON role map" in msg


class TestLoadRoleMap:
    def test_round_trip(self, tmp_path):
        path = tmp_path / "m.json"
        path.write_text(json.dumps(BANDAI))
        assert load_role_map(path) == BANDAI

    @pytest.mark.parametrize(
        ("text", "match"),
        [
            ("{not json", "not valid JSON"),
            ("[1, 2]", "must be a JSON object"),
            ('{"root": 3}', "must be a JSON object"),
            ('{"tail": "Tail"}', "unknown roles"),
        ],
    )
    def test_invalid(self, tmp_path, text, match):
        path = tmp_path / "m.json"
        path.write_text(text)
        with pytest.raises(RigError, match=match):
            load_role_map(path)

    def test_missing_file(self, tmp_path):
        with pytest.raises(RigError, match="does not exist"):
            load_role_map(tmp_path / "nope.json")
