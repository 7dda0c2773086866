"""Dynamic time warping and the canonical timeline."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.models.mar.registration import canonical_time, dtw_path, frame_at, register


def _signal(t: np.ndarray) -> np.ndarray:
    return np.stack((np.sin(t), np.cos(2 * t), 0.3 * t), 1)


def test_a_time_warped_copy_is_registered_to_its_warp():
    ref_t = np.linspace(0, 6, 120)
    warp = 6 * (np.linspace(0, 1, 180) ** 1.3)
    tau, cost = register(_signal(warp), _signal(ref_t))
    expected = np.interp(warp, ref_t, np.arange(120))
    assert np.abs(tau - expected).mean() < 1.5
    assert cost < 0.05
    assert np.all(np.diff(tau) > 0)
    np.testing.assert_allclose(frame_at(tau, tau[[10, 50, 100]]), [10, 50, 100], atol=1e-6)


def test_the_path_is_monotone_and_spans_both_sequences(rng):
    a, b = rng.normal(size=(30, 2)), rng.normal(size=(20, 2))
    pa, pb, _ = dtw_path(a, b)
    assert (pa[0], pb[0], pa[-1], pb[-1]) == (0, 0, 29, 19)
    assert np.all(np.diff(pa) >= 0) and np.all(np.diff(pb) >= 0)
    assert np.all(np.diff(pa) + np.diff(pb) >= 1)
    tau = canonical_time(pa, pb, 30)
    assert tau.shape == (30,) and np.all(np.diff(tau) > 0)


def _contacts(strikes_left, strikes_right, frames, stance=8):
    c = np.zeros((frames, 2), dtype=bool)
    for col, strikes in ((0, strikes_left), (1, strikes_right)):
        for s in strikes:
            c[s:s + stance, col] = True
    return c


def test_gait_cycles_give_every_step_the_same_canonical_phase():
    """Regression: warping whole takes of different step counts onto each other matched
    steps with other steps (timing errors of seconds); cycles are matched by foot strikes."""
    from emotive.models.mar.registration import GaitCycle

    ref = _contacts([10, 40, 70, 100], [25, 55, 85], 120)
    cycle = GaitCycle.of(ref)
    assert cycle == GaitCycle(30.0, 15.0)
    # A slower take with more steps, starting on the right foot.
    slow = _contacts([24, 68, 112, 156, 200], [2, 46, 90, 134, 178], 220)
    u = cycle.unwrapped(slow)
    assert u[24] == 0.0 and u[68] == pytest.approx(30.0) and u[46] == pytest.approx(15.0)
    assert np.all(np.diff(u) > 0)
    tau = cycle.wrap(u)
    np.testing.assert_allclose(tau[[24, 68, 112, 156, 200]], 0.0, atol=1e-9)
    np.testing.assert_allclose(tau[[2, 46, 90, 134, 178]], 15.0, atol=1e-9)
    # Two thirds of a canonical frame per frame, also before the first and after the last.
    np.testing.assert_allclose(np.diff(u), 30.0 / 44.0, atol=1e-9)
    assert GaitCycle.of(_contacts([5], [20], 40)) is None
