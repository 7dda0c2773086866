"""Tests of :mod:`emotive.eval.metrics` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.core.roles import ROLES, JointRoles
from emotive.eval import metrics as m
from emotive.paths import closest_points
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    euler_to_quaternion,
    quaternion_multiply,
    quaternion_normalize,
)

FPS = 30.0
ROLE_MAP = JointRoles({r: k for k, r in enumerate(ROLES)}, {r: r for r in ROLES}, "test")
IDX = ROLE_MAP.index

# (forward, up, left) offsets of every role from the root's ground point, standing.
_BODY = {
    "root": (0, 0.95, 0), "spine": (0, 1.05, 0), "chest": (0, 1.25, 0), "neck": (0, 1.5, 0),
    "head": (0, 1.6, 0),
    "l_shoulder": (0, 1.45, 0.18), "r_shoulder": (0, 1.45, -0.18),
    "l_elbow": (0, 1.17, 0.18), "r_elbow": (0, 1.17, -0.18),
    "l_wrist": (0, 0.92, 0.18), "r_wrist": (0, 0.92, -0.18),
    "l_handtip": (0, 0.84, 0.18), "r_handtip": (0, 0.84, -0.18),
    "l_hip": (0, 0.95, 0.1), "r_hip": (0, 0.95, -0.1),
    "l_knee": (0.02, 0.5, 0.1), "r_knee": (0.02, 0.5, -0.1),
    "l_ankle": (0, 0.08, 0.1), "r_ankle": (0, 0.08, -0.1),
    "l_toe": (0.15, 0.02, 0.1), "r_toe": (0.15, 0.02, -0.1),
}


def figure(root_xz: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``(T, R, 3)`` stick figure in :data:`ROLES` order, standing over ``(T, 2)`` ground points
    and facing ``(T,)`` headings (radians from +Z towards +X)."""
    fwd = np.stack((np.sin(heading), np.zeros_like(heading), np.cos(heading)), -1)
    left = np.stack((np.cos(heading), np.zeros_like(heading), -np.sin(heading)), -1)
    up = np.array([0.0, 1.0, 0.0])
    off = np.array([_BODY[r] for r in ROLES], dtype=np.float64)
    base = np.stack((root_xz[:, 0], np.zeros(len(root_xz)), root_xz[:, 1]), -1)
    return (base[:, None] + off[:, 0, None] * fwd[:, None] + off[:, 1, None] * up
            + off[:, 2, None] * left[:, None])


def standing(frames: int = 30) -> np.ndarray:
    return figure(np.zeros((frames, 2)), np.zeros(frames))


def unit_quaternions(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return quaternion_normalize(rng.normal(size=(*shape, 4)))


# ------------------------------------------------------------------- pose and rotation errors


def test_identical_motions_have_zero_errors(rng):
    pos = rng.normal(size=(3, 10, 6, 3))
    q = unit_quaternions(rng, (3, 10, 6))
    np.testing.assert_allclose(m.pose_error(pos, pos), 0.0, atol=1e-12)
    np.testing.assert_allclose(m.pose_error(pos, pos, root_index=None), 0.0, atol=1e-12)
    np.testing.assert_allclose(m.rotation_error(q, q), 0.0, atol=1e-5)
    np.testing.assert_allclose(m.rotation_error(-q, q), 0.0, atol=1e-5)
    np.testing.assert_allclose(m.euler_angle_error(q, q, "ZXY"), 0.0, atol=1e-5)
    assert m.pose_error(pos, pos).shape == (3,)
    assert m.rotation_error(q, q, reduction="frame").shape == (3, 10)
    assert m.euler_angle_error(q, q, "XYZ", reduction="none").shape == (3, 10, 6)


def test_pose_error_is_relative_to_the_bounding_box_diagonal():
    # Two joints spanning a 1 x 2 x 2 box: diagonal 3, in every frame, wherever the body is.
    target = np.array([[[0.0, 0, 0], [1, 2, 2]]]).repeat(5, 0)
    target += np.arange(5)[:, None, None] * np.array([10.0, 0, 0])
    assert m.bounding_box_diagonal(target) == pytest.approx(3.0)
    predicted = target.copy()
    predicted[:, 1, 1] += 0.3
    assert m.pose_error(predicted, target) == pytest.approx(0.1)
    # World positions average the root's zero error in.
    assert m.pose_error(predicted, target, root_index=None) == pytest.approx(0.05)
    assert m.pose_error(predicted, target, scale=1.0) == pytest.approx(0.3)
    # A shifted trajectory leaves the root-relative pose error at zero.
    shifted = target + np.array([0.5, 0.0, -0.2])
    assert m.pose_error(shifted, target) == pytest.approx(0.0)
    assert m.pose_error(shifted, target, root_index=None) > 0


@settings(max_examples=40, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1),
    axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
        lambda v: np.linalg.norm(v) > 0.1),
    degrees=st.floats(0.0, 179.5),
)
def test_a_rotation_offset_gives_its_angle(q, axis, degrees):
    q = quaternion_normalize(np.array(q))
    axis = np.array(axis) / np.linalg.norm(axis)
    offset = axis_angle_to_quaternion(axis * np.radians(degrees))
    for predicted in (quaternion_multiply(q, offset), -quaternion_multiply(offset, q)):
        error = m.rotation_error(predicted[None, None], q[None, None])
        assert error == pytest.approx(degrees, abs=1e-6)


