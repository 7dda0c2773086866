"""The path bank: many paths packed in one table answer exactly as each path alone."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.paths import GroundPath, circle, figure8, line, waypoints, zigzag
from emotive.paths import bank as bank_module
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


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_paths_added_in_one_batch_answer_as_added_one_by_one(seed):
    """``add_many`` (one batch of rows and grids) against ``add`` of each path in turn."""
    rng = np.random.default_rng(seed)
    names = rng.choice(sorted(PATHS), 6)
    polylines = [GroundPath.from_polyline(np.cumsum(rng.normal(size=(int(rng.integers(2, 8)),
                                                                     2)), 0),
                                          closed=bool(rng.integers(2))) for _ in range(6)]
    paths = [PATHS[n] for n in names] + polylines
    one, many = PathBank(), PathBank()
    one.add(line(2.0))
    one.release(one.add(circle(1.0)))
    many.add(line(2.0))
    many.release(many.add(circle(1.0)))
    a = np.array([one.add(p) for p in paths])
    b = np.array(many.add_many(paths + paths[:2]))
    assert b[-2:].tolist() == b[:2].tolist() and len(many) == len(one)
    arc = rng.uniform(-1.0, 8.0, len(paths))
    offsets = np.linspace(-1.0, 2.0, 7)
    np.testing.assert_allclose(many.ahead(b[:len(paths)], arc, offsets),
                               one.ahead(a, arc, offsets), atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_nearest_for_many_paths_at_once_equals_each_paths_own(seed):
    rng = np.random.default_rng(seed)
    paths = [PATHS[n] for n in rng.choice(sorted(PATHS), 4)] + [
        GroundPath.from_polyline(np.cumsum(rng.normal(size=(int(rng.integers(2, 8)), 2)), 0),
                                 closed=bool(rng.integers(2))) for _ in range(4)]
    bank = PathBank()
    slots = np.array(bank.add_many(paths))
    which = rng.integers(0, len(paths), 50)
    xz = rng.uniform(-4.0, 6.0, (50, 2))
    got = bank.nearest(slots[which], xz)
    for i, k in enumerate(which):
        want_arc, want_gap = paths[k].nearest(xz[i])
        at = paths[k].position(got[i])
        assert abs(np.linalg.norm(at - xz[i]) - want_gap) < 1e-9
        # The same arc, or the same point (a loop's first vertex is also its last).
        assert (abs(got[i] - want_arc) < 1e-9
                or np.linalg.norm(at - paths[k].position(want_arc)) < 1e-9)


def test_nearest_in_chunks_answers_as_in_one(monkeypatch):
    """Queries split over several chunks of segments (long paths) give the same arcs."""
    bank = PathBank()
    slots = np.array(bank.add_many([PATHS[n] for n in sorted(PATHS)]))
    rng = np.random.default_rng(0)
    which = slots[rng.integers(0, len(slots), 40)]
    xz = rng.uniform(-4.0, 6.0, (40, 2))
    whole = bank.nearest(which, xz)
    monkeypatch.setattr(bank_module, "NEAREST_CHUNK", 500)
    np.testing.assert_allclose(bank.nearest(which, xz), whole, rtol=0, atol=1e-12)
