"""Tests of :mod:`emotive.eval.stability` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from stick_figures import FPS

from emotive.eval import stability


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
    np.testing.assert_allclose(stability.motion_energy(pos, FPS), [2.0, 2.0])
    np.testing.assert_allclose(stability.motion_energy(pos, FPS, root_index=None), [1.0, 1.0])
    assert stability.motion_energy(np.stack((pos, pos)), FPS, window_s=0.5).shape == (2, 4)
    with pytest.raises(ValueError, match="window"):
        stability.motion_energy(pos[:20], FPS)


def test_a_steady_motion_is_stable():
    report = stability.stability_report(swinging_arm(np.full(300, 0.5)), FPS, parents=PARENTS)
    assert report.stable and not report.non_finite
    assert report.energy.shape == (9,)
    np.testing.assert_allclose(report.energy, report.reference_energy, rtol=1e-6)
    assert report.max_bone_ratio == pytest.approx(1.0)


def test_collapse_is_detected_when_the_motion_dies_out_or_freezes():
    amplitude = np.where(np.arange(300) < 150, 0.5, 0.0)
    report = stability.stability_report(swinging_arm(amplitude), FPS, parents=PARENTS)
    assert report.collapsed and not report.exploded
    assert report.collapse_time == pytest.approx(5.0)
    still = np.broadcast_to(swinging_arm(np.zeros(1))[:1], (90, 3, 3))
    frozen = stability.stability_report(still, FPS)
    assert frozen.collapsed and frozen.collapse_time == 0.0


def test_explosion_is_detected_from_energy_non_finite_values_and_bones():
    growing = stability.stability_report(swinging_arm(0.5 * np.exp(np.arange(300) / FPS / 2)), FPS)
    assert growing.exploded and not growing.collapsed
    assert growing.explosion_time == pytest.approx(4.0)
    for bad in (np.nan, np.inf):
        pos = swinging_arm(np.full(300, 0.5))
        pos[200:, 2] = bad
        report = stability.stability_report(pos, FPS, parents=PARENTS)
        assert report.exploded and report.non_finite
        assert report.explosion_time == pytest.approx(200 / FPS)
    pos = swinging_arm(np.full(300, 0.5))
    pos[100:, 2] = pos[100:, 1] + 2.0 * (pos[100:, 2] - pos[100:, 1])
    report = stability.stability_report(pos, FPS, parents=PARENTS)
    assert report.exploded and not report.non_finite
    assert report.max_bone_ratio == pytest.approx(2.0)
    assert report.explosion_time == pytest.approx(100 / FPS)