def test_euler_error_of_a_known_offset_and_across_the_wrap():
    orders = ["ZXY", "XYZ"]
    true = np.radians([[[30.0, 20.0, -40.0], [179.0, 10.0, 5.0]]])
    pred = true.copy()
    pred[0, 0, 2] += np.radians(10.0)  # third angle of joint 0 off by 10 degrees
    pred[0, 1, 0] = np.radians(-179.0)  # first angle of joint 1 across +-180: 2 degrees off
    qt = np.stack([euler_to_quaternion(true[:, j], o) for j, o in enumerate(orders)], 1)
    qp = np.stack([euler_to_quaternion(pred[:, j], o) for j, o in enumerate(orders)], 1)
    np.testing.assert_allclose(m.euler_angle_error(qp[None], qt[None], orders, reduction="none"),
                               [[[10.0, 2.0]]], atol=1e-6)
    with pytest.raises(ValueError, match="one per joint"):
        m.euler_angle_error(qp, qt, ["ZXY"])


@pytest.mark.parametrize(
    ("fn", "a", "b"),
    [
        (m.pose_error, np.zeros((4, 3, 3)), np.zeros((4, 2, 3))),
        (m.pose_error, np.zeros((4, 3)), np.zeros((4, 3))),
        (m.rotation_error, np.zeros((4, 3, 3)), np.zeros((4, 3, 3))),
        (m.rotation_error, np.ones((2, 3, 4)), np.ones((1, 3, 4))),
    ],
)
def test_errors_reject_bad_shapes(fn, a, b):
    with pytest.raises(ValueError, match="shape"):
        fn(a, b)


# --------------------------------------------------------------------------------- feet


@settings(max_examples=25, deadline=None)
@given(speed=st.floats(0.0, 3.0), direction=st.floats(-np.pi, np.pi))
def test_a_foot_sliding_in_contact_gives_its_speed(speed, direction):
    pos = standing(20)
    t = np.arange(20) / FPS
    slide = speed * t[:, None] * np.array([np.cos(direction), 0.0, np.sin(direction)])
    pos[:, [IDX["l_ankle"], IDX["l_toe"]]] += slide[:, None]
    contacts = np.ones((20, 2), dtype=bool)
    report = m.foot_skating(pos, ROLE_MAP, FPS, contacts=contacts)
    assert report.intervals == 2 * 19
    assert report.mean_speed == pytest.approx(speed / 2, abs=1e-9)
    if abs(speed - m.SKATE_SPEED) > 1e-6:
        assert report.ratio == (0.5 if speed > m.SKATE_SPEED else 0.0)
    only_left = contacts & np.array([True, False])
    assert m.foot_skating(pos, ROLE_MAP, FPS, contacts=only_left).mean_speed == pytest.approx(
        speed, abs=1e-9)


def test_rolling_over_a_planted_toe_is_not_skating():
    pos = standing(20)
    pos[:, IDX["l_ankle"]] += (np.arange(20) * 0.01)[:, None] * np.array([0.0, 1.0, 0.5])
    report = m.foot_skating(pos, ROLE_MAP, FPS, contacts=np.ones((20, 2), dtype=bool))
    assert report.mean_speed == pytest.approx(0.0)


