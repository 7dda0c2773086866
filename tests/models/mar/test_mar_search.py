"""The point-cloud distance of equation 1 and the nearest-neighbour search."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.models.mar.search import best_rotation, rigid_distance


def _turn(points: np.ndarray, angle: float, shift: tuple[float, float]) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    x, z = points[..., 0], points[..., 2]
    return np.stack((c * x + s * z + shift[0], points[..., 1], -s * x + c * z + shift[1]), -1)


def _grid_minimum(query, cand, weights) -> float:
    w = weights.reshape(-1) / weights.sum()
    q = query.reshape(-1, 3)
    best = np.inf
    for angle in np.linspace(-np.pi, np.pi, 3601):
        b = _turn(cand.reshape(-1, 3), angle, (0.0, 0.0))
        shift = (w @ q - w @ b) * np.array([1.0, 0.0, 1.0])
        best = min(best, float(w @ ((q - b - shift) ** 2).sum(-1)))
    return best


def test_a_moved_copy_is_at_distance_zero_and_its_rotation_is_found(rng):
    query = rng.normal(size=(4, 6, 3))
    weights = rng.uniform(0.2, 1.0, (4, 6))
    moved = _turn(query, 0.9, (3.0, -2.0))
    assert rigid_distance(query, moved[None], weights)[0] == pytest.approx(0.0, abs=1e-10)
    back = _turn(moved, best_rotation(query, moved, weights), (0.0, 0.0))
    w = weights.reshape(-1) / weights.sum()
    shift = (w @ query.reshape(-1, 3) - w @ back.reshape(-1, 3)) * np.array([1, 0, 1])
    np.testing.assert_allclose(back.reshape(-1, 3) + shift, query.reshape(-1, 3), atol=1e-9)


def test_the_closed_form_equals_a_search_over_rotations(rng):
    query = rng.normal(size=(3, 5, 3))
    cands = rng.normal(size=(4, 3, 5, 3))
    weights = rng.uniform(0.1, 1.0, (3, 5))
    closed = rigid_distance(query, cands, weights)
    grid = [_grid_minimum(query, c, weights) for c in cands]
    np.testing.assert_allclose(closed, grid, rtol=1e-4, atol=1e-8)
    # Not invariant to vertical moves: height matters.
    lifted = query + np.array([0.0, 0.5, 0.0])
    assert rigid_distance(query, lifted[None], weights)[0] == pytest.approx(0.25)


def test_tree_search_finds_the_brute_force_neighbours(mar_db, mar_search):
    db = mar_db
    idx = db.window_index()
    rng = np.random.default_rng(1)
    classes = db.classes_where("walk", None)
    agree = []
    for frame in rng.choice(np.flatnonzero(np.isin(db.frame_class, classes)), 10, replace=False):
        window = db.points[idx[frame]].astype(np.float64) + rng.normal(0, 0.01, (3, 21, 3))
        from emotive.models.mar.representation import heading_of_points

        yaw = heading_of_points(window[-1:], (13, 14), (5, 6))[0]
        fast = mar_search.search(window, yaw, classes)
        slow = mar_search.brute_force(window, classes)
        for c in fast.classes:
            row_f = fast.frames[list(fast.classes).index(c)]
            row_s = slow.frames[list(slow.classes).index(c)]
            agree.append(len(set(row_f) & set(row_s)) / len(row_s))
        # Exact distances are sorted and non-negative.
        assert np.all(np.diff(fast.distances, axis=1) >= 0) and np.all(fast.distances >= 0)
    assert np.mean(agree) > 0.9, np.mean(agree)
