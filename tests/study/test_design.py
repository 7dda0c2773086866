"""Participants' plans: Williams squares, balanced conditions, repeats, attention checks."""

from __future__ import annotations

from collections import Counter
from itertools import pairwise
from pathlib import Path

from hypothesis import given
from hypothesis import strategies as st

from emotive.study.config import parse_study
from emotive.study.design import plan_for, williams_square


@given(st.integers(1, 24))
def test_a_williams_square_balances_positions_and_neighbours(n):
    square = williams_square(n)
    rows = len(square)
    assert rows == (n if n % 2 == 0 or n == 1 else 2 * n)
    for row in square:
        assert sorted(row) == list(range(n))
    for column in square.T:
        assert Counter(column.tolist()) == dict.fromkeys(range(n), rows // n)
    pairs = Counter((int(a), int(b)) for row in square for a, b in pairwise(row))
    if n > 1:
        assert set(pairs.values()) == {rows // n}
        assert len(pairs) == n * (n - 1)


def _study(stimuli: int = 5, conditions: int = 2, repeats: int = 2, checks: int = 1):
    data = {
        "title": "t", "consent": "c", "completion_code": "CODE-1", "seed": 3,
        "repeats": repeats,
        "questions": [{"id": "happy", "kind": "likert", "prompt": "?"}],
        "stimuli": [{"id": f"s{i}", "file": f"stimuli/s{i}.glb"} for i in range(stimuli)],
        "conditions": [{"name": f"c{i}"} for i in range(conditions)],
        "attention_checks": [{"id": f"k{i}", "stimulus": "s0", "position": 2 + i,
                              "instruction": "answer 1", "expect": {"happy": 1}}
                             for i in range(checks)],
    }
    return parse_study(Path("/study"), data, Path("/study/study.toml"))


def test_conditions_are_balanced_and_orders_counterbalanced():
    study = _study(stimuli=5, conditions=2, repeats=1, checks=0)
    plans = [plan_for(study, k) for k in range(40)]
    assert Counter(p.condition for p in plans) == {"c0": 20, "c1": 20}
    firsts = Counter(p.items[0].stimulus for p in plans if p.condition == "c0")
    # 20 participants of a condition = two full blocks of the 10-row square: each stimulus
    # opens the sequence 4 times.
    assert set(firsts.values()) == {4}
    assert len({tuple(i.stimulus for i in p.items) for p in plans[:20:2]}) == 10
    assert plan_for(study, 7) == plan_for(study, 7)


def test_repeats_come_after_a_full_pass_and_checks_sit_at_their_positions():
    study = _study(stimuli=4, conditions=1, repeats=2, checks=2)
    plan = plan_for(study, 5)
    assert [i.item for i in plan.items] == list(range(10))
    checks = [i for i in plan.items if i.check]
    assert [(c.item, c.check) for c in checks] == [(2, "k0"), (4, "k1")]
    rated = [i for i in plan.items if not i.check]
    first, second = rated[:4], rated[4:]
    assert {i.repeat for i in first} == {0} and {i.repeat for i in second} == {1}
    assert sorted(i.stimulus for i in first) == sorted(i.stimulus for i in second)
    assert [i.stimulus for i in first] != [i.stimulus for i in second]