def test_skating_detects_contacts_batched_and_ignores_swing():
    batch = np.stack((standing(30), standing(30)))
    report = m.foot_skating(batch, ROLE_MAP, FPS)
    np.testing.assert_array_equal(report.intervals, [58, 58])
    np.testing.assert_allclose(report.mean_speed, 0.0)
    # A foot moving fast but never in contact does not count.
    pos = standing(30)
    pos[:, IDX["r_toe"]] += (np.arange(30) * 0.1)[:, None] * np.array([1.0, 0.0, 0.0])
    report = m.foot_skating(pos, ROLE_MAP, FPS, contacts=np.zeros((30, 2), dtype=bool))
    assert report.intervals == 0 and report.mean_speed == 0.0 and report.ratio == 0.0
    # The swing that ends in a strike is not sliding: only frame pairs both in contact count.
    pos = standing(30)
    swing = np.minimum(np.arange(30), 10) * 0.05
    pos[:, [IDX["r_ankle"], IDX["r_toe"]], 2] += swing[:, None]
    strike = np.zeros((30, 2), dtype=bool)
    strike[10:, 1] = True
    report = m.foot_skating(pos, ROLE_MAP, FPS, contacts=strike)
    assert report.intervals == 19 and report.mean_speed == 0.0
    with pytest.raises(ValueError, match="contacts"):
        m.foot_skating(pos, ROLE_MAP, FPS, contacts=np.zeros((29, 2), dtype=bool))


def test_ground_penetration_of_a_sinking_toe():
    pos = standing(10)
    pos[5:, IDX["r_toe"], 1] = -0.03
    pos[7, IDX["r_toe"], 1] = -0.05
    report = m.ground_penetration(pos, ROLE_MAP)
    assert report.max == pytest.approx(0.05)
    assert report.mean == pytest.approx((4 * 0.03 + 0.05) / 40)
    assert report.ratio == pytest.approx(5 / 40)
    assert m.ground_penetration(standing(10), ROLE_MAP).max == 0.0


# ------------------------------------------------------------------------ path following

# An L: 4 m along +Z, then a left turn and 3 m along +X.
L_PATH = np.array([[0.0, 0.0], [0.0, 4.0], [0.0, 4.0], [3.0, 4.0]])


def walk_along_l(offset: float, turn: float = 0.0) -> np.ndarray:
    """Root on the L (offset metres to the right of it), facing along it plus ``turn``."""
    s = np.linspace(0.05, 6.95, 50)
    first = s < 4.0
    xz = np.where(first[:, None], np.stack((-offset + 0 * s, s), -1),
                  np.stack((s - 4.0, 4.0 + offset + 0 * s), -1))
    heading = np.where(first, 0.0, np.pi / 2) + turn
    return figure(xz, heading)


