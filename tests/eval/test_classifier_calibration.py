"""Temperature scaling and the expected calibration error of the classifier's probabilities."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.eval.calibration import (
    TEMPERATURE_RANGE,
    calibrated,
    expected_calibration_error,
    fit_temperature,
    negative_log_likelihood,
)


def sampled(rng: np.random.Generator, n: int, temperature: float) -> tuple[np.ndarray, ...]:
    """Logits and labels drawn from softmax(logits / temperature): calibrated at that T."""
    logits = rng.normal(0.0, 3.0, (n, 4))
    p = calibrated(logits, temperature)
    labels = (rng.random((n, 1)) > np.cumsum(p, -1)).sum(-1)
    return logits, np.minimum(labels, 3)


def test_fit_temperature_recovers_the_true_temperature_and_lowers_the_nll():
    rng = np.random.default_rng(0)
    for true in (0.5, 2.5):
        logits, labels = sampled(rng, 8000, true)
        t = fit_temperature(logits, labels)
        assert t == pytest.approx(true, rel=0.1)
        assert (negative_log_likelihood(logits, labels, t)
                < negative_log_likelihood(logits, labels, 1.0))
    assert fit_temperature(np.zeros((0, 4)), np.zeros(0, dtype=int)) == 1.0
    # Separable data wants a sharp temperature, down to the range's floor at most.
    logits = np.eye(4)[np.arange(40) % 4] * 5.0
    assert TEMPERATURE_RANGE[0] <= fit_temperature(logits, np.arange(40) % 4) < 0.2


def test_ece_is_small_when_calibrated_and_large_when_overconfident():
    rng = np.random.default_rng(1)
    logits, labels = sampled(rng, 20000, 2.0)
    assert expected_calibration_error(calibrated(logits, 2.0), labels) < 0.02
    over = expected_calibration_error(calibrated(logits, 0.3), labels)
    assert over > 0.15
    after = expected_calibration_error(calibrated(logits, fit_temperature(logits, labels)),
                                       labels)
    assert after < 0.02


def test_ece_by_hand():
    # Two bins used: 0.9 confident and right, 0.6 confident and wrong.
    p = np.array([[0.9, 0.1], [0.9, 0.1], [0.6, 0.4], [0.4, 0.6]])
    labels = np.array([0, 0, 1, 0])
    # bin 9: confidence 0.9, accuracy 1 (gap 0.1); bin 6: confidence 0.6, accuracy 0 (0.6).
    assert expected_calibration_error(p, labels) == pytest.approx(0.5 * 0.1 + 0.5 * 0.6)
    assert np.isnan(expected_calibration_error(np.zeros((0, 2)), np.zeros(0, dtype=int)))
