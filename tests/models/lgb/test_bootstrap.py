"""Local Grid Bootstrap on synthetic cycles and swings: speed, stalling, drift, reproducibility."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.errors import EmotiveError
from emotive.models.lgb.bootstrap import (
    LGBError,
    LocalGridBootstrap,
    TooLittleDataError,
    carry_offsets,
    min_observations,
)

#: Observed angular step of the cycle: one turn every 200 observations.
STEP = 2 * np.pi / 200


def _cycle(n: int = 1200, noise: float = 0.01, seed: int = 0) -> np.ndarray:
    """``(n, 2)`` noisy unit circle, ``n / 200`` turns; closed since 200 divides ``n``."""
    th = np.arange(n) * STEP
    rng = np.random.default_rng(seed)
    return np.stack((np.cos(th), np.sin(th)), 1) + rng.normal(0.0, noise, (n, 2))


def _swing(n: int = 1200, period: int = 60, seed: int = 0) -> np.ndarray:
    """``(n, 2)`` a periodic back-and-forth walk along a line: the forward and the backward pass
    go through the same positions (a limb swinging), with a little noise; closed."""
    t = np.arange(n)
    rng = np.random.default_rng(seed)
    s = np.sin(2 * np.pi * t / period)
    return np.stack((s, 0.2 * s), 1) + rng.normal(0.0, 0.005, (n, 2))


def _steps(x: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.diff(x, axis=0), axis=1)


@pytest.mark.parametrize("order", [1, 3])
def test_samples_stay_on_the_cycle_and_move_at_its_speed(order):
    boot = LocalGridBootstrap(order=order).fit(_cycle())
    states, index, passengers = boot.sample(3000, np.random.default_rng(1))
    assert states.shape == (3000, 2) and index.shape == (3000,) and passengers is None
    radius = np.linalg.norm(states, axis=1)
    assert np.abs(radius - 1.0).max() < 0.1  # on the circle (noise 0.01 per coordinate)
    angle = np.unwrap(np.arctan2(states[:, 1], states[:, 0]))
    step = np.diff(angle)
    assert 0.85 < step.mean() / STEP < 1.15  # the observed angular speed
    # Never stuck, never running backwards over a third of a second.
    assert np.min(angle[10:] - angle[:-10]) > 0
    # Moves come from nearby observations: no jump across the circle.
    assert np.abs(step).max() < 12 * STEP
    # The drawn observations lie near the generated states.
    assert np.linalg.norm(boot.observed_[index] - states, axis=1).max() < 0.1


def _reversals_per_second(x: np.ndarray) -> float:
    """Sign changes of the first coordinate's velocity per 30 frames."""
    return float(np.mean(np.diff(np.sign(np.diff(x[:, 0]))) != 0) * 30)


def _coverage(x: np.ndarray, frames: int = 60) -> float:
    """5th percentile over ``frames``-frame windows of the first coordinate's range."""
    windows = np.lib.stride_tricks.sliding_window_view(x[:, 0], frames)
    return float(np.percentile(np.ptp(windows, axis=1), 5))


def test_a_periodic_swing_keeps_its_step_size_where_the_papers_barycentre_stalls():
    x = _swing()
    real = _steps(np.concatenate((x, x[:1]))).mean()
    s = LocalGridBootstrap(order=2, lag=5).fit(x).sample(4000, np.random.default_rng(0)).states
    paper = LocalGridBootstrap(order=1, rule="barycentre", carry=0.0).fit(x)
    p = paper.sample(1000, np.random.default_rng(0)).states
    print(f"step vs observed: successor {_steps(s).mean() / real:.2f}, paper "
          f"{_steps(p).mean() / real:.2f}; reversals/s: observed {_reversals_per_second(x):.1f},"
          f" successor {_reversals_per_second(s):.1f}, paper {_reversals_per_second(p):.1f}; "
          f"2-s range: successor {_coverage(s):.2f}, paper {_coverage(p):.2f}")
    assert 0.85 < _steps(s).mean() / real < 1.15
    # It swings like the data: a full swing (range 2) in every 2 s, reversing at the ends only.
    assert _coverage(s) > 1.5
    assert _reversals_per_second(s) < 1.5 * _reversals_per_second(x)
    # The paper's barycentre, on the same data, jitters in place: the stall it replaces.
    assert _coverage(p) < 0.5
    assert _reversals_per_second(p) > 3 * _reversals_per_second(x)
    # No drift over the run: the last quarter stays as close to the data as the first.
    near = np.min(np.abs(s[:, None, 0] - x[None, :, 0]), axis=1)
    assert near[-1000:].mean() < 2 * near[:1000].mean() + 1e-3
    assert np.abs(s).max() < 1.1


