from __future__ import annotations

import numpy as np
import pytest
from retarget_helpers import bone_angles, walk

from emotive.core import Skeleton
from emotive.core.rig_layouts import to_layout
from emotive.core.roles import resolve_roles
from emotive.errors import RigError
from emotive.features.contacts import leg_length
from emotive.retarget import foot_skate, leg_scale, pair_rigs, rest_clip, rest_template, retarget
from emotive.retarget.retarget import transfer_pose
from layout_clips import synthetic_clip

#: Role bones that point exactly along the source's: those of joints with one child role,
#: and the shoulders (Mixamo's clavicle joint is swung to aim them).
EXACT = ("spine", "chest", "neck", "head", "l_elbow", "l_wrist", "r_elbow", "r_wrist",
         "l_knee", "l_ankle", "l_toe", "r_knee", "r_ankle", "r_toe", "l_shoulder", "r_shoulder",
         "l_handtip", "r_handtip")


@pytest.fixture(scope="module")
def clip():
    return synthetic_clip(frames=20)


def _pose_only(motion, target):
    pairing = pair_rigs(motion.skeleton, target)
    return transfer_pose(motion, target, pairing, leg_scale(motion, pairing))


def test_bones_point_where_the_source_bones_point(clip):
    mixamo = to_layout(clip, "mixamo").skeleton
    target = rest_template(mixamo, pose="a", proportions={"legs": 1.2, "arms": 0.8},
                           rotation_order="XYZ")
    angles = bone_angles(clip, _pose_only(clip, target))
    assert max(angles[r] for r in EXACT) < 1e-4
    # The hips hang off a joint with several child roles and are fitted, not aimed: the
    # template's hips hang 19 degrees lower than the synthetic rig's level ones.
    assert set(angles) - set(EXACT) == {"l_hip", "r_hip"}
    assert max(angles["l_hip"], angles["r_hip"]) < 20.0


def test_t_and_a_pose_rests_give_the_same_motion(clip):
    skeleton = to_layout(clip, "cmu").skeleton
    t_pose = _pose_only(clip, rest_template(skeleton, pose="t"))
    a_pose = _pose_only(clip, rest_template(skeleton, pose="a"))
    assert np.abs(t_pose.global_positions() - a_pose.global_positions()).max() < 1e-9
    assert np.abs(t_pose.rotations - a_pose.rotations).max() > 0.1


def test_the_same_rig_gives_the_same_motion_but_for_joints_without_roles(clip):
    out = retarget(clip, clip.skeleton)
    sk = clip.skeleton
    roles = resolve_roles(sk)
    # The toe roles are the toe joints' end sites: the toe joints play no role and keep their
    # rest rotation, and the ankle aims at the toe tip, so the feet differ; the rest is exact.
    toes = [sk.index("Toes_L"), sk.index("Toes_R")]
    kept = [i for r, i in roles.index.items() if r not in ("l_toe", "r_toe")]
    moved = out.positions_with_end_sites()[:, kept] - clip.positions_with_end_sites()[:, kept]
    assert np.abs(moved).max() < 1e-6
    assert np.allclose(np.abs(out.rotations[:, toes, 0]), 1.0)


def test_output_has_the_target_layout_unit_and_rate(clip):
    target = rest_clip(rest_template(to_layout(clip, "unreal").skeleton, rotation_order="XZY"),
                       unit="in")
    out = retarget(clip, target, fps=60.0)
    assert out.skeleton is target.skeleton
    assert out.fps == 60.0 and out.num_frames == 2 * clip.num_frames
    assert out.metadata["file_unit"] == "in" and out.metadata["name"] == "synthetic"
    assert {out.skeleton.rotation_order(j) for j in range(out.skeleton.num_joints)} == {"XZY"}


def test_root_motion_scales_with_leg_length(clip):
    target = rest_template(clip.skeleton, proportions={"legs": 1.3})
    out = _pose_only(clip, target)
    scale = leg_length(rest_clip(target).positions_with_end_sites(), resolve_roles(target)) / \
        leg_length(clip.positions_with_end_sites(), resolve_roles(clip.skeleton))
    assert scale == pytest.approx(1.3, rel=0.05)
    moved = out.global_positions()[:, 0] - out.global_positions()[0, 0]
    source = clip.global_positions()[:, 0] - clip.global_positions()[0, 0]
    assert np.allclose(moved, scale * source)


