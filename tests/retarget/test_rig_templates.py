from __future__ import annotations

import numpy as np
import pytest

from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.core.roles import resolve_roles
from emotive.errors import RigError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.retarget import rest_clip, rest_template
from emotive.retarget.rest import rest_points
from layout_clips import synthetic_clip


@pytest.fixture(scope="module")
def mixamo():
    return to_layout(synthetic_clip(), "mixamo").skeleton


def _at(skeleton, role_map=None):
    roles = resolve_roles(skeleton, role_map)
    points = rest_points(skeleton)
    return lambda role: points[roles.index[role]]


def test_t_pose_stands_facing_z_with_its_lengths(mixamo):
    tpl = rest_template(mixamo)
    at = _at(tpl)
    assert tpl.names == mixamo.names and np.array_equal(tpl.parents, mixamo.parents)
    kept = np.linalg.norm(tpl.offsets[1:], axis=1)
    assert np.allclose(kept, np.linalg.norm(mixamo.offsets[1:], axis=1))
    assert np.allclose(np.linalg.norm(tpl.end_site_offsets, axis=1),
                       np.linalg.norm(mixamo.end_site_offsets, axis=1))
    assert rest_points(tpl)[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    # Arms straight out sideways (left on +X), legs straight down, the head above the root.
    for side, sign in (("l", 1.0), ("r", -1.0)):
        arm = at(f"{side}_wrist") - at(f"{side}_shoulder")
        assert arm[0] * sign > 0.3 and abs(arm[1]) < 1e-9 and abs(arm[2]) < 1e-9
        leg = at(f"{side}_ankle") - at(f"{side}_hip")
        assert leg[1] < -0.5 and np.allclose(leg[[0, 2]], 0.0)
        assert (at(f"{side}_toe") - at(f"{side}_ankle"))[2] > 0.05
    assert at("head")[1] > at("chest")[1] > at("root")[1]


def test_a_pose_lowers_the_arms_by_45_degrees(mixamo):
    at = _at(rest_template(mixamo, pose="a"))
    arm = at("l_wrist") - at("l_shoulder")
    assert np.degrees(np.arctan2(-arm[1], arm[0])) == pytest.approx(45.0)


def test_proportions_scale_their_parts_only(mixamo):
    base, long = rest_template(mixamo), rest_template(mixamo, proportions={"legs": 1.2,
                                                                           "arms": 0.8})
    a, b = _at(base), _at(long)
    for side in "lr":
        thigh = np.linalg.norm(b(f"{side}_knee") - b(f"{side}_hip"))
        assert thigh == pytest.approx(1.2 * np.linalg.norm(a(f"{side}_knee") - a(f"{side}_hip")))
        fore = np.linalg.norm(b(f"{side}_wrist") - b(f"{side}_elbow"))
        assert fore == pytest.approx(0.8 * np.linalg.norm(a(f"{side}_wrist") - a(f"{side}_elbow")))
    torso = np.linalg.norm(b("neck") - b("root"))
    assert torso == pytest.approx(np.linalg.norm(a("neck") - a("root")))


def test_rotation_order_changes_every_rotating_joint(mixamo):
    tpl = rest_template(mixamo, rotation_order="yzx")
    assert {tpl.rotation_order(j) for j in range(tpl.num_joints)} == {"YZX"}
    assert tpl.channels[0][:3] == ("Xposition", "Yposition", "Zposition")


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"pose": "x"}, ["pose", "t, a"]),
    ({"proportions": {"tail": 2.0}}, ["tail", "legs"]),
    ({"rotation_order": "XXY"}, ["XXY", "three distinct axes"]),
])
def test_bad_template_requests_are_rig_errors(mixamo, kwargs, words):
    with pytest.raises(RigError) as info:
        rest_template(mixamo, **kwargs)
    assert all(w in str(info.value) for w in words)


def test_rig_file_in_inches_reads_back(tmp_path, mixamo):
    tpl = rest_template(mixamo, proportions={"legs": 1.1}, rotation_order="XZY")
    path = write_bvh(rest_clip(tpl, unit="in"), tmp_path / "rig.bvh")
    back = read_bvh(path)
    assert back.metadata["file_unit"] == "in" and back.skeleton.same_as(tpl, atol=1e-7)
    assert back.skeleton.channels == tpl.channels


@pytest.mark.parametrize("layout", LAYOUTS)
def test_every_layout_makes_a_template_detected_as_itself(layout):
    skeleton = to_layout(synthetic_clip(), layout).skeleton
    tpl = rest_template(skeleton, pose="a")
    assert resolve_roles(tpl).names == resolve_roles(skeleton).names
    assert rest_points(tpl)[:, 1].min() == pytest.approx(0.0, abs=1e-12)
