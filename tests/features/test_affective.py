"""Tests of the 18 pose affective features (torch kernel and NumPy wrapper)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from emotive.core.roles import JointRoles
from emotive.errors import RigError
from emotive.features.affective import (
    AFFECTIVE_FEATURE_KINDS,
    AFFECTIVE_FEATURE_NAMES,
    AFFECTIVE_ROLES,
    affective_features,
    affective_features_batch_last,
    affective_features_np,
)

PI = np.pi
R = len(AFFECTIVE_ROLES)

#: A T-pose-like stick figure in metres (left = +X, facing +Z): arms straight out at the
#: height of the spine joint, straight legs, toes forward.
T_POSE = {
    "root": (0, 1.0, 0), "spine": (0, 1.4, 0), "neck": (0, 1.5, 0), "head": (0, 1.7, 0),
    "l_shoulder": (0.2, 1.4, 0), "r_shoulder": (-0.2, 1.4, 0),
    "l_elbow": (0.5, 1.4, 0), "r_elbow": (-0.5, 1.4, 0),
    "l_wrist": (0.8, 1.4, 0), "r_wrist": (-0.8, 1.4, 0),
    "l_handtip": (0.9, 1.4, 0), "r_handtip": (-0.9, 1.4, 0),
    "l_hip": (0.1, 1.0, 0), "r_hip": (-0.1, 1.0, 0),
    "l_knee": (0.1, 0.5, 0), "r_knee": (-0.1, 0.5, 0),
    "l_ankle": (0.1, 0.1, 0), "r_ankle": (-0.1, 0.1, 0),
    "l_toe": (0.1, 0.0, 0.15), "r_toe": (-0.1, 0.0, 0.15),
}


def pose(overrides: dict[str, tuple[float, float, float]] | None = None) -> np.ndarray:
    """``(R, 3)`` float64 positions of :data:`T_POSE` with some roles moved."""
    table = {**T_POSE, **(overrides or {})}
    return np.array([table[r] for r in AFFECTIVE_ROLES], dtype=np.float64)


def yaw_matrix(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


class TestNames:
    def test_stable_names_and_order(self):
        assert AFFECTIVE_FEATURE_NAMES == (
            "shoulders_angle_at_spine", "wrists_angle_at_spine",
            "l_handtip_neck_root_ratio", "r_handtip_neck_root_ratio", "handtips_torso_ratio",
            "shoulders_spine_root_area_ratio", "wrists_spine_root_area_ratio",
            "l_elbow_angle", "r_elbow_angle",
            "head_neck_l_shoulder_angle", "head_neck_r_shoulder_angle",
            "head_root_l_knee_angle", "head_root_r_knee_angle",
            "toes_torso_ratio", "toes_angle_at_root", "l_knee_angle", "r_knee_angle",
            "handtips_neck_toes_root_area_ratio",
        )

    def test_kinds_match_the_paper(self):
        kinds = list(AFFECTIVE_FEATURE_KINDS)
        assert (kinds.count("angle"), kinds.count("distance_ratio"), kinds.count("area_ratio")) == (
            11, 4, 3,
        )


class TestKnownValues:
    def test_t_pose(self):
        f = affective_features_np(pose())
        # Feature 15: toes at (+-0.1, -1, 0.15) from the root.
        toes_cos = (1 + 0.15**2 - 0.1**2) / (1 + 0.15**2 + 0.1**2)
        expected = [
            PI,  # 1 shoulders in line with the spine joint
            PI,  # 2 wrists in line with the spine joint
            np.sqrt(0.82 / 0.97),  # 3 d(L handtip, neck) / d(L handtip, root)
            np.sqrt(0.82 / 0.97),  # 4
            1.8 / 0.5,  # 5 handtip spread over neck-root
            0.0,  # 6 collinear shoulders and spine: zero area
            0.0,  # 7
            PI, PI,  # 8, 9 straight elbows
            PI / 2 + np.arctan(0.5), PI / 2 + np.arctan(0.5),  # 10, 11 head up, shoulders down-out
            PI - np.arctan(0.2), PI - np.arctan(0.2),  # 12, 13 head above root, knees below
            0.2 / 0.5,  # 14 toe distance over neck-root
            np.arccos(toes_cos),  # 15
            PI, PI,  # 16, 17 straight knees
            (0.5 * 1.8 * 0.1) / (0.5 * 0.2 * np.sqrt(1 + 0.15**2)),  # 18
        ]
        np.testing.assert_allclose(f, expected, rtol=1e-7, atol=1e-7)

    def test_bent_elbows_and_knees(self):
        f = affective_features_np(pose({
            "l_wrist": (0.5, 1.1, 0), "r_wrist": (-0.5, 1.4, 0.3),  # 90 degree elbows
            "l_ankle": (0.1, 0.5 - 0.2, -0.2),  # left knee bent to 135 degrees
        }))
        names = list(AFFECTIVE_FEATURE_NAMES)
        assert f[names.index("l_elbow_angle")] == pytest.approx(PI / 2, abs=1e-9)
        assert f[names.index("r_elbow_angle")] == pytest.approx(PI / 2, abs=1e-9)
        assert f[names.index("l_knee_angle")] == pytest.approx(3 * PI / 4, abs=1e-9)
        assert f[names.index("r_knee_angle")] == pytest.approx(PI, abs=1e-7)

    def test_slouch_narrows_the_shoulder_angle(self):
        slouch = pose({"l_shoulder": (0.2, 1.45, 0.1), "r_shoulder": (-0.2, 1.45, 0.1)})
        f = affective_features_np(slouch)
        assert f[0] == pytest.approx(2 * np.arctan2(0.2, np.hypot(0.05, 0.1)), abs=1e-9)


class TestInvariance:
    @settings(max_examples=60, deadline=None)
    @given(
        noise=arrays(np.float64, (R, 3), elements=st.floats(-0.08, 0.08)),
        scale=st.floats(0.05, 20.0),
        yaw=st.floats(-np.pi, np.pi),
        shift=arrays(np.float64, (3,), elements=st.floats(-50.0, 50.0)),
    )
    def test_scale_yaw_translation(self, noise, scale, yaw, shift):
        p = pose() + noise
        q = scale * p @ yaw_matrix(yaw).T + shift
        np.testing.assert_allclose(
            affective_features_np(q), affective_features_np(p), rtol=1e-6, atol=1e-8
        )

    def test_any_rotation(self, rng):
        p = pose() + rng.normal(0, 0.05, (R, 3))
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        np.testing.assert_allclose(
            affective_features_np(p @ rot.T), affective_features_np(p), rtol=1e-9, atol=1e-10
        )


def _finite_with_gradients(points: np.ndarray) -> torch.Tensor:
    x = torch.tensor(points, dtype=torch.float64, requires_grad=True)
    f = affective_features(x)
    assert torch.isfinite(f).all(), f
    (grad,) = torch.autograd.grad(f.sum(), x)
    assert torch.isfinite(grad).all(), grad
    return f.detach()


class TestDegenerate:
    def test_all_joints_at_one_point(self):
        f = _finite_with_gradients(np.full((R, 3), 0.7))
        kinds = np.array(AFFECTIVE_FEATURE_KINDS)
        assert torch.all(f[kinds == "angle"] == PI / 2)  # zero-length arms
        assert torch.all(f[kinds != "angle"] == 1.0)  # 0 / 0 ratios

    def test_collinear(self, rng):
        direction = np.array([0.3, -0.5, 0.8])
        points = rng.uniform(-1, 1, (R, 1)) * direction + np.array([1.0, 2.0, 3.0])
        f = _finite_with_gradients(points)
        kinds = np.array(AFFECTIVE_FEATURE_KINDS)
        angles = f[kinds == "angle"].numpy()
        assert np.all((np.abs(angles) < 1e-6) | (np.abs(angles - PI) < 1e-6))

    def test_coincident_pairs(self):
        # Rigs without hand tips put them on the wrists; crossed feet put the toes together.
        f = _finite_with_gradients(pose({
            "l_handtip": T_POSE["l_wrist"], "r_handtip": T_POSE["r_wrist"],
            "l_toe": (0, 0, 0.1), "r_toe": (0, 0, 0.1), "l_elbow": T_POSE["l_wrist"],
        }))
        assert f[list(AFFECTIVE_FEATURE_NAMES).index("toes_torso_ratio")] < 1e-5

    def test_float32(self):
        x = torch.zeros((4, R, 3), dtype=torch.float32, requires_grad=True)
        f = affective_features(x)
        (grad,) = torch.autograd.grad(f.sum(), x)
        assert f.dtype == torch.float32
        assert torch.isfinite(f).all() and torch.isfinite(grad).all()


class TestKernel:
    def test_torch_equals_numpy(self, rng):
        p = pose() + rng.normal(0, 0.1, (2, 5, R, 3))
        np.testing.assert_array_equal(
            affective_features(torch.from_numpy(p)).numpy(), affective_features_np(p)
        )
        assert affective_features_np(p).shape == (2, 5, 18)
        assert affective_features_np(p.astype(np.float32)).dtype == np.float32

    def test_roles_index_a_joint_and_end_site_array(self, rng):
        p = pose() + rng.normal(0, 0.1, (3, R, 3))
        # Scatter the roles into a bigger array with distractor points.
        order = rng.permutation(R + 6)
        big = rng.normal(size=(3, R + 6, 3))
        big[:, order[:R]] = p
        roles = JointRoles({r: int(order[k]) for k, r in enumerate(AFFECTIVE_ROLES)}, {}, "test")
        np.testing.assert_allclose(affective_features_np(big, roles), affective_features_np(p))

    def test_gradcheck(self, rng):
        x = torch.tensor(pose() + rng.normal(0, 0.05, (R, 3)), requires_grad=True)
        assert torch.autograd.gradcheck(affective_features, (x,))

    def test_bad_shapes_and_roles(self):
        with pytest.raises(ValueError, match=r"\(\.\.\., 20, 3\)"):
            affective_features(torch.zeros(5, 3))
        with pytest.raises(ValueError):
            affective_features(torch.zeros(R, 2))
        with pytest.raises(RigError, match="l_toe"):
            affective_features_np(pose(), {r: 0 for r in AFFECTIVE_ROLES if r != "l_toe"})


@pytest.mark.data
def test_real_walk_is_finite_and_plausible(walk_dir):
    from emotive.core.roles import resolve_roles
    from emotive.io.bvh import read_bvh

    motion = read_bvh(walk_dir / "dataset-1_walk_normal_001.bvh")
    f = affective_features_np(motion.positions_with_end_sites(), resolve_roles(motion.skeleton))
    assert f.shape == (motion.num_frames, 18) and np.isfinite(f).all()
    kinds = np.array(AFFECTIVE_FEATURE_KINDS)
    assert (f[:, kinds == "angle"] >= 0).all() and (f[:, kinds == "angle"] <= PI).all()
    names = list(AFFECTIVE_FEATURE_NAMES)
    # Knees straighten in stance and bend in swing; the stride angle opens and closes.
    knee = f[:, names.index("l_knee_angle")]
    assert knee.max() > 3.0 and knee.min() < 2.2
    assert np.ptp(f[:, names.index("toes_angle_at_root")]) > 0.4


def test_batch_last_features_equal_the_poses_first_ones():
    rng = np.random.default_rng(3)
    roles = {name: k + 2 for k, name in enumerate(AFFECTIVE_ROLES)}
    points = torch.from_numpy(rng.normal(size=(6, R + 4, 3)))
    expected = affective_features(points, roles)
    got = affective_features_batch_last(points.permute(1, 2, 0).contiguous(), roles)
    assert got.shape == (len(AFFECTIVE_FEATURE_NAMES), 6)
    torch.testing.assert_close(got.T, expected)
