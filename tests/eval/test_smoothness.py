"""Tests of :mod:`emotive.eval.smoothness` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from stick_figures import FPS

from emotive.eval import smoothness


def test_constant_velocity_has_zero_jerk_and_a_cubic_its_known_jerk(rng):
    t = np.arange(40) / FPS
    start, velocity = rng.normal(size=(2, 5, 3))
    linear = start + t[:, None, None] * velocity
    np.testing.assert_allclose(smoothness.jerk(linear, FPS), 0.0, atol=1e-6)
    a = np.array([0.5, -2.0, 1.0])
    cubic = np.broadcast_to(a * t[:, None] ** 3, (5, 40, 3)).transpose(1, 0, 2) + linear
    expected = 6.0 * np.linalg.norm(a)
    np.testing.assert_allclose(smoothness.jerk(cubic, FPS), expected, rtol=1e-6)
    assert smoothness.jerk(cubic[None], FPS, per_joint=True).shape == (1, 37, 5)
    with pytest.raises(ValueError, match="4 frame"):
        smoothness.jerk(cubic[:3], FPS)


def sway(frames: int = 180) -> np.ndarray:
    """``(T, 2, 3)``: a fixed joint and one swaying 0.2 m sideways at 0.5 Hz."""
    t = np.arange(frames) / FPS
    pos = np.zeros((frames, 2, 3))
    pos[:, 1, 0] = 0.2 * np.sin(np.pi * t)
    return pos


def test_a_kink_at_an_emotion_change_exceeds_real_jerk_and_a_smooth_change_does_not():
    reference = smoothness.windowed_jerk(sway(), FPS)
    smooth = smoothness.transition_smoothness(sway(), FPS, np.array([75]), reference)
    assert not smooth.exceeds[0]
    assert 0 < smooth.percentile[0] < 50
    kinked = sway()
    kinked[75:, 1, 2] += (np.arange(105) + 1) / FPS  # starts moving at 1 m/s
    report = smoothness.transition_smoothness(kinked, FPS, np.array([75, 0]), reference)
    assert report.exceeds.tolist() == [True, False]
    assert report.percentile[0] == 100.0
    assert report.threshold == pytest.approx(np.percentile(reference, 99))
    with pytest.raises(ValueError, match="change_frames"):
        smoothness.transition_smoothness(kinked, FPS, np.array([180]), reference)
