"""Tests for emotive.core.ops and emotive.core.mirroring."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.core import mirroring, ops
from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_slerp,
    quaternion_to_matrix,
    yaw_quaternion,
)

SIX = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
REFLECT_X = np.array([-1.0, 1.0, 1.0])

# The Bandai Namco rig as its files give it (centimetres), with its small left/right
# asymmetries: bones point along the parent's local X, right-side offsets negated.
BANDAI = [
    ("joint_Root", None, (0, 0, 0)),
    ("Hips", "joint_Root", (4.5925, 91.4895, -427.239)),
    ("Spine", "Hips", (15.7357, 0, 0)),
    ("Chest", "Spine", (8.98455, -0.406207, 0)),
    ("Neck", "Chest", (16.3773, 0, 0)),
    ("Head", "Neck", (6.45672, 0, 0)),
    ("Shoulder_L", "Chest", (12.9942, -0.242716, 4.98039)),
    ("UpperArm_L", "Shoulder_L", (5.34809, 0, 0)),
    ("LowerArm_L", "UpperArm_L", (24.3286, 1.87007e-05, 0)),
    ("Hand_L", "LowerArm_L", (22.2916, 0, 0)),
    ("Shoulder_R", "Chest", (12.9945, -0.242716, -4.98039)),
    ("UpperArm_R", "Shoulder_R", (-5.34813, 0, 0)),
    ("LowerArm_R", "UpperArm_R", (-24.3289, 0.000322201, 0)),
    ("Hand_R", "LowerArm_R", (-22.2915, -0.000108084, 0)),
    ("UpperLeg_L", "Hips", (-2.19248, -6.46944, 0)),
    ("LowerLeg_L", "UpperLeg_L", (39.0811, 0, -1.23785e-05)),
    ("Foot_L", "LowerLeg_L", (40.9854, 0, -1.26872e-05)),
    ("Toes_L", "Foot_L", (11.7543, 0, 0)),
    ("UpperLeg_R", "Hips", (-2.19251, 6.46944, 0)),
    ("LowerLeg_R", "UpperLeg_R", (-39.0811, -0.00228153, -0.0401928)),
    ("Foot_R", "LowerLeg_R", (-40.9854, 0, 0)),
    ("Toes_R", "Foot_R", (-11.7543, 0, 0)),
]
BANDAI_ENDS = {"Head": (0, 0, 0), "Hand_L": (0, 0, 0), "Hand_R": (0, 0, 0),
               "Toes_L": (0, 0, 0), "Toes_R": (0, 0, 0)}

# A CMU-style rig at rest in a T-pose facing +Z (left is +X), metres.
CMU = [
    ("Hips", None, (0, 0.95, 0)),
    ("LeftUpLeg", "Hips", (0.09, -0.05, 0)), ("LeftLeg", "LeftUpLeg", (0, -0.42, 0)),
    ("LeftFoot", "LeftLeg", (0, -0.42, 0)), ("LeftToeBase", "LeftFoot", (0, -0.05, 0.12)),
    ("RightUpLeg", "Hips", (-0.09, -0.05, 0)), ("RightLeg", "RightUpLeg", (0, -0.42, 0)),
    ("RightFoot", "RightLeg", (0, -0.42, 0)), ("RightToeBase", "RightFoot", (0, -0.05, 0.12)),
    ("Spine", "Hips", (0, 0.12, 0)), ("Spine1", "Spine", (0, 0.15, 0.01)),
    ("Neck", "Spine1", (0, 0.2, 0)), ("Head", "Neck", (0, 0.1, 0.02)),
    ("LeftShoulder", "Spine1", (0.04, 0.15, 0)), ("LeftArm", "LeftShoulder", (0.12, 0, 0)),
    ("LeftForeArm", "LeftArm", (0.28, 0, 0)), ("LeftHand", "LeftForeArm", (0.25, 0, 0)),
    ("RightShoulder", "Spine1", (-0.04, 0.15, 0)), ("RightArm", "RightShoulder", (-0.12, 0, 0)),
    ("RightForeArm", "RightArm", (-0.28, 0, 0)), ("RightHand", "RightForeArm", (-0.25, 0, 0)),
]
CMU_ENDS = {"Head": (0, 0.1, 0), "LeftHand": (0.08, 0, 0), "RightHand": (-0.08, 0, 0),
            "LeftToeBase": (0, 0, 0.05), "RightToeBase": (0, 0, 0.05)}


def build(joints, ends, scale=1.0, six=False) -> Skeleton:
    names = tuple(j[0] for j in joints)
    parents = [names.index(j[1]) if j[1] else -1 for j in joints]
    channels = (SIX,) * len(names) if six else ()
    return Skeleton(
        names, parents, np.array([j[2] for j in joints]) * scale, channels,
        [names.index(e) for e in ends], np.array(list(ends.values())) * scale,
    )


def bandai_skeleton() -> Skeleton:
    return build(BANDAI, BANDAI_ENDS, scale=0.01, six=True)


def cmu_skeleton() -> Skeleton:
    return build(CMU, CMU_ENDS)


def random_motion(sk: Skeleton, frames: int = 12, seed: int = 0, fps: float = 30) -> Motion:
    rng = np.random.default_rng(seed)
    rot = quaternion_normalize(rng.normal(size=(frames, sk.num_joints, 4)))
    pos = np.broadcast_to(sk.offsets, (frames, sk.num_joints, 3)).copy()
    roots = sk.parents < 0
    pos[:, roots] += rng.normal(size=(frames, roots.sum(), 3))
    return Motion(sk, rot, pos, fps, {"name": "synthetic"})


def smooth_motion(sk: Skeleton, frames: int = 20, seed: int = 0, fps: float = 30) -> Motion:
    """Slowly varying rotations (a random slerp path per joint) and a moving root."""
    rng = np.random.default_rng(seed)
    a = quaternion_normalize(rng.normal(size=(sk.num_joints, 4)))
    b = quaternion_normalize(rng.normal(size=(sk.num_joints, 4)))
    t = np.linspace(0, 1, frames)
    rot = quaternion_slerp(a[None], b[None], t[:, None])
    pos = np.broadcast_to(sk.offsets, (frames, sk.num_joints, 3)).copy()
    pos[:, 0] += np.outer(t, [1.0, 0.1, 2.0])
    return Motion(sk, rot, pos, fps)


def rest_motion(sk: Skeleton, frames: int = 3) -> Motion:
    rot = np.zeros((frames, sk.num_joints, 4))
    rot[..., 0] = 1.0
    return Motion(sk, rot, np.broadcast_to(sk.offsets, (frames, sk.num_joints, 3)).copy(), 30)


def same_rotations(a: np.ndarray, b: np.ndarray, atol: float = 1e-9) -> bool:
    return bool(np.abs(np.abs((a * b).sum(-1)) - 1.0).max() < atol)


class TestResample:
    def test_same_fps_reproduces(self):
        m = random_motion(bandai_skeleton())
        out = ops.resample(m, 30)
        np.testing.assert_array_equal(out.rotations, m.rotations)
        np.testing.assert_array_equal(out.positions, m.positions)
        assert out.rotations is not m.rotations

    def test_double_frame_rate(self):
        m = smooth_motion(cmu_skeleton(), frames=10)
        out = ops.resample(m, 60)
        assert out.num_frames == 20 and out.fps == 60.0
        assert math.isclose(out.duration, m.duration)
        np.testing.assert_allclose(out.rotations[0:20:2], m.rotations, atol=1e-12)
        np.testing.assert_allclose(out.positions[0:20:2], m.positions, atol=1e-12)
        mid = quaternion_slerp(m.rotations[:-1], m.rotations[1:], np.full((9, 1), 0.5))
        assert same_rotations(out.rotations[1:19:2], mid, atol=1e-12)
        np.testing.assert_allclose(
            out.positions[1:19:2], 0.5 * (m.positions[:-1] + m.positions[1:]), atol=1e-12
        )
        # Past the last original frame the clip holds it.
        np.testing.assert_allclose(out.rotations[-1], m.rotations[-1], atol=1e-12)

    @pytest.mark.parametrize(("frames", "expected"), [(10, 5), (11, 6), (1, 1)])
    def test_halve_frame_rate(self, frames, expected):
        m = smooth_motion(cmu_skeleton(), frames=frames)
        out = ops.resample(m, 15)
        assert out.num_frames == expected
        np.testing.assert_allclose(out.rotations, m.rotations[::2], atol=1e-12)
        np.testing.assert_allclose(out.positions, m.positions[::2], atol=1e-12)

    def test_up_and_down_round_trip(self):
        m = smooth_motion(bandai_skeleton(), frames=17)
        back = ops.resample(ops.resample(m, 120), 30)
        assert back.num_frames == m.num_frames
        assert same_rotations(back.rotations, m.rotations, atol=1e-12)
        np.testing.assert_allclose(back.positions, m.positions, atol=1e-12)

    @settings(max_examples=25, deadline=None)
    @given(frames=st.integers(1, 60), fps=st.floats(5.0, 240.0))
    def test_frame_count_duration_and_first_frame(self, frames, fps):
        m = random_motion(cmu_skeleton(), frames=frames)
        out = ops.resample(m, fps)
        assert out.num_frames == max(1, math.floor(frames * fps / 30 + 0.5))
        if out.num_frames > 1:
            assert abs(out.duration - m.duration) <= 0.5 / fps + 1e-12
        np.testing.assert_array_equal(out.rotations[0], m.rotations[0])
        np.testing.assert_array_equal(out.positions[0], m.positions[0])
        assert np.allclose(np.linalg.norm(out.rotations, axis=-1), 1.0)

    def test_empty_clip(self):
        m = random_motion(cmu_skeleton(), frames=3)
        empty = m.replace(rotations=m.rotations[:0], positions=m.positions[:0])
        assert ops.resample(empty, 60).num_frames == 0

    @pytest.mark.parametrize("fps", [0, -30, float("nan"), float("inf"), "30"])
    def test_invalid_fps(self, fps):
        with pytest.raises(ops.MotionError, match="positive frame rate"):
            ops.resample(random_motion(cmu_skeleton()), fps)


class TestCrop:
    def test_frames(self):
        m = random_motion(cmu_skeleton(), frames=12)
        out = ops.crop(m, 3, 7)
        assert out.num_frames == 4
        np.testing.assert_array_equal(out.rotations, m.rotations[3:7])
        np.testing.assert_array_equal(out.positions, m.positions[3:7])
        assert ops.crop(m, 5).num_frames == 7

    def test_seconds(self):
        m = random_motion(cmu_skeleton(), frames=90)
        out = ops.crop(m, 1.0, 2.0, seconds=True)
        assert out.num_frames == 30 and math.isclose(out.duration, 1.0)
        np.testing.assert_array_equal(out.rotations, m.rotations[30:60])
        assert ops.crop(m, 0.5, seconds=True).num_frames == 75

    @pytest.mark.parametrize(
        ("start", "stop", "seconds", "match"),
        [
            (5, 5, False, "cannot crop"),
            (-1, 4, False, "cannot crop"),
            (0, 13, False, "0 <= start < stop <= 12"),
            (1.5, 4, False, "whole frame numbers"),
            (0.2, 0.5, True, "cannot crop"),
        ],
    )
    def test_invalid(self, start, stop, seconds, match):
        with pytest.raises(ops.MotionError, match=match):
            ops.crop(random_motion(cmu_skeleton(), frames=12), start, stop, seconds=seconds)


class TestConcatenate:
    def test_smoke(self):
        sk = cmu_skeleton()
        a, b = random_motion(sk, 4, seed=1), random_motion(sk, 6, seed=2)
        out = ops.concatenate([a, b])
        assert out.num_frames == 10 and out.metadata == a.metadata
        np.testing.assert_array_equal(out.rotations[4:], b.rotations)
        np.testing.assert_array_equal(ops.concatenate([a]).positions, a.positions)

    def test_animated_offsets_may_differ(self):
        # Bandai clips differ in the Hips rest offset, which every frame overrides.
        a = random_motion(bandai_skeleton(), 3)
        other = list(BANDAI)
        other[1] = ("Hips", "joint_Root", (-17.1583, 93.1646, 452.98))
        b = random_motion(build(other, BANDAI_ENDS, scale=0.01, six=True), 3)
        assert ops.concatenate([a, b]).num_frames == 6

    def test_fps_mismatch(self):
        sk = cmu_skeleton()
        with pytest.raises(ops.MotionError, match=r"30 fps.*60 fps.*resample"):
            ops.concatenate([random_motion(sk, fps=30), random_motion(sk, fps=60)])

    def test_rig_mismatch(self):
        a = random_motion(cmu_skeleton(), 3)
        with pytest.raises(RigError, match="joint names differ"):
            ops.concatenate([a, random_motion(bandai_skeleton(), 3)])
        longer = build([(n, p, np.array(o) * 1.1) for n, p, o in CMU], CMU_ENDS)
        with pytest.raises(RigError, match="rest offsets"):
            ops.concatenate([a, random_motion(longer, 3)])

    def test_empty(self):
        with pytest.raises(ops.MotionError, match="at least one"):
            ops.concatenate([])


class TestMirrorMap:
    def test_bandai_rule(self):
        sk = bandai_skeleton()
        mm = mirroring.mirror_map(sk)
        names = dict(zip(sk.names, mm.reflection_names, strict=True))
        assert names["joint_Root"] == "x" and names["Hips"] == "y"
        assert {names[n] for n in ("Spine", "Chest", "Neck", "Head")} == {"z"}
        sided = [n for n in sk.names if n.endswith(("_L", "_R"))]
        assert {names[n] for n in sided} == {"-I"}
        assert sk.names[mm.pairs[sk.index("Hand_L")]] == "Hand_R"
        assert mm.pairs[sk.index("Neck")] == sk.index("Neck")
        ends = sk.end_site_parents
        np.testing.assert_array_equal(ends[mm.end_site_pairs], mm.pairs[ends])

    def test_cmu_rule_is_plain_x_reflection(self):
        mm = mirroring.mirror_map(cmu_skeleton())
        assert set(mm.reflection_names) == {"x"}

    @pytest.mark.parametrize(
        ("left", "right"),
        [("Arm_L", "Arm_R"), ("arm.l", "arm.r"), ("LeftArm", "RightArm"),
         ("upper_left_arm", "upper_right_arm"), ("L_Arm", "R_Arm"), ("LArm", "RArm"),
         ("l_arm", "r_arm")],
    )
    def test_name_patterns(self, left, right):
        sk = Skeleton(("Root", left, right), [-1, 0, 0], [[0, 1, 0], [0.2, 0, 0], [-0.2, 0, 0]])
        np.testing.assert_array_equal(mirroring.mirror_map(sk).pairs, [0, 2, 1])

    def test_explicit_pairs(self):
        sk = Skeleton(("Root", "A", "B"), [-1, 0, 0], [[0, 1, 0], [0.2, 0, 0], [-0.2, 0, 0]])
        np.testing.assert_array_equal(mirroring.mirror_map(sk).pairs, [0, 1, 2])
        np.testing.assert_array_equal(mirroring.mirror_map(sk, {"A": "B"}).pairs, [0, 2, 1])
        with pytest.raises(RigError, match="'C'"):
            mirroring.mirror_map(sk, {"A": "C"})

    def test_unpaired_sided_joint(self):
        sk = Skeleton(("Root", "LeftEye"), [-1, 0], [[0, 1, 0], [0.1, 0, 0]])
        with pytest.raises(RigError, match=r"LeftEye \(no RightEye\).*pairs="):
            mirroring.mirror_map(sk)

    def test_non_mirror_hierarchy(self):
        sk = Skeleton(
            ("Root", "Spine", "Arm_L", "Arm_R"), [-1, 0, 0, 1], np.ones((4, 3)) * 0.1
        )
        with pytest.raises(RigError, match="not mirror images"):
            mirroring.mirror_map(sk)

    def test_end_site_mismatch(self):
        sk = Skeleton(
            ("Root", "Arm_L", "Arm_R"), [-1, 0, 0], [[0, 1, 0], [0.2, 0, 0], [-0.2, 0, 0]],
            end_site_parents=[1], end_site_offsets=[[0.1, 0, 0]],
        )
        with pytest.raises(RigError, match="end sites"):
            mirroring.mirror_map(sk)


class TestMirror:
    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    @pytest.mark.parametrize("seed", [0, 1, 2])
    def test_world_positions_are_reflected(self, rig, seed):
        m = random_motion(rig(), seed=seed)
        out = ops.mirror(m)
        mm = mirroring.mirror_map(m.skeleton)
        perm = np.concatenate([mm.pairs, m.skeleton.num_joints + mm.end_site_pairs])
        expected = m.positions_with_end_sites()[:, perm] * REFLECT_X
        np.testing.assert_allclose(out.positions_with_end_sites(), expected, atol=1e-9)

    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    def test_world_frames_are_reflected(self, rig):
        m = random_motion(rig(), seed=3)
        mm = mirroring.mirror_map(m.skeleton)
        d = np.array([{"-I": [-1, -1, -1], "x": [-1, 1, 1], "y": [1, -1, 1], "z": [1, 1, -1]}[n]
                      for n in mm.reflection_names], dtype=float)
        rot = quaternion_to_matrix(m.global_transforms()[0])[:, mm.pairs]
        expected = np.diag(REFLECT_X) @ rot * d[None, :, None, :]
        got = quaternion_to_matrix(ops.mirror(m).global_transforms()[0])
        np.testing.assert_allclose(got, expected, atol=1e-12)

    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    def test_twice_is_identity(self, rig):
        m = random_motion(rig(), seed=4)
        twice = ops.mirror(ops.mirror(m))
        np.testing.assert_array_equal(twice.positions, m.positions)
        np.testing.assert_array_equal(twice.skeleton.offsets, m.skeleton.offsets)
        np.testing.assert_array_equal(twice.skeleton.end_site_offsets, m.skeleton.end_site_offsets)
        # Same rotations; quaternions come back as q or -q (see the ops module docstring).
        assert np.abs(np.abs(twice.rotations) - np.abs(m.rotations)).max() == 0.0
        assert same_rotations(twice.rotations, m.rotations, atol=1e-12)
        np.testing.assert_allclose(twice.global_positions(), m.global_positions(), atol=1e-12)
        assert twice.metadata["mirrored"] is False

    def test_twice_is_bit_exact_on_plane_reflections(self):
        m = random_motion(cmu_skeleton(), seed=5)
        np.testing.assert_array_equal(ops.mirror(ops.mirror(m)).rotations, m.rotations)

    def test_symmetric_rig_keeps_skeleton_and_rest_pose(self):
        sk = cmu_skeleton()
        out = ops.mirror(rest_motion(sk))
        assert out.skeleton is sk
        np.testing.assert_array_equal(np.abs(out.rotations), np.abs(rest_motion(sk).rotations))

    def test_cmu_local_rule(self):
        m = random_motion(cmu_skeleton(), seed=6)
        mm = mirroring.mirror_map(m.skeleton)
        expected = m.rotations[:, mm.pairs] * [1, 1, -1, -1]
        np.testing.assert_array_equal(ops.mirror(m).rotations, expected)

    def test_bandai_rig_nearly_kept(self):
        sk = bandai_skeleton()
        out = ops.mirror(random_motion(sk))
        assert out.skeleton is not sk
        fixed = np.abs(out.skeleton.offsets - sk.offsets)
        fixed[sk.index("Hips")] = 0.0  # a start position in the capture room, not a bone
        assert fixed.max() < 5e-4
        # Limbs copy their local rotations across (-I on both sides of the joint).
        m = random_motion(sk, seed=7)
        lower_leg = ops.mirror(m).rotations[:, sk.index("LowerLeg_L")]
        np.testing.assert_array_equal(lower_leg, m.rotations[:, sk.index("LowerLeg_R")])

    def test_explicit_pairs(self):
        sk = Skeleton(("Root", "A", "B"), [-1, 0, 0], [[0, 1, 0], [0.2, 0, 0], [-0.2, 0, 0]])
        m = random_motion(sk)
        out = ops.mirror(m, pairs={"A": "B"})
        expected = m.global_positions()[:, [0, 2, 1]] * REFLECT_X
        np.testing.assert_allclose(out.global_positions(), expected, atol=1e-12)
        assert out.skeleton is sk

    def test_heading_is_negated(self):
        m = smooth_motion(bandai_skeleton(), seed=8)
        np.testing.assert_allclose(ops.heading(ops.mirror(m)), -ops.heading(m), atol=1e-9)


class TestPlaceOnGround:
    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    def test_lowest_point_at_zero(self, rig):
        m = random_motion(rig(), seed=1)
        out = ops.place_on_ground(m)
        pts = out.positions_with_end_sites()
        assert abs(pts[..., 1].min()) < 1e-12
        # Only a vertical shift: XZ and shape unchanged.
        before = m.positions_with_end_sites()
        np.testing.assert_allclose(pts[..., [0, 2]], before[..., [0, 2]], atol=1e-12)
        np.testing.assert_allclose(pts[..., 1] - before[..., 1], -before[..., 1].min(), atol=1e-12)

    def test_end_sites_count(self):
        sk = cmu_skeleton()
        m = rest_motion(sk)
        out = ops.place_on_ground(m)
        # The toe end sites (0.05 below the ankle) are the lowest points.
        assert abs(out.positions_with_end_sites()[..., 1].min()) < 1e-12
        assert out.global_positions()[..., 1].min() > 0

    def test_empty(self):
        m = rest_motion(cmu_skeleton())
        with pytest.raises(ops.MotionError, match="empty"):
            ops.place_on_ground(m.replace(rotations=m.rotations[:0], positions=m.positions[:0]))


class TestHeading:
    def test_rest_pose_faces_plus_z(self):
        m = rest_motion(cmu_skeleton())
        np.testing.assert_allclose(ops.heading(m), 0.0, atol=1e-12)
        np.testing.assert_allclose(ops.facing_directions(m), [[0, 0, 1.0]] * 3, atol=1e-12)

    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    @settings(max_examples=15, deadline=None)
    @given(angle=st.floats(-3.0, 3.0))
    def test_turning_the_clip_turns_the_heading(self, rig, angle):
        m = smooth_motion(rig(), frames=6, seed=2)
        turned = ops._move_roots(m, yaw_quaternion(np.asarray(angle)), np.zeros(3))
        diff = np.angle(np.exp(1j * (ops.heading(turned) - ops.heading(m) - angle)))
        np.testing.assert_allclose(diff, 0.0, atol=1e-9)

    def test_directions_are_unit_ground_vectors(self):
        m = random_motion(bandai_skeleton(), seed=3)
        f = ops.facing_directions(m)
        assert f.shape == (m.num_frames, 3)
        np.testing.assert_allclose(np.linalg.norm(f, axis=-1), 1.0)
        assert np.all(f[:, 1] == 0.0)
        h = ops.heading(m)
        assert h.shape == (m.num_frames,)
        np.testing.assert_allclose(f[:, [0, 2]], np.stack((np.sin(h), np.cos(h)), -1))

    def test_degenerate_frames_take_nearest(self):
        sk = cmu_skeleton()
        m = rest_motion(sk, frames=4)
        rot = m.rotations.copy()
        # Frame 2 lies the body face down and turned so that hips and shoulders line up with Y.
        rot[2, 0] = axis_angle_to_quaternion(np.array([0.0, 0.0, math.pi / 2]))
        h = ops.heading(m.replace(rotations=rot))
        np.testing.assert_allclose(h, 0.0, atol=1e-12)

    def test_missing_roles(self):
        sk = Skeleton(("Root", "A"), [-1, 0], [[0, 1, 0], [0, 1, 0]])
        with pytest.raises(RigError, match="lacks the roles"):
            ops.heading(rest_motion(sk))


class TestRootTrajectory:
    def test_follows_hips(self):
        sk = bandai_skeleton()
        m = random_motion(sk)
        traj = ops.root_trajectory(m)
        assert traj.shape == (m.num_frames, 2)
        np.testing.assert_allclose(traj, m.global_positions()[:, sk.index("Hips")][:, [0, 2]])

    def test_role_map(self):
        sk = cmu_skeleton()
        m = random_motion(sk)
        mapping = {"root": "Spine"} | {
            r: n for r, n in ops.resolve_roles(sk).names.items() if r != "root"
        }
        np.testing.assert_allclose(
            ops.root_trajectory(m, mapping), m.global_positions()[:, sk.index("Spine")][:, [0, 2]]
        )


class TestCanonicalizeFacing:
    @pytest.mark.parametrize("rig", [bandai_skeleton, cmu_skeleton])
    @pytest.mark.parametrize("frame", [0, 5, -1])
    def test_root_at_origin_facing_z(self, rig, frame):
        m = smooth_motion(rig(), frames=12, seed=4)
        out = ops.canonicalize_facing(m, frame)
        np.testing.assert_allclose(ops.root_trajectory(out)[frame], 0.0, atol=1e-12)
        assert abs(ops.heading(out)[frame]) < 1e-9
        # A rigid motion about Y: heights and distances between joints are kept.
        before, after = m.positions_with_end_sites(), out.positions_with_end_sites()
        np.testing.assert_allclose(after[..., 1], before[..., 1], atol=1e-12)
        np.testing.assert_allclose(
            np.linalg.norm(after - after[:, :1], axis=-1),
            np.linalg.norm(before - before[:, :1], axis=-1), atol=1e-12,
        )

    def test_idempotent(self):
        m = ops.canonicalize_facing(random_motion(bandai_skeleton(), seed=5))
        again = ops.canonicalize_facing(m)
        np.testing.assert_allclose(again.global_positions(), m.global_positions(), atol=1e-12)

    def test_local_rotations_below_roots_untouched(self):
        m = random_motion(cmu_skeleton(), seed=6)
        out = ops.canonicalize_facing(m)
        np.testing.assert_array_equal(out.rotations[:, 1:], m.rotations[:, 1:])
        expected = quaternion_multiply(
            yaw_quaternion(np.asarray(-ops.heading(m)[0])), m.rotations[:, 0]
        )
        np.testing.assert_allclose(out.rotations[:, 0], expected, atol=1e-12)

    def test_bad_frame(self):
        with pytest.raises(ops.MotionError, match="outside the clip of 12 frames"):
            ops.canonicalize_facing(random_motion(cmu_skeleton()), 12)


@pytest.mark.data
def test_mirror_twice_is_identity_on_real_locomotion_clips(bandai1_dir, bandai2_dir):
    from emotive.data import load_clips

    for dataset in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        for clip in load_clips(dataset, locomotion=True)[::5]:
            m = clip.motion
            once = ops.mirror(m)
            mm = mirroring.mirror_map(m.skeleton)
            # The mirror image: each joint lands where its counterpart's reflection was.
            np.testing.assert_allclose(
                once.global_positions(), m.global_positions()[:, mm.pairs] * REFLECT_X,
                atol=1e-9, err_msg=clip.name,
            )
            twice = ops.mirror(once)
            np.testing.assert_array_equal(twice.positions, m.positions, err_msg=clip.name)
            assert same_rotations(twice.rotations, m.rotations, atol=1e-12), clip.name
            assert twice.skeleton.same_as(m.skeleton, atol=0.0)