def test_joints_without_roles_keep_their_rest_rotation(clip):
    target = rest_template(to_layout(clip, "mixamo").skeleton)
    out = retarget(clip, target)
    roles = resolve_roles(target)
    for name in ("mixamorig:LeftHandThumb2", "mixamorig:RightHandIndex3", "mixamorig:Spine1",
                 "mixamorig:LeftToeBase"):
        j = target.index(name)
        assert j not in roles.index.values()
        assert np.allclose(np.abs(out.rotations[:, j, 0]), 1.0)


def test_a_target_without_feet_is_a_rig_error_naming_the_roles(clip):
    sk = clip.skeleton
    keep = [j for j, n in enumerate(sk.names) if not n.startswith(("Foot_", "Toes_"))]
    parents = [keep.index(p) if p >= 0 else -1 for p in sk.parents[keep]]
    footless = Skeleton(tuple(sk.names[j] for j in keep), parents, sk.offsets[keep],
                        end_site_parents=[keep.index(sk.index("Head"))],
                        end_site_offsets=[[0.0, 0.1, 0.0]])
    with pytest.raises(RigError) as info:
        retarget(clip, footless)
    message = str(info.value)
    assert "\n" not in message and message.startswith("target rig")
    assert all(r in message for r in ("l_ankle", "r_ankle", "l_toe", "r_toe", "--to-roles"))


@pytest.fixture(scope="module")
def round_trip(bandai1_dir):
    source = walk(bandai1_dir)
    cmu = rest_template(to_layout(source, "cmu").skeleton, proportions={"legs": 1.1,
                                                                         "arms": 0.9})
    there = retarget(source, cmu)
    return source, there, retarget(there, source)


def test_round_trip_through_a_cmu_t_pose_keeps_joints_and_feet(round_trip):
    source, there, back = round_trip
    error = np.linalg.norm(back.positions_with_end_sites() - source.positions_with_end_sites(),
                           axis=-1)
    assert error.mean() <= 0.02
    assert foot_skate(back) <= 1.2 * foot_skate(source)
    assert foot_skate(there) <= 1.2 * there.metadata["leg_scale"] * foot_skate(source)


def test_round_trip_keeps_the_perceived_emotion(round_trip):
    from emotive.eval.classifier import load_default_classifier

    source, _, back = round_trip
    classifier = load_default_classifier()
    before, after = classifier.classify(source)[1], classifier.classify(back)[1]
    assert np.abs(before - after).max() <= 0.1


def test_knees_on_a_t_pose_target_bend_about_its_lateral_axis(round_trip):
    from emotive.transforms.np_rotations import quaternion_to_axis_angle

    _, there, _ = round_trip
    roles = resolve_roles(there.skeleton)
    for knee in ("l_knee", "r_knee"):
        v = quaternion_to_axis_angle(there.rotations[:, roles.index[knee]])
        energy, axes = np.linalg.eigh(v.T @ v)
        # The Maya-style rest of the source carried across: a pure hinge about X.
        assert abs(axes[0, -1]) > 0.99 and energy[-1] / energy.sum() > 0.99


def test_foot_skate_is_the_speed_of_feet_on_the_floor(clip):
    frames = 30
    rest = rest_clip(clip.skeleton, frames=frames)
    t = np.arange(frames) / rest.fps
    sliding = rest.positions.copy()
    sliding[:, 0, 2] += 0.5 * t
    assert foot_skate(rest) == 0.0
    assert foot_skate(rest.replace(positions=sliding)) == pytest.approx(0.5)
    # A hop: still on the floor, then 2 m/s through the air for frames 10-19, then still.
    hop = rest.positions.copy()
    air = (np.arange(frames) >= 10) & (np.arange(frames) < 20)
    hop[:, 0, 1] += np.where(air, 0.3, 0.0)
    hop[:, 0, 2] += 2.0 * np.clip(t - t[9], 0.0, t[19] - t[9])
    skate = foot_skate(rest.replace(positions=hop))
    assert 0.0 < skate < 0.2  # only the two landing frames beside the hop move at all
