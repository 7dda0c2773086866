"""Fair turns of commands, the join estimate and the scene's spare time for the preparer."""

from __future__ import annotations

import threading
from concurrent.futures import Future

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.models.gait.generate import GaitFrame
from emotive.serve.limits import WorkBudget
from emotive.serve.messages import Command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation
from emotive.serve.turns import FIRST_JOIN, JOIN_SCALE, JoinCosts, Pending, Turns, share

#: Wall seconds a wait may take before it counts as a hang.
HANG = 120.0


def _item(kind: str, client: int, budget: WorkBudget | None = None, agent: int = 0) -> Pending:
    return Pending(Command(kind, agent), client, Future(), budget)


def _order(turns: Turns) -> list[tuple[int, int]]:
    out = []
    while (item := turns.next_command()) is not None:
        out.append((item.client, item.command.agent))
    return out


def test_commands_are_taken_one_client_at_a_time_each_in_its_order():
    turns = Turns()
    for k in range(3):
        turns.put(_item("set_pace", 1, agent=k))
    turns.put(_item("set_pace", 2, agent=10))
    turns.put(_item("set_pace", 3, agent=20))
    turns.put(_item("set_pace", 3, agent=21))
    assert _order(turns) == [(1, 0), (2, 10), (3, 20), (1, 1), (3, 21), (1, 2)]
    assert len(turns) == 0


def test_a_client_over_budget_and_one_waiting_to_join_are_passed_over():
    now = [0.0]
    broke = WorkBudget(1.0, 1.0, lambda: now[0])
    broke.charge(2.0)
    turns = Turns()
    turns.put(_item("set_pace", 1, broke))
    turns.put(_item("add_agent", 2))
    turns.put(_item("set_pace", 2, agent=5))
    turns.put(_item("set_pace", 3, agent=7))
    assert _order(turns) == [(3, 7)]
    assert turns.joining() and len(turns) == 3
    now[0] = 1.5  # the budget refilled with (scene) time
    assert _order(turns) == [(1, 0)]


def test_joins_are_taken_one_client_at_a_time_up_to_a_clients_other_command():
    turns = Turns()
    for _ in range(3):
        turns.put(_item("add_agent", 1))
    turns.put(_item("set_pace", 1, agent=99))
    turns.put(_item("add_agent", 1))
    turns.put(_item("add_agent", 2))
    batch = turns.joins(3)
    assert [i.client for i in batch] == [1, 2, 1]
    batch = turns.joins(10)
    assert [i.client for i in batch] == [1]
    assert not turns.joining() and _order(turns) == [(1, 99)]
    assert [i.client for i in turns.joins(10)] == [1] and len(turns) == 0


def test_a_batch_is_charged_to_its_clients_by_their_share_of_it():
    now = [0.0]
    budgets = [WorkBudget(0.1, 1.0, lambda: now[0]) for _ in range(2)]
    share([_item("add_agent", 1, budgets[0]), _item("add_agent", 1, budgets[0]),
           _item("add_agent", 2, budgets[1]), _item("add_agent", -1)], 0.4)
    assert budgets[0]._left == pytest.approx(0.8) and budgets[1]._left == pytest.approx(0.9)


@settings(max_examples=50, deadline=None)
@given(one=st.floats(0.001, 0.5), spare=st.floats(0.0, 1.0))
def test_the_join_estimate_learns_the_cost_and_fits_batches_in_spare_time(one, spare):
    costs = JoinCosts()
    assert costs.estimate(1) == pytest.approx(FIRST_JOIN * (1 + 1 / JOIN_SCALE))
    for n in (1, 8, 32, 4, 16) * 10:
        costs.measured(n, one * (1 + n / JOIN_SCALE))
    assert costs.base == pytest.approx(one, rel=1e-3)
    n = costs.fitting(spare, 32)
    assert 0 <= n <= 32
    if n:
        assert costs.estimate(n) <= spare * (1 + 1e-9)
    if n < 32:
        assert costs.estimate(n + 1) > spare * (1 - 1e-9)


def test_work_budget_refills_with_its_clock_while_overdrawn():
    now = [0.0]
    budget = WorkBudget(rate=0.1, burst=0.5, clock=lambda: now[0])
    budget.charge(0.7)
    # 0.2 s overdrawn at 0.1 s per second of its clock: allowed again after 2 s of it.
    now[0] = 1.99
    assert not budget.allowed()
    now[0] = 2.01
    assert budget.allowed()
    # Work expected to cost more than the bucket holds waits for it to hold that much.
    assert not budget.allowed(0.01) and budget.allowed(0.0001)
    now[0] = 7.0
    assert budget.allowed(0.5) and not budget.allowed(0.51)


def test_charges_from_many_threads_all_count():
    budget = WorkBudget(rate=1e-9, burst=1000.0, clock=lambda: 0.0)
    threads = [threading.Thread(target=lambda: [budget.charge(0.001) for _ in range(1000)])
               for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(HANG)
    assert budget._left == pytest.approx(1000.0 - 4.0)


class _Engine:
    """An empty scene."""

    fps = 30.0
    labels = ("happy",)
    mover = 0

    def __len__(self) -> int:
        return 0

    def step(self) -> GaitFrame:
        return GaitFrame((), np.zeros((0, 1, 4)), np.zeros((0, 1, 3)), np.zeros((0, 2, 3)),
                         np.zeros((0, 1)), np.zeros((0, 2)))


class _Sink:
    def encodings(self) -> frozenset[int]:
        return frozenset()

    def frame(self, data: dict[int, bytes]) -> None:
        pass

    def notice(self, client: int | None, message: dict) -> None:
        pass


class _Parked:
    """Stands in for the thread's stop event: each of its waits lasts until released."""

    def __init__(self) -> None:
        self.stop = threading.Event()
        self.go = threading.Semaphore(0)

    def is_set(self) -> bool:
        return self.stop.is_set()

    def set(self) -> None:
        self.stop.set()
        self.go.release()

    def wait(self, seconds: float) -> bool:
        self.go.acquire(timeout=HANG)
        return self.stop.is_set()


def test_the_preparer_is_let_in_while_the_scene_waits_for_a_due_time():
    # A clock that stands still: each tick's wait is then a frame period or more, and the
    # thread stays in it until the test releases it.
    sim = Simulation(_Engine(), ServeSettings(), _Sink(), clock=lambda: 5.0)
    parked = sim._stop = _Parked()
    sim.start()
    try:
        for k in range(1, 4):
            idles = k - 1
            while idles < k:  # the (k - 1)-th wait may not have ended yet
                sim.wait_spare(0.01, HANG)
                with sim._idle:
                    idles, until = sim._idles, sim._idle_until
            # It returned inside the k-th wait of the thread, with its time ahead.
            assert idles == k and until - 5.0 >= k / 30.0 - 1e-9
            parked.go.release()
    finally:
        sim.stop()
    # Once the thread stops, nobody waits for it.
    sim.wait_spare(1.0, HANG)


def test_without_waits_of_the_scene_the_preparer_waits_its_patience_only():
    sim = Simulation(_Engine(), ServeSettings(), _Sink())  # not started: never waits
    start = sim._clock()
    sim.wait_spare(0.001, 0.05)
    assert sim._clock() - start >= 0.05