def test_jump_probabilities_are_symmetric_so_frames_are_visited_uniformly():
    boot = LocalGridBootstrap(order=2, lag=5).fit(_swing(600))
    n = len(boot.observed_)
    p = np.zeros((n, n))
    for i in range(n):
        a, b = boot.pointers_[i], boot.pointers_[i + 1]
        p[i, boot.candidates_[a:b]] += np.diff(boot.cumulative_[a:b], prepend=0.0)
    np.testing.assert_allclose(p.sum(1), 1.0)
    jumps = p - np.diag(np.diag(p))
    np.testing.assert_allclose(jumps, jumps.T, atol=1e-12)
    assert 0.0 < jumps.sum(1).mean() < 1.0
    # The chain i -> successor of the drawn frame keeps the uniform distribution.
    successor = np.roll(p, 1, axis=1)
    np.testing.assert_allclose(np.full(n, 1.0 / n) @ successor, 1.0 / n, atol=1e-12)


def test_reproducible_for_a_seed_and_longer_than_the_observations():
    x = _cycle(600)
    boot = LocalGridBootstrap().fit(x)
    a = boot.sample(2000, np.random.default_rng(7)).states
    b = boot.sample(2000, np.random.default_rng(7)).states
    c = boot.sample(2000, np.random.default_rng(8)).states
    assert len(a) > len(x)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.1
    assert boot.sample(0, np.random.default_rng(0)).states.shape == (0, 2)


def test_carry_offsets_follow_the_recurrence_and_fade():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(50, 3))
    index = np.array([11, 12, 30, 31, 32, 33, 5, 6])
    out = carry_offsets(values, index, 0.9, start=10)
    cur = values[10]
    for t, i in enumerate(index):
        cur = values[i] + 0.9 * (cur - values[i - 1])
        np.testing.assert_allclose(out[t], cur)
    np.testing.assert_array_equal(carry_offsets(values, index, 0.0, 10), values[index])
    # Along a passage the offset only decays.
    o = out - values[index]
    np.testing.assert_allclose(o[3:6], o[2] * 0.9 ** np.arange(1, 4)[:, None])


def test_neighbourhood_keeps_50_to_100_states():
    rng = np.random.default_rng(3)
    # Uneven density: a dense cluster and a sparse spread, so the clipping acts both ways.
    x = np.concatenate((rng.normal(0, 0.05, (400, 3)), rng.normal(0, 2.0, (400, 3))))
    boot = LocalGridBootstrap().fit(x)
    counts = []
    for state in np.concatenate((boot.states_[::7], rng.normal(0, 3.0, (50, 3)))):
        idx, dist, radius = boot.neighbourhood(state)
        counts.append(len(idx))
        assert np.all(dist <= radius)
    assert 50 <= min(counts) and max(counts) <= 100
    assert min(counts) < max(counts)  # the radius adapts (fixed where density is typical)


@pytest.mark.parametrize("rule", ["successor", "barycentre"])
def test_passengers_follow_the_drawn_observations(rule):
    x = _cycle(600)
    boot = LocalGridBootstrap(rule=rule, carry=0.0 if rule == "barycentre" else 0.9).fit(
        x, passengers=-2.0 * x
    )
    states, _, extra = boot.sample(500, np.random.default_rng(0))
    np.testing.assert_allclose(extra, -2.0 * states, atol=1e-9)


def test_too_little_data_names_the_numbers():
    need = min_observations(3)
    assert need == 203 and min_observations(2, lag=5) == 206
    with pytest.raises(TooLittleDataError, match=r"has 150 frames but at least 203") as err:
        LocalGridBootstrap(order=3).fit(_cycle(150), name="emotion sad")
    assert isinstance(err.value, EmotiveError)
    assert (err.value.have, err.value.need) == (150, 203)


def test_nan_and_bad_input_raise_typed_errors():
    x = _cycle(600)
    x[[5, 17]] = np.nan
    with pytest.raises(LGBError, match=r"NaN or infinite values at 2 frames \(5, 17\)"):
        LocalGridBootstrap().fit(x)
    with pytest.raises(LGBError, match=r"shape \(N, D\)"):
        LocalGridBootstrap().fit(np.zeros(600))
    with pytest.raises(LGBError, match="fit the bootstrap"):
        LocalGridBootstrap().sample(3, np.random.default_rng(0))
    with pytest.raises(LGBError, match="k_min <= k_max"):
        LocalGridBootstrap(k_min=120)
    with pytest.raises(LGBError, match="rule in"):
        LocalGridBootstrap(rule="nearest")
    with pytest.raises(LGBError, match=">= 0"):
        LocalGridBootstrap().fit(_cycle(600)).sample(-1, np.random.default_rng(0))
