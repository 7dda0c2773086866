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
