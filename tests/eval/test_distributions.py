"""Tests of :mod:`emotive.eval.distributions` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stick_figures import standing

from emotive.eval import distributions


def test_frechet_distance_of_a_set_with_itself_is_zero(rng):
    a = rng.normal(size=(200, 6)) @ rng.normal(size=(6, 6))
    assert distributions.frechet_distance(a, a) == pytest.approx(0.0, abs=1e-8)
    # Fewer samples than channels, and a duplicated channel: singular covariances.
    few = rng.normal(size=(5, 12))
    assert distributions.frechet_distance(few, few) == pytest.approx(0.0, abs=1e-4)
    dup = np.concatenate((a, a[:, :2]), axis=1)
    assert distributions.frechet_distance(dup, dup) == pytest.approx(0.0, abs=1e-4)
    assert np.isfinite(distributions.frechet_distance(few, rng.normal(size=(7, 12))))


def test_frechet_distance_of_two_gaussians_matches_the_closed_form(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    var1, var2 = np.array([1.0, 4.0, 0.25]), np.array([2.0, 1.0, 1.0])
    s1, s2 = q @ np.diag(var1) @ q.T, q @ np.diag(var2) @ q.T
    mu1, mu2 = np.array([0.0, 1.0, 2.0]), np.array([1.0, -1.0, 2.0])
    expected = 5.0 + np.sum((np.sqrt(var1) - np.sqrt(var2)) ** 2)
    exact = distributions.gaussian_frechet_distance(mu1, s1, mu2, s2)
    assert exact == pytest.approx(expected, rel=1e-9)
    a = rng.multivariate_normal(mu1, s1, size=20000)
    b = rng.multivariate_normal(mu2, s2, size=20000)
    assert distributions.frechet_distance(a, b) == pytest.approx(expected, rel=0.03)
    with pytest.raises(ValueError, match="channel"):
        distributions.frechet_distance(a, b[:, :2])


def test_frechet_distance_with_singular_covariances_is_exact(rng):
    zero = np.zeros((2, 2))
    assert distributions.gaussian_frechet_distance([0, 0], zero, [0, 0], np.diag([1.0, 4.0])) == 5.0
    # Rank one: Tr((v v^T S)^(1/2)) = (v^T S v)^(1/2).
    v = rng.normal(size=3)
    s = np.diag([1.0, 2.0, 3.0])
    expected = v @ v + 6.0 - 2.0 * np.sqrt(v @ s @ v)
    d = distributions.gaussian_frechet_distance(np.zeros(3), np.outer(v, v), np.zeros(3), s)
    assert d == pytest.approx(expected, rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(m1=st.floats(-10, 10), m2=st.floats(-10, 10), s1=st.floats(0.01, 10),
       s2=st.floats(0.01, 10))
def test_frechet_distance_of_1d_gaussians(m1, m2, s1, s2):
    d = distributions.gaussian_frechet_distance([m1], [[s1**2]], [m2], [[s2**2]])
    assert d == pytest.approx((m1 - m2) ** 2 + (s1 - s2) ** 2, rel=1e-7, abs=1e-9)
    assert d == pytest.approx(
        distributions.gaussian_frechet_distance([m2], [[s2**2]], [m1], [[s1**2]])
    )


def test_diversity():
    assert distributions.diversity(np.array([[0.0], [1.0], [3.0]])) == pytest.approx(2.0)
    assert distributions.diversity(np.zeros((4, 5))) == 0.0
    pos = standing(10)
    shifted = np.stack((pos, pos + np.array([0.3, 0.0, 0.4])))
    assert distributions.diversity(shifted, points=True) == pytest.approx(0.5)
    assert distributions.diversity(shifted) == pytest.approx(0.5 * np.sqrt(pos.size / 3))
    with pytest.raises(ValueError, match="N >= 2"):
        distributions.diversity(np.zeros((1, 3)))
