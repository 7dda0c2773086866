"""Calibration of classifier probabilities: temperature scaling and the expected calibration error.

Temperature scaling (Guo et al., "On Calibration of Modern Neural Networks", ICML 2017) divides
the logits by one number ``T`` fitted to minimize the negative log-likelihood of held-out
labels; the ranking of the labels is unchanged, only the confidence moves. The expected
calibration error (ECE) bins the windows by their top probability into ``bins`` equal-width
bins and averages ``|accuracy - confidence|`` over the bins, weighted by their share of the
windows.

Legend: ``N`` windows, ``C`` labels.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import log_softmax, softmax

#: Range searched for the temperature (log-uniform bounds).
TEMPERATURE_RANGE = (0.05, 20.0)


def negative_log_likelihood(logits: np.ndarray, labels: np.ndarray,
                            temperature: float = 1.0) -> float:
    """Mean ``-log p(label)`` of ``(N, C)`` logits divided by ``temperature``."""
    z = log_softmax(np.asarray(logits, dtype=np.float64) / temperature, axis=-1)
    return float(-z[np.arange(len(z)), np.asarray(labels)].mean())


def fit_temperature(logits: np.ndarray, labels: np.ndarray) -> float:
    """The temperature minimizing the held-out negative log-likelihood.

    Args:
        logits: ``(N, C)`` uncalibrated logits of held-out windows.
        labels: ``(N,)`` their true label indices.

    Returns:
        ``T`` in :data:`TEMPERATURE_RANGE` (1.0 when there are no windows).
    """
    logits, labels = np.asarray(logits, dtype=np.float64), np.asarray(labels, dtype=np.int64)
    if not len(labels):
        return 1.0
    low, high = np.log(TEMPERATURE_RANGE)
    best = minimize_scalar(lambda u: negative_log_likelihood(logits, labels, float(np.exp(u))),
                           bounds=(low, high), method="bounded", options={"xatol": 1e-4})
    return float(np.exp(best.x))


def expected_calibration_error(probabilities: np.ndarray, labels: np.ndarray,
                               bins: int = 10) -> float:
    """ECE of ``(N, C)`` probabilities against ``(N,)`` true labels, ``bins`` equal bins.

    Returns:
        The ECE in 0..1 (NaN when there are no windows).
    """
    p = np.asarray(probabilities, dtype=np.float64)
    labels = np.asarray(labels, dtype=np.int64)
    if not len(labels):
        return float("nan")
    confidence = p.max(-1)
    correct = (p.argmax(-1) == labels).astype(np.float64)
    which = np.minimum((confidence * bins).astype(np.int64), bins - 1)
    total = 0.0
    for b in range(bins):
        inside = which == b
        if inside.any():
            total += inside.mean() * abs(correct[inside].mean() - confidence[inside].mean())
    return float(total)


def calibrated(logits: np.ndarray, temperature: float) -> np.ndarray:
    """``(N, C)`` probabilities of logits divided by ``temperature``."""
    return softmax(np.asarray(logits, dtype=np.float64) / temperature, axis=-1)
