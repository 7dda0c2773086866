"""Local Grid Bootstrap on a noisy limit cycle: stays on it, moves around it, reproducible."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.errors import EmotiveError
from emotive.models.lgb.bootstrap import (
    LGBError,
    LocalGridBootstrap,
    TooLittleDataError,
    min_observations,
)

#: Observed angular step of the cycle: one turn every 200 observations.
STEP = 2 * np.pi / 200


def _cycle(n: int = 1200, noise: float = 0.01, seed: int = 0) -> np.ndarray:
    """``(n, 2)`` noisy unit circle, ``n / 200`` turns; closed since 200 divides ``n``."""
    th = np.arange(n) * STEP
    rng = np.random.default_rng(seed)
    return np.stack((np.cos(th), np.sin(th)), 1) + rng.normal(0.0, noise, (n, 2))


@pytest.mark.parametrize("order", [1, 3])
def test_samples_stay_on_the_cycle_and_move_at_its_speed(order):
    boot = LocalGridBootstrap(order=order).fit(_cycle())
    states, index, passengers = boot.sample(3000, np.random.default_rng(1))
    assert states.shape == (3000, 2) and index.shape == (3000,) and passengers is None
    radius = np.linalg.norm(states, axis=1)
    assert np.abs(radius - 1.0).max() < 0.06  # on the circle (noise 0.01)
    angle = np.unwrap(np.arctan2(states[:, 1], states[:, 0]))
    step = np.diff(angle)
    assert 0.85 < step.mean() / STEP < 1.15  # the observed angular speed
    # Not stuck, not running backwards: order 1 knows no direction, so its grid draws may step
    # back a little, but 1-s stretches (30 steps) nearly always and 3-s stretches always advance.
    assert np.mean(angle[30:] > angle[:-30]) > 0.9
    assert np.min(angle[90:] - angle[:-90]) > 0
    # Moves come from nearby observations: no jump across the circle.
    assert np.abs(step).max() < 12 * STEP
    # The drawn observations lie near the generated states.
    assert np.linalg.norm(boot.observed_[index] - states, axis=1).max() < 0.5


def test_reproducible_for_a_seed_and_longer_than_the_observations():
    x = _cycle(600)
    boot = LocalGridBootstrap().fit(x)
    a = boot.sample(2000, np.random.default_rng(7)).states
    b = boot.sample(2000, np.random.default_rng(7)).states
    c = boot.sample(2000, np.random.default_rng(8)).states
    assert len(a) > len(x)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 0.1
    # Not a replay: generated states are barycentres, not observations.
    assert np.min(np.abs(a[:, None, 0] - x[None, :, 0]), axis=1).mean() > 1e-4


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


def test_passengers_follow_the_drawn_cell():
    x = _cycle(600)
    boot = LocalGridBootstrap().fit(x, passengers=-2.0 * x)
    states, _, extra = boot.sample(500, np.random.default_rng(0))
    np.testing.assert_allclose(extra, -2.0 * states, atol=1e-9)


def test_too_little_data_names_the_numbers():
    need = min_observations(3)
    assert need == 203
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
