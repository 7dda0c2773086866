"""Distributions of motion features.

:func:`frechet_distance`, :func:`gaussian_frechet_distance` and :func:`diversity`.

Legend: ``C`` channels of a feature vector, ``N`` and ``M`` samples.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import LinAlgError, LinAlgWarning, sqrtm
from scipy.spatial.distance import pdist

__all__ = [
    "diversity",
    "frechet_distance",
    "gaussian_frechet_distance",
]


def _trace_sqrt_product(s1: np.ndarray, s2: np.ndarray) -> float:
    """``Tr((S1 S2)^(1/2))`` for symmetric positive semi-definite ``(C, C)`` matrices."""
    product = s1 @ s2
    with warnings.catch_warnings():
        warnings.simplefilter("error", LinAlgWarning)
        try:
            root = sqrtm(product)
        except (LinAlgWarning, LinAlgError):
            root = None
    if root is not None and np.all(np.isfinite(root)):
        size = max(float(np.abs(root).max()), 1e-300)
        # S1 S2 has real non-negative eigenvalues: an imaginary part above rounding, or a root
        # that does not square back to the product, means sqrtm went wrong on a (near-)singular
        # product rather than found a real answer.
        imaginary = float(np.abs(np.imag(root)).max()) if np.iscomplexobj(root) else 0.0
        residual = np.linalg.norm(root @ root - product)
        if imaginary <= 1e-6 * size and residual <= 1e-8 * max(np.linalg.norm(product), 1e-300):
            return float(np.trace(root).real)
    # (S1 S2)^(1/2) has the eigenvalues of (R S2 R)^(1/2) with R = S1^(1/2): a symmetric form
    # whose eigenvalues are real and which stays exact when a covariance is singular.
    w, v = np.linalg.eigh(s1)
    r = (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T
    inner = r @ s2 @ r
    return float(np.sqrt(np.clip(np.linalg.eigvalsh(0.5 * (inner + inner.T)), 0.0, None)).sum())


def gaussian_frechet_distance(
    mu1: np.ndarray,
    sigma1: np.ndarray,
    mu2: np.ndarray,
    sigma2: np.ndarray,
) -> float:
    """Fréchet (2-Wasserstein squared) distance between two Gaussians.

    ``d = |mu1 - mu2|^2 + Tr(S1 + S2 - 2 (S1 S2)^(1/2))`` with the matrix square root from
    :func:`scipy.linalg.sqrtm`, whose imaginary part from rounding is dropped. When the
    product is (near-)singular and the root is non-finite, has a non-negligible imaginary part
    or does not square back to the product, the trace is taken instead from the symmetric form
    ``Tr((R S2 R)^(1/2))``, ``R = S1^(1/2)``, through eigenvalue decompositions with negative
    rounding errors clipped to 0 (exact for singular covariances, where adding a ridge would
    bias the result by ``O(sqrt(ridge))``). The result is clipped at 0.

    Args:
        mu1: ``(C,)`` mean of the first distribution.
        sigma1: ``(C, C)`` covariance of the first distribution.
        mu2: ``(C,)`` mean of the second distribution.
        sigma2: ``(C, C)`` covariance of the second distribution.

    Returns:
        The squared distance, in squared feature units.

    Raises:
        ValueError: shapes do not agree or values are not finite.
    """
    m1, m2 = (np.atleast_1d(np.asarray(m, dtype=np.float64)) for m in (mu1, mu2))
    s1, s2 = (np.atleast_2d(np.asarray(s, dtype=np.float64)) for s in (sigma1, sigma2))
    c = m1.shape[0]
    if m1.shape != (c,) or m2.shape != (c,) or s1.shape != (c, c) or s2.shape != (c, c):
        raise ValueError(f"means must be (C,) and covariances (C, C) with one C, got "
                         f"{m1.shape}, {s1.shape}, {m2.shape}, {s2.shape}")
    if not all(np.all(np.isfinite(a)) for a in (m1, m2, s1, s2)):
        raise ValueError("means and covariances must be finite")
    s1, s2 = 0.5 * (s1 + s1.T), 0.5 * (s2 + s2.T)
    diff = m1 - m2
    d = diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * _trace_sqrt_product(s1, s2)
    return max(float(d), 0.0)


def _feature_set(x: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 1:
        raise ValueError(f"{name} must have shape (N, C) with N >= 2 samples, got {a.shape}")
    return a


def frechet_distance(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Fréchet distance between two sets of feature vectors (as FID, on motion features).

    Each set is summarized by its mean and covariance (``ddof = 1``) and compared with
    :func:`gaussian_frechet_distance`. With fewer samples than channels the covariances are
    singular (handled exactly), but such estimates are biased, so compare distances computed
    from equal sample counts.

    Args:
        features_a: ``(N, C)`` feature vectors, ``N >= 2``.
        features_b: ``(M, C)`` feature vectors, ``M >= 2``.

    Returns:
        The squared distance, in squared feature units.

    Raises:
        ValueError: bad shapes, different ``C``, or non-finite features.
    """
    a, b = _feature_set(features_a, "features_a"), _feature_set(features_b, "features_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"the sets have different channel counts: {a.shape[1]} and "
                         f"{b.shape[1]}")
    return gaussian_frechet_distance(
        a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False)
    )


def diversity(samples: np.ndarray, points: bool = False) -> float:
    """Mean distance between every pair of samples.

    ``div = 2 / (N (N - 1)) sum_{a < b} d(x_a, x_b)`` with ``d`` the Euclidean distance of the
    flattened samples (feature vectors); with ``points``, samples are arrays of 3D points and
    ``d`` is the mean distance between corresponding points (metres for positions).

    Args:
        samples: ``(N, C)`` feature vectors, or any ``(N, ...)`` array (flattened per sample);
            with ``points``, ``(N, ..., 3)`` such as positions ``(N, T, J, 3)``. ``N >= 2``.
        points: measure distances point by point instead of on the flattened samples.

    Returns:
        The mean pairwise distance.

    Raises:
        ValueError: fewer than two samples, or the last axis is not 3 with ``points``.
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim < 2 or x.shape[0] < 2:
        raise ValueError(f"samples must have shape (N, ...) with N >= 2, got {x.shape}")
    if not points:
        return float(pdist(x.reshape(len(x), -1)).mean())
    if x.ndim < 3 or x.shape[-1] != 3:
        raise ValueError(f"with points=True samples must have shape (N, ..., 3), got {x.shape}")
    flat = x.reshape(len(x), -1, 3)
    # One row of pairs per sample keeps memory at N x points instead of N^2 x points.
    total = sum(
        np.linalg.norm(flat[a + 1 :] - flat[a], axis=-1).mean(-1).sum() for a in range(len(x) - 1)
    )
    return float(total / (len(x) * (len(x) - 1) / 2))
