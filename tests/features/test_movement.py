"""Tests of the movement features: root height, speed, orientation, curvature, stepping."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.roles import ROLES, JointRoles, resolve_roles
from emotive.features.movement import (
    MOVEMENT_FEATURE_NAMES,
    MovementFeatures,
    facing_directions,
    lowpass,
    movement_features,
    stepping_phase,
)
from emotive.io.bvh import read_bvh

PI = np.pi


def ang(theta: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to ``(-pi, pi]``, so that phases near 0 and 2 pi compare as close."""
    return np.angle(np.exp(1j * np.asarray(theta)))
ROLE_INDEX = JointRoles({r: k for k, r in enumerate(ROLES)}, {}, "test")


def body_on_path(root: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """``(T, R, 3)`` positions: a rigid upright body at ``root (T, 3)`` facing ``(T, 2)`` (x, z).

    Left is ``(f_z, -f_x)``: with Y up, a body facing +Z has its left at +X.
    """
    facing = facing / np.linalg.norm(facing, axis=1, keepdims=True)
    left = np.stack((facing[:, 1], np.zeros(len(facing)), -facing[:, 0]), 1)
    fwd = np.stack((facing[:, 0], np.zeros(len(facing)), facing[:, 1]), 1)
    up = np.array([0.0, 1.0, 0.0])
    offsets = {
        "root": (0, 0, 0), "spine": (0, 0.1, 0), "chest": (0, 0.3, 0), "neck": (0, 0.55, 0),
        "head": (0, 0.7, 0), "l_shoulder": (0.18, 0.5, 0), "r_shoulder": (-0.18, 0.5, 0),
        "l_elbow": (0.2, 0.22, 0), "r_elbow": (-0.2, 0.22, 0),
        "l_wrist": (0.2, -0.03, 0), "r_wrist": (-0.2, -0.03, 0),
        "l_handtip": (0.2, -0.1, 0), "r_handtip": (-0.2, -0.1, 0),
        "l_hip": (0.1, 0, 0), "r_hip": (-0.1, 0, 0), "l_knee": (0.1, -0.45, 0.02),
        "r_knee": (-0.1, -0.45, 0.02), "l_ankle": (0.1, -0.85, 0), "r_ankle": (-0.1, -0.85, 0),
        "l_toe": (0.1, -0.92, 0.15), "r_toe": (-0.1, -0.92, 0.15),
    }
    o = np.array([offsets[r] for r in ROLES])
    return (
        root[:, None]
        + o[None, :, 0:1] * left[:, None]
        + o[None, :, 1:2] * up
        + o[None, :, 2:3] * fwd[:, None]
    )


def features_on_path(root: np.ndarray, facing: np.ndarray, fps: float = 30.0) -> MovementFeatures:
    contacts = np.zeros((len(root), 2), dtype=bool)
    return movement_features(body_on_path(root, facing), ROLE_INDEX, fps, contacts=contacts)


class TestRootFeatures:
    @pytest.mark.parametrize("heading", [0.0, 0.7, -2.5])
    @pytest.mark.parametrize("speed", [0.5, 1.4])
    def test_straight_line(self, heading, speed):
        fps, n = 30.0, 90
        d = np.array([np.sin(heading), 0.0, np.cos(heading)])
        root = np.array([1.0, 0.9, -2.0]) + (speed / fps) * np.arange(n)[:, None] * d
        f = features_on_path(root, np.tile(d[[0, 2]], (n, 1)), fps)
        np.testing.assert_allclose(f.root_speed, speed / fps, rtol=1e-9)
        np.testing.assert_allclose(f.root_speed_lowpass, speed / fps, rtol=1e-9)
        np.testing.assert_allclose(f.curvature, 0.0, atol=1e-12)
        np.testing.assert_allclose(f.orientation_difference, 0.0, atol=1e-6)
        np.testing.assert_allclose(f.root_height, 0.0, atol=1e-12)

    @pytest.mark.parametrize(("turn", "delta"), [(PI, PI), (PI / 2, PI / 2), (-PI / 2, PI / 2)])
    def test_walking_backwards_and_sideways(self, turn, delta):
        n = 30
        root = np.zeros((n, 3))
        root[:, 2] = 0.04 * np.arange(n)
        facing = np.tile([np.sin(turn), np.cos(turn)], (n, 1))
        f = features_on_path(root, facing)
        np.testing.assert_allclose(f.orientation_difference, delta, atol=1e-6)

    @pytest.mark.parametrize("radius", [0.5, 3.0])
    @pytest.mark.parametrize("step", [0.01, 0.05, -0.03])
    def test_circle(self, radius, step):
        n = 120
        a = step * np.arange(n)  # angle of the root on the circle, radians per frame
        root = np.stack((radius * np.cos(a), np.full(n, 0.9), radius * np.sin(a)), 1)
        tangent = np.sign(step) * np.stack((-np.sin(a), np.cos(a)), 1)
        f = features_on_path(root, tangent)
        w = abs(step)
        np.testing.assert_allclose(f.root_speed, 2 * radius * np.sin(w / 2), rtol=1e-9)
        np.testing.assert_allclose(f.curvature, 4 * radius * np.sin(w / 2) ** 2, rtol=1e-7)
        # A backward chord meets the tangent at its end at half the turned angle.
        np.testing.assert_allclose(f.orientation_difference, w / 2, atol=1e-7)

    def test_root_height_deviation(self):
        n = 60
        y = 0.9 + 0.03 * np.sin(2 * PI * np.arange(n) / 15)
        root = np.stack((np.zeros(n), y, 0.04 * np.arange(n)), 1)
        f = features_on_path(root, np.tile([0.0, 1.0], (n, 1)))
        np.testing.assert_allclose(f.root_height, y - y.mean(), atol=1e-12)
        assert abs(f.root_height.mean()) < 1e-12

    def test_standing_still_has_no_orientation_difference(self):
        rng = np.random.default_rng(1)
        root = np.array([0.0, 0.9, 0.0]) + rng.normal(0, 1e-4, (30, 3))
        f = features_on_path(root, np.tile([1.0, 0.0], (30, 1)))
        assert np.all(f.orientation_difference == 0.0)

    def test_facing_from_hips_and_shoulders(self):
        root = np.zeros((3, 3))
        facing = np.array([[0.0, 1.0], [1.0, 0.0], [-0.6, -0.8]])
        got = facing_directions(body_on_path(root, facing), ROLE_INDEX)
        np.testing.assert_allclose(got, facing)


class TestLowpass:
    def test_removes_the_step_sway(self):
        fps = 30.0
        t = np.arange(300) / fps
        speed = 0.04 + 0.01 * np.sin(2 * PI * 2.0 * t)
        out = lowpass(speed, fps)
        assert np.abs(out[30:-30] - 0.04).max() < 0.001

    def test_short_or_unfilterable_signals_pass_through(self):
        x = np.array([1.0, 2.0])
        np.testing.assert_array_equal(lowpass(x, 30.0), x)
        y = np.arange(10.0)
        np.testing.assert_array_equal(lowpass(y, 1.5, cutoff_hz=1.0), y)
        assert lowpass(np.arange(5.0), 30.0).shape == (5,)


def contacts_from_strikes(n: int, left: list[int], right: list[int], hold: int = 5) -> np.ndarray:
    c = np.zeros((n, 2), dtype=bool)
    for foot, frames in enumerate((left, right)):
        for s in frames:
            c[s:s + hold, foot] = True
    return c


class TestSteppingPhase:
    def test_linear_between_strikes_with_documented_edges(self):
        n = 100
        theta = stepping_phase(contacts_from_strikes(n, [20, 50], [35, 65]))
        assert ang(theta[20]) == pytest.approx(0.0) and ang(theta[50]) == pytest.approx(0.0)
        assert theta[35] == pytest.approx(PI) and theta[65] == pytest.approx(PI)
        assert theta[27] == pytest.approx(PI * 7 / 15)
        assert theta[60] == pytest.approx(PI * 10 / 15)
        # Before the first strike: one half-period (15 frames) at the same rate, then held.
        assert theta[10] == pytest.approx(2 * PI - PI * 10 / 15)
        np.testing.assert_allclose(theta[:6], 2 * PI - PI)
        # After the last strike: the same for 15 frames, then held at 2 pi - 0.
        assert theta[70] == pytest.approx(PI + PI * 5 / 15)
        np.testing.assert_allclose(ang(theta[80:]), 0.0, atol=1e-12)
        assert np.all((theta >= 0) & (theta < 2 * PI))

    def test_frequency_wraps(self):
        n = 100
        contacts = contacts_from_strikes(n, [10, 40, 70], [25, 55, 85])
        positions = body_on_path(np.zeros((n, 3)), np.tile([0.0, 1.0], (n, 1)))
        f = movement_features(positions, ROLE_INDEX, 30.0, contacts=contacts)
        # Constant pi / 15 per frame across the 2 pi -> 0 wrap, for up to 15 frames outside.
        np.testing.assert_allclose(f.step_frequency[:], PI / 15, atol=1e-12)
        assert np.all(f.step_frequency > -PI) and np.all(f.step_frequency <= PI)

    def test_missed_strike_spans_a_full_cycle(self):
        theta = stepping_phase(contacts_from_strikes(80, [10, 40], []))
        assert theta[25] == pytest.approx(PI)  # halfway through a whole 2 pi
        assert ang(theta[10]) == pytest.approx(0.0)

    def test_without_two_strikes_the_phase_is_constant(self):
        np.testing.assert_array_equal(stepping_phase(np.zeros((20, 2), dtype=bool)), 0.0)
        one = stepping_phase(contacts_from_strikes(20, [], [8]))
        np.testing.assert_allclose(one, PI)
        # A foot down from the first frame has not struck.
        np.testing.assert_array_equal(stepping_phase(np.ones((20, 2), dtype=bool)), 0.0)

    def test_simultaneous_strikes_are_finite(self):
        theta = stepping_phase(contacts_from_strikes(30, [10], [10]))
        assert np.isfinite(theta).all()


class TestMovementFeatures:
    def test_names_match_the_fields(self, stick_walk):
        p, roles, _ = stick_walk(frames=40)
        f = movement_features(p, roles, 30.0)
        assert f.names == MOVEMENT_FEATURE_NAMES
        assert f.as_array().shape == (40, len(MOVEMENT_FEATURE_NAMES))
        np.testing.assert_array_equal(f.as_array()[:, 3], f.orientation_difference)

    def test_stick_walk_end_to_end(self, stick_walk):
        p, roles, truth = stick_walk(frames=150, step_hz=2.0, speed=1.2, heading=1.0)
        f = movement_features(p, roles, 30.0)
        np.testing.assert_allclose(f.root_speed, 1.2 / 30, rtol=1e-9)
        np.testing.assert_allclose(f.orientation_difference, 0.0, atol=1e-6)
        # 2 steps per second: pi per 15 frames once stepping.
        assert np.median(f.step_frequency) == pytest.approx(PI / 15, rel=1e-6)
        lefts = np.flatnonzero(truth["strikes"][:, 0])
        assert np.all(np.abs(ang(f.step_phase[lefts])) < PI / 15 * 2)

    def test_tiny_clips(self, stick_walk):
        for n in (1, 2):
            p, roles, _ = stick_walk(frames=n)
            a = movement_features(p, roles, 30.0).as_array()
            assert a.shape == (n, 7) and np.isfinite(a).all()

    def test_bad_contacts_shape(self, stick_walk):
        p, roles, _ = stick_walk(frames=10)
        with pytest.raises(ValueError, match="contacts"):
            movement_features(p, roles, 30.0, contacts=np.zeros((9, 2), dtype=bool))


@pytest.mark.data
def test_real_walk_back_faces_away_from_travel(walk_dir):
    for name, expected in (("walk_normal_001", 0.0), ("walk-back_normal_001", PI)):
        motion = read_bvh(walk_dir / f"dataset-1_{name}.bvh")
        f = movement_features(
            motion.positions_with_end_sites(), resolve_roles(motion.skeleton), motion.fps
        )
        assert np.median(f.orientation_difference) == pytest.approx(expected, abs=0.15), name
        assert f.root_speed_lowpass.mean() * motion.fps > 0.8  # metres per second
