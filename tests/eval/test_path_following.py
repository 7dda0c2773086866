"""Tests of :mod:`emotive.eval.path_following` on hand-built synthetic walks with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from stick_figures import ROLE_MAP, figure

from emotive.eval import path_following
from emotive.paths import closest_points

# An L: 4 m along +Z, then a left turn and 3 m along +X.
L_PATH = np.array([[0.0, 0.0], [0.0, 4.0], [0.0, 4.0], [3.0, 4.0]])


def walk_along_l(offset: float, turn: float = 0.0) -> np.ndarray:
    """Root on the L (offset metres to the right of it), facing along it plus ``turn``."""
    s = np.linspace(0.05, 6.95, 50)
    first = s < 4.0
    xz = np.where(first[:, None], np.stack((-offset + 0 * s, s), -1),
                  np.stack((s - 4.0, 4.0 + offset + 0 * s), -1))
    heading = np.where(first, 0.0, np.pi / 2) + turn
    return figure(xz, heading)


def test_walking_on_the_path_has_zero_deviation():
    report = path_following.path_following(walk_along_l(0.0), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(report.position_deviation, 0.0, atol=1e-12)
    np.testing.assert_allclose(report.heading_deviation, 0.0, atol=1e-6)


def test_a_lateral_offset_and_a_turned_body_give_their_size():
    report = path_following.path_following(walk_along_l(0.25, turn=np.pi / 2), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(report.position_deviation, 0.25, atol=1e-12)
    np.testing.assert_allclose(report.heading_deviation, 90.0, atol=1e-6)
    backwards = path_following.path_following(walk_along_l(0.0, turn=np.pi), ROLE_MAP, L_PATH)
    np.testing.assert_allclose(backwards.heading_deviation, 180.0, atol=1e-6)
    both = np.stack((walk_along_l(0.0), walk_along_l(0.25)))
    batch = path_following.path_following(both, ROLE_MAP, L_PATH)
    np.testing.assert_allclose(batch.position_deviation.mean(-1), [0.0, 0.25], atol=1e-12)


def test_closest_points_on_path():
    distance, nearest, tangent, _ = closest_points(
        np.array([[1.0, 5.0], [-1.0, -1.0], [4.0, 4.0]]), L_PATH)
    np.testing.assert_allclose(distance, [1.0, np.sqrt(2.0), 1.0])
    np.testing.assert_allclose(nearest, [[1.0, 4.0], [0.0, 0.0], [3.0, 4.0]])
    np.testing.assert_allclose(tangent, [[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    with pytest.raises(ValueError, match="non-zero length"):
        closest_points(np.zeros((3, 2)), np.ones((3, 2)))
    with pytest.raises(ValueError, match="polyline"):
        closest_points(np.zeros((3, 2)), np.ones((3, 3)))