def test_walking_on_the_path_has_zero_deviation():
    report = m.path_following(walk_along_l(0.0), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(report.position_deviation, 0.0, atol=1e-12)
    np.testing.assert_allclose(report.heading_deviation, 0.0, atol=1e-6)


def test_a_lateral_offset_and_a_turned_body_give_their_size():
    report = m.path_following(walk_along_l(0.25, turn=np.pi / 2), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(report.position_deviation, 0.25, atol=1e-12)
    np.testing.assert_allclose(report.heading_deviation, 90.0, atol=1e-6)
    backwards = m.path_following(walk_along_l(0.0, turn=np.pi), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(backwards.heading_deviation, 180.0, atol=1e-6)
    batch = m.path_following(np.stack((walk_along_l(0.0), walk_along_l(0.25))), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(batch.position_deviation.mean(-1), [0.0, 0.25], atol=1e-12)


def test_closest_points_on_path():
    distance, nearest, tangent, _ = closest_points(
        np.array([[1.0, 5.0], [-1.0, -1.0], [4.0, 4.0]]), L_PATH)
    np.testing.assert_allclose(distance, [1.0, np.sqrt(2.0), 1.0])
    np.testing.assert_allclose(nearest, [[1.0, 4.0], [0.0, 0.0], [3.0, 4.0]])
    np.testing.assert_allclose(tangent, [[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    with pytest.raises(ValueError, match="non-zero length"):
        closest_points(np.zeros((3, 2)), np.ones((3, 2)))
    with pytest.raises(ValueError, match="polyline"):
        closest_points(np.zeros((3, 2)), np.ones((3, 3)))


# ---------------------------------------------------------------------------- smoothness


def test_constant_velocity_has_zero_jerk_and_a_cubic_its_known_jerk(rng):
    t = np.arange(40) / FPS
    start, velocity = rng.normal(size=(2, 5, 3))
    linear = start + t[:, None, None] * velocity
    np.testing.assert_allclose(m.jerk(linear, FPS), 0.0, atol=1e-6)
    a = np.array([0.5, -2.0, 1.0])
    cubic = np.broadcast_to(a * t[:, None] ** 3, (5, 40, 3)).transpose(1, 0, 2) + linear
    expected = 6.0 * np.linalg.norm(a)
    np.testing.assert_allclose(m.jerk(cubic, FPS), expected, rtol=1e-6)
    assert m.jerk(cubic[None], FPS, per_joint=True).shape == (1, 37, 5)
    with pytest.raises(ValueError, match="4 frame"):
        m.jerk(cubic[:3], FPS)


def sway(frames: int = 180) -> np.ndarray:
    """``(T, 2, 3)``: a fixed joint and one swaying 0.2 m sideways at 0.5 Hz."""
    t = np.arange(frames) / FPS
    pos = np.zeros((frames, 2, 3))
    pos[:, 1, 0] = 0.2 * np.sin(np.pi * t)
    return pos


def test_a_kink_at_an_emotion_change_exceeds_real_jerk_and_a_smooth_change_does_not():
    reference = m.windowed_jerk(sway(), FPS)
    smooth = m.transition_smoothness(sway(), FPS, np.array([75]), reference)
    assert not smooth.exceeds[0]
    assert 0 < smooth.percentile[0] < 50
    kinked = sway()
    kinked[75:, 1, 2] += (np.arange(105) + 1) / FPS  # starts moving at 1 m/s
    report = m.transition_smoothness(kinked, FPS, np.array([75, 0]), reference)
    assert report.exceeds.tolist() == [True, False]
    assert report.percentile[0] == 100.0
    assert report.threshold == pytest.approx(np.percentile(reference, 99))
    with pytest.raises(ValueError, match="change_frames"):
        m.transition_smoothness(kinked, FPS, np.array([180]), reference)


# --------------------------------------------------------------- long-horizon stability


def swinging_arm(amplitude: np.ndarray, frames: int = 300) -> np.ndarray:
    """``(T, 3, 3)``: a root walking at 1 m/s, a joint below it, an arm of 0.4 m swinging at
    1 Hz with per-frame ``amplitude`` (radians)."""
    t = np.arange(frames) / FPS
    theta = amplitude * np.sin(2 * np.pi * t)
    root = np.stack((0 * t, 1.0 + 0 * t, t), -1)
    hip = root + np.array([0.0, -0.1, 0.0])
    hand = hip + 0.4 * np.stack((np.sin(theta), -np.cos(theta), 0 * t), -1)
    return np.stack((root, hip, hand), 1)


PARENTS = [-1, 0, 1]


def test_motion_energy_of_a_joint_at_constant_speed():
    pos = np.zeros((61, 2, 3))
    pos[:, 1, 0] = 2.0 * np.arange(61) / FPS
    np.testing.assert_allclose(m.motion_energy(pos, FPS), [2.0, 2.0])
    np.testing.assert_allclose(m.motion_energy(pos, FPS, root_index=None), [1.0, 1.0])
    assert m.motion_energy(np.stack((pos, pos)), FPS, window_s=0.5).shape == (2, 4)
    with pytest.raises(ValueError, match="window"):
        m.motion_energy(pos[:20], FPS)


def test_a_steady_motion_is_stable():
    report = m.stability_report(swinging_arm(np.full(300, 0.5)), FPS, parents=PARENTS)
    assert report.stable and not report.non_finite
    assert report.energy.shape == (9,)
    np.testing.assert_allclose(report.energy, report.reference_energy, rtol=1e-6)
    assert report.max_bone_ratio == pytest.approx(1.0)


def test_collapse_is_detected_when_the_motion_dies_out_or_freezes():
    amplitude = np.where(np.arange(300) < 150, 0.5, 0.0)
    report = m.stability_report(swinging_arm(amplitude), FPS, parents=PARENTS)
    assert report.collapsed and not report.exploded
    assert report.collapse_time == pytest.approx(5.0)
    frozen = m.stability_report(np.broadcast_to(swinging_arm(np.zeros(1))[:1], (90, 3, 3)), FPS)
    assert frozen.collapsed and frozen.collapse_time == 0.0


def test_explosion_is_detected_from_energy_non_finite_values_and_bones():
    growing = m.stability_report(swinging_arm(0.5 * np.exp(np.arange(300) / FPS / 2)), FPS)
    assert growing.exploded and not growing.collapsed
    assert growing.explosion_time == pytest.approx(4.0)
    for bad in (np.nan, np.inf):
        pos = swinging_arm(np.full(300, 0.5))
        pos[200:, 2] = bad
        report = m.stability_report(pos, FPS, parents=PARENTS)
        assert report.exploded and report.non_finite
        assert report.explosion_time == pytest.approx(200 / FPS)
    pos = swinging_arm(np.full(300, 0.5))
    pos[100:, 2] = pos[100:, 1] + 2.0 * (pos[100:, 2] - pos[100:, 1])
    report = m.stability_report(pos, FPS, parents=PARENTS)
    assert report.exploded and not report.non_finite
    assert report.max_bone_ratio == pytest.approx(2.0)
    assert report.explosion_time == pytest.approx(100 / FPS)


# -------------------------------------------------------------------------- distributions


def test_frechet_distance_of_a_set_with_itself_is_zero(rng):
    a = rng.normal(size=(200, 6)) @ rng.normal(size=(6, 6))
    assert m.frechet_distance(a, a) == pytest.approx(0.0, abs=1e-8)
    # Fewer samples than channels, and a duplicated channel: singular covariances.
    few = rng.normal(size=(5, 12))
    assert m.frechet_distance(few, few) == pytest.approx(0.0, abs=1e-4)
    dup = np.concatenate((a, a[:, :2]), axis=1)
    assert m.frechet_distance(dup, dup) == pytest.approx(0.0, abs=1e-4)
    assert np.isfinite(m.frechet_distance(few, rng.normal(size=(7, 12))))


def test_frechet_distance_of_two_gaussians_matches_the_closed_form(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    var1, var2 = np.array([1.0, 4.0, 0.25]), np.array([2.0, 1.0, 1.0])
    s1, s2 = q @ np.diag(var1) @ q.T, q @ np.diag(var2) @ q.T
    mu1, mu2 = np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0, 2.0])
    expected = 5.0 + np.sum((np.sqrt(var1) - np.sqrt(var2)) ** 2)
    assert m.gaussian_frechet_distance(mu1, s1, mu2, s2) == pytest.approx(expected, rel=1e-9)
    a = rng.multivariate_normal(mu1, s1, size=20000)
    b = rng.multivariate_normal(mu2, s2, size=20000)
    assert m.frechet_distance(a, b) == pytest.approx(expected, rel=0.03)
    with pytest.raises(ValueError, match="channel"):
        m.frechet_distance(a, b[:, :2])


def test_frechet_distance_with_singular_covariances_is_exact(rng):
    zero = np.zeros((2, 2))
    assert m.gaussian_frechet_distance([0, 0], zero, [0, 0], np.diag([1.0, 4.0])) == 5.0
    # Rank one: Tr((v v^T S)^(1/2)) = (v^T S v)^(1/2).
    v = rng.normal(size=3)
    s = np.diag([1.0, 2.0, 3.0])
    expected = v @ v + 6.0 - 2.0 * np.sqrt(v @ s @ v)
    d = m.gaussian_frechet_distance(np.zeros(3), np.outer(v, v), np.zeros(3), s)
    assert d == pytest.approx(expected, rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(m1=st.floats(-10, 10), m2=st.floats(-10, 10), s1=st.floats(0.01, 10),
       s2=st.floats(0.01, 10))
def test_frechet_distance_of_1d_gaussians(m1, m2, s1, s2):
    d = m.gaussian_frechet_distance([m1], [[s1**2]], [m2], [[s2**2]])
    assert d == pytest.approx((m1 - m2) ** 2 + (s1 - s2) ** 2, rel=1e-7, abs=1e-9)
    assert d == pytest.approx(m.gaussian_frechet_distance([m2], [[s2**2]], [m1], [[s1**2]]))


def test_diversity():
    assert m.diversity(np.array([[0.0], [1.0], [3.0]])) == pytest.approx(2.0)
    assert m.diversity(np.zeros((4, 5))) == 0.0
    pos = standing(10)
    shifted = np.stack((pos, pos + np.array([0.3, 0.0, 0.4])))
    assert m.diversity(shifted, points=True) == pytest.approx(0.5)
    assert m.diversity(shifted) == pytest.approx(0.5 * np.sqrt(pos.size / 3))
    with pytest.raises(ValueError, match="N >= 2"):
        m.diversity(np.zeros((1, 3)))
