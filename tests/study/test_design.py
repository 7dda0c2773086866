"""Participants' plans: Williams squares, balanced conditions, repeats, attention checks."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import Counter
from itertools import pairwise
from pathlib import Path

import pytest
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


def _study(stimuli: int = 5, conditions: int = 2, repeats: int = 2, checks: int = 1,
           seed: int = 3):
    data = {
        "title": "t", "consent": "c", "completion_code": "CODE-1", "seed": seed,
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


def _orders(study, participants) -> list[list[str]]:
    return [[i.stimulus for i in plan_for(study, k).items] for k in participants]


def test_the_seed_alone_fixes_the_orders_and_another_seed_gives_others():
    orders = _orders(_study(seed=3), range(40))
    assert _orders(_study(seed=3), range(40)) == orders  # a fresh study of the same seed
    # Another interpreter, with another string hashing: nothing but the seed decides.
    code = ("import json, sys; sys.path.insert(0, sys.argv[1]); import test_design as t; "
            "print(json.dumps(t._orders(t._study(seed=3), range(40))))")
    done = subprocess.run([sys.executable, "-c", code, str(Path(__file__).parent)],
                          capture_output=True, text=True, check=True,
                          env={**os.environ, "PYTHONHASHSEED": "12345"})
    assert json.loads(done.stdout) == orders
    other = _orders(_study(seed=4), range(40))
    assert other != orders
    assert sorted(map(tuple, other)) != sorted(map(tuple, orders)), "the symbols shuffle too"


@pytest.mark.parametrize("stimuli", [4, 5])
def test_every_block_of_participants_balances_positions_and_neighbours_exactly(stimuli):
    study = _study(stimuli=stimuli, conditions=2, repeats=1, checks=0)
    rows = len(williams_square(stimuli))
    each = rows // stimuli
    blocks = {}
    for c, condition in enumerate(study.conditions):
        for block in range(2):
            joined = [c + 2 * m for m in range(block * rows, (block + 1) * rows)]
            assert {plan_for(study, k).condition for k in joined} == {condition.name}
            orders = _orders(study, joined)
            assert len({tuple(o) for o in orders}) == rows, "every row of the square once"
            for position in range(stimuli):
                assert Counter(o[position] for o in orders) == dict.fromkeys(
                    condition.stimuli, each)
            pairs = Counter(pair for o in orders for pair in pairwise(o))
            assert len(pairs) == stimuli * (stimuli - 1) and set(pairs.values()) == {each}
            blocks[c, block] = orders
    # Each block draws its own order of the rows.
    assert blocks[0, 0] != blocks[0, 1] and sorted(blocks[0, 0]) == sorted(blocks[0, 1])


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
