"""Participants' plans: condition, counterbalanced order, repeats and attention checks.

Everything here is a function of the study's seed and the participant's join order ``k``
(0, 1, 2, ... in the order the server admitted them), so the same study gives every
participant the same plan on any machine:

* **Condition** (between-subject): round robin, ``k mod C``, so the groups never differ by
  more than one participant (the random assignment of Carreno-Medrano et al. 2018, section
  7.1.1, balanced).
* **Order** (within-subject): the rows of a Williams design, a Latin square in which every
  stimulus takes every position equally often and follows every other stimulus equally often
  (first-order carry-over balanced; ``n`` rows for an even number of stimuli, ``2 n`` for an
  odd one). The ``m``-th participant of a condition gets row ``π_b(m mod R)``, where
  ``π_b`` is a random permutation of the ``R`` rows drawn from (seed, condition, block
  ``b = m // R``): orders are randomized per participant and balanced over every full block.
  Which stimulus plays which symbol of the square is shuffled once per study and condition.
* **Repeats**: each pass rates every stimulus once before any is shown again (section 7.2.1
  of the same paper); pass ``p`` uses row ``(row + p R / repeats) mod R``, a different order.
* **Attention checks** are inserted into the first pass after their ``position`` items.

Legend: ``n`` stimuli of the condition, ``R`` rows of its square, ``C`` conditions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.study.config import StudyConfig


@dataclass(frozen=True)
class PlanItem:
    """One item of a participant's plan.

    Attributes:
        item: its index in the plan, from 0.
        stimulus: the stimulus shown.
        repeat: the pass it belongs to (0 for the first rating).
        check: the attention check's id, or ``""`` for a rated stimulus.
    """

    item: int
    stimulus: str
    repeat: int = 0
    check: str = ""


@dataclass(frozen=True)
class Plan:
    """What one participant sees.

    Attributes:
        index: the participant's join order ``k``.
        condition: the condition's name.
        render: how their stimuli are drawn.
        items: the items in order.
    """

    index: int
    condition: str
    render: str
    items: tuple[PlanItem, ...]


def williams_square(n: int) -> np.ndarray:
    """The rows of a Williams design for ``n`` treatments.

    Returns:
        ``(R, n)`` int array, ``R = n`` for even ``n`` and ``2 n`` for odd ``n``: every row
        a permutation of ``0..n-1``; every treatment in every column ``R / n`` times; every
        ordered pair of different treatments adjacent ``R / n`` times over the rows.

    Raises:
        ValueError: ``n < 1``.
    """
    if n < 1:
        raise ValueError(f"a Latin square needs at least one treatment, got {n}")
    first = [0]
    low, high = 1, n - 1
    while len(first) < n:
        first.append(low)
        low += 1
        if len(first) < n:
            first.append(high)
            high -= 1
    rows = (np.asarray(first)[None, :] + np.arange(n)[:, None]) % n
    if n % 2 == 1 and n > 1:
        rows = np.concatenate([rows, rows[:, ::-1]])
    return rows


def _rng(seed: int, *keys: int) -> np.random.Generator:
    return np.random.default_rng([seed, *keys])


def plan_for(study: StudyConfig, index: int) -> Plan:
    """The plan of the participant who joined ``index``-th (from 0); see the module docstring.

    Raises:
        ValueError: a negative index.
    """
    if index < 0:
        raise ValueError(f"join order must be 0 or more, got {index}")
    c = index % len(study.conditions)
    condition = study.conditions[c]
    m = index // len(study.conditions)
    stimuli = list(condition.stimuli)
    square = williams_square(len(stimuli))
    rows = len(square)
    symbols = _rng(study.seed, c, 0).permutation(len(stimuli))
    block = _rng(study.seed, c, 1, m // rows).permutation(rows)
    row = int(block[m % rows])
    items: list[PlanItem] = []
    for p in range(study.repeats):
        order = square[(row + p * max(rows // study.repeats, 1)) % rows]
        items.extend(PlanItem(0, stimuli[symbols[s]], repeat=p) for s in order)
    # Ascending positions: the checks already inserted all stand before this one.
    for j, check in enumerate(sorted(study.checks, key=lambda ch: (ch.position, ch.id))):
        items.insert(min(check.position, len(stimuli)) + j,
                     PlanItem(0, check.stimulus, check=check.id))
    numbered = tuple(PlanItem(i, it.stimulus, it.repeat, it.check) for i, it in enumerate(items))
    return Plan(index, condition.name, condition.render, numbered)
