"""The path bank: many paths packed in one table answer exactly as each path alone."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.paths import circle, figure8, line, waypoints, zigzag
from emotive.paths.bank import PathBank

PATHS = {
    "circle": circle(1.5), "figure8": figure8(2.0), "line": line(5.0), "zigzag": zigzag(),
    "waypoints": waypoints(np.array([[0.0, 0.0], [1.0, 2.0], [3.0, 1.0], [4.0, 4.0]])),
}


def _angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs(np.angle(np.exp(1j * (a - b))))


@settings(max_examples=25, deadline=None)
@given(st.lists(st.sampled_from(sorted(PATHS)), min_size=1, max_size=6),
       st.integers(0, 2**31 - 1))
def test_batched_queries_equal_each_paths_own(names, seed):
    bank = PathBank()
    slots = [bank.add(PATHS[n]) for n in names]
    rng = np.random.default_rng(seed)
    which = rng.integers(0, len(names), 200)
    paths = [PATHS[names[k]] for k in which]
    s = np.array([rng.uniform(-2.0, p.length + 2.0) for p in paths])
    sl = np.array([slots[k] for k in which])
    pos, head, curv = bank.position(sl, s), bank.heading(sl, s), bank.curvature(sl, s)
    for i, p in enumerate(paths):
        assert np.abs(pos[i] - p.position(s[i])).max() < 1e-9
        assert _angle_gap(head[i], p.heading(s[i])) < 1e-9
        assert abs(curv[i] - p.curvature(s[i])) < 1e-7


def test_shared_paths_share_a_slot_and_released_rows_are_compacted():
    bank = PathBank()
    a = bank.add(PATHS["circle"])
    assert bank.add(PATHS["circle"]) == a and len(bank) == 1
    b = bank.add(PATHS["line"])
    bank.release(a)
    assert len(bank) == 2  # still held once
    bank.release(a)
    c = bank.add(PATHS["figure8"])
    bank.release(c)  # dead rows now outnumber live ones: compacted
    assert len(bank) == 1 and bank._used == len(PATHS["line"].arc)
    s = np.linspace(0.0, 5.0, 11)
    np.testing.assert_allclose(bank.position(np.full(11, b), s), PATHS["line"].position(s),
                               atol=1e-12)
    with pytest.raises(KeyError):
        bank.release(a)


def test_adding_a_thousand_paths_is_linear_and_queries_are_vectorized():
    bank = PathBank()
    paths = [circle(1.0 + 0.001 * i) for i in range(1000)]
    slots = np.array([bank.add(p) for p in paths])
    s = np.linspace(0.0, 5.0, 1000)
    xz = bank.position(slots, s)
    assert xz.shape == (1000, 2)
    np.testing.assert_allclose(xz[::97], [p.position(v) for p, v in zip(paths[::97], s[::97],
                                                                          strict=True)], atol=1e-9)


def test_an_open_path_continues_straight_past_both_ends():
    """``ahead`` past an open path's end (and before its start) follows the end tangents."""
    bank = PathBank()
    ell = waypoints(np.array([[0.0, 0.0], [0.0, 5.0], [4.0, 5.0]]))   # north, then east
    slots = np.array([bank.add(line(10.0)), bank.add(ell)])
    offsets = np.array([-2.0, 0.0, 1.5, 6.0])
    # The line (+Z) from its end at 10 m; the L from its end, heading +X.
    points = bank.ahead(slots, np.array([10.0, ell.length]), offsets)
    np.testing.assert_allclose(points[0], [[0, 8.0], [0, 10.0], [0, 11.5], [0, 16.0]],
                               atol=1e-9)
    end = ell.position(ell.length)
    tangent = np.array([np.sin(ell.heading(ell.length)), np.cos(ell.heading(ell.length))])
    for k in (2, 3):
        np.testing.assert_allclose(points[1, k], end + offsets[k] * tangent, atol=1e-9)
    # Before the start: back along the first tangent.
    before = bank.ahead(slots[:1], np.array([0.0]), np.array([-3.0, -0.5]))
    np.testing.assert_allclose(before[0], [[0.0, -3.0], [0.0, -0.5]], atol=1e-9)
