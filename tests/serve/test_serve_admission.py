"""Admission at the tick: fair turns, batches of new agents in spare time, quotas, the limit.

The scene's clock is a virtual one that the fake engine's calls move on by what they are set
to cost, so the shares of a frame are checked exactly, whatever the machine.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.models.gait.generate import GaitFrame
from emotive.serve.commands import COMMAND_SHARE, JOIN_BURST, JOIN_SHARE
from emotive.serve.errors import MessageError
from emotive.serve.limits import WorkBudget
from emotive.serve.messages import AddAgent, Command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import JOIN_PER_TICK, STEP_BUDGET, Simulation
from emotive.serve.turns import FIRST_JOIN

FPS = 30.0


class Clock:
    """Virtual seconds, moved on by the fake engine's calls."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class FakeCrowd:
    """Agents that stand still; ``add_agents`` counts its calls; calls cost virtual time.

    Args:
        clock: the virtual clock its calls move on.
        join: seconds one ``add_agents`` call takes.
        command: seconds one ``set_pace`` takes.
    """

    fps = FPS
    labels = ("happy", "sad")
    mover = 0

    def __init__(self, clock: Clock | None = None, join: float = 0.0,
                 command: float = 0.0) -> None:
        self.clock = Clock() if clock is None else clock
        self.join = join
        self.command = command
        self.ids: list[int] = []
        self.calls: list[int] = []
        self.paces: dict[int, float] = {}
        self.order: list[int] = []

    def __len__(self) -> int:
        return len(self.ids)

    def add_agents(self, paths, schedules, starts, paces) -> list[int]:
        self.clock.now += self.join
        new = list(range(len(self.ids), len(self.ids) + len(paths)))
        self.ids += new
        self.calls.append(len(paths))
        return new

    def remove_agent(self, agent: int) -> None:
        self.ids.remove(agent)

    def set_pace(self, agent: int, pace: float) -> None:
        self.clock.now += self.command
        self.paces[agent] = pace
        self.order.append(agent)

    def step(self) -> GaitFrame:
        b = len(self.ids)
        return GaitFrame(tuple(self.ids), np.tile([1.0, 0, 0, 0], (b, 3, 1)),
                         np.zeros((b, 3, 3)), np.zeros((b, 4, 3)), np.zeros((b, 2)),
                         np.zeros((b, 2)))


class Sink:
    def encodings(self) -> frozenset[int]:
        return frozenset()

    def frame(self, data: dict[int, bytes]) -> None:
        pass

    def notice(self, client: int, message: dict) -> None:
        pass


def _sim(crowd: FakeCrowd | None = None, **settings) -> Simulation:
    crowd = FakeCrowd() if crowd is None else crowd
    return Simulation(crowd, ServeSettings(**settings), Sink(), clock=crowd.clock)


def _add(sim: Simulation, client: int, budget: WorkBudget | None = None):
    return sim.submit(Command("add_agent", None, AddAgent(None, None)), client, budget)


def _tick(sim: Simulation, spare: float | None = None) -> None:
    """One tick's commands, its frame due ``spare`` seconds after its own step (``None``:
    no limit), then the frame counted."""
    now = sim._clock()
    sim._apply_pending(None if spare is None else now + sim._tick_guess + spare)
    sim.frames += 1


def _agents(sim: Simulation, count: int) -> None:
    """``count`` agents of a client 0, joined."""
    adds = [_add(sim, 0) for _ in range(count)]
    while not all(f.done() for f in adds):
        _tick(sim)


def test_agents_join_in_batches_in_turns_and_a_clients_later_messages_wait_in_order():
    sim = _sim()
    adds = [_add(sim, 1) for _ in range(JOIN_PER_TICK + 8)]
    pace = sim.submit(Command("set_pace", JOIN_PER_TICK + 6, 1.2), 1)
    other = _add(sim, 2)
    _tick(sim)
    # One agent of each waiting client a round: the other client's joins in the first batch.
    assert sum(f.done() for f in adds) == JOIN_PER_TICK - 1 and other.done()
    assert not pace.done()
    _tick(sim)
    assert all(f.done() for f in adds) and not pace.done()
    _tick(sim)
    assert pace.result() == {"type": "ok"} and sim.engine.paces == {JOIN_PER_TICK + 6: 1.2}
    assert sim.engine.calls == [JOIN_PER_TICK, 9]
    assert other.result()["id"] == 1
    assert [f.result()["id"] for f in adds] == [0, *range(2, JOIN_PER_TICK + 9)]


def test_one_clients_many_commands_take_turns_with_anothers_within_a_share_of_the_frame():
    crowd = FakeCrowd(command=0.004)
    sim = _sim(crowd, max_agents_per_client=100)
    _agents(sim, 100)
    flood = [sim.submit(Command("set_pace", k, 1.1), 1) for k in range(40)]
    mine = sim.submit(Command("set_pace", 99, 0.9), 2)
    _tick(sim, spare=1.0)
    per_tick = len(crowd.order)
    # 4 ms each, a quarter of a 33 ms frame: 3 commands (the one that passes the share ends).
    assert per_tick == int(COMMAND_SHARE / FPS / 0.004) + 1
    assert mine.done() and crowd.order[:2] == [0, 99]
    while not all(f.done() for f in flood):
        _tick(sim, spare=1.0)
    assert len(crowd.order) == 41


def test_a_client_over_its_budget_waits_and_nobody_else_does():
    crowd = FakeCrowd(command=0.06)
    sim = _sim(crowd)
    _agents(sim, 10)
    budget = WorkBudget(0.1, 0.1, sim.scene_time)
    theirs = [sim.submit(Command("set_pace", 1, 1.1), 1, budget) for _ in range(3)]
    _tick(sim, spare=1.0)
    _tick(sim, spare=1.0)
    # 60 ms charged per command against 0.1 s per second of scene time: after two, it is
    # overdrawn and waits while the scene goes on; another client's command does not.
    assert [f.done() for f in theirs] == [True, True, False]
    mine = sim.submit(Command("set_pace", 2, 0.9), 2, WorkBudget(0.1, 0.1, sim.scene_time))
    _tick(sim, spare=1.0)
    assert mine.done() and not theirs[2].done()
    while not theirs[2].done():
        _tick(sim, spare=1.0)
    # It waited until the scene's time refilled its budget: 17 ms owed at 0.1 s a second.
    assert sim.frames >= 2 + (0.12 - 0.1 - 2 / FPS * 0.1) / 0.1 * FPS


def test_joins_wait_for_spare_time_and_beyond_it_take_a_share_of_scene_time():
    crowd = FakeCrowd(join=0.1)
    sim = _sim(crowd)
    adds = [_add(sim, 1, WorkBudget(10.0, 10.0, sim.scene_time)) for _ in range(200)]
    _tick(sim, spare=1.0)
    # A batch that fits the spare time joins (and teaches the estimate what joins cost).
    assert crowd.calls == [JOIN_PER_TICK] and sim._join_costs.estimate(1) > FIRST_JOIN
    _tick(sim, spare=0.2)
    assert crowd.calls == [JOIN_PER_TICK] * 2
    # No spare time: a batch joins anyway while the scene's join budget (JOIN_SHARE of scene
    # time, bursts of JOIN_BURST) allows; what it took beyond the spare time is owed, and
    # further batches wait.
    ticks = 0
    while not all(f.done() for f in adds):
        _tick(sim, spare=0.0)
        ticks += 1
    forced = len(crowd.calls) - 2
    assert forced == 5
    # The 0.5 s of forced joins took JOIN_SHARE of the scene's time, but for the budget's
    # burst and the batch that overdraws it.
    assert 0.1 * forced <= JOIN_SHARE * ticks / FPS + JOIN_BURST + 0.1, ticks
    assert 0.1 * forced > JOIN_SHARE * ticks / FPS, ticks


def test_each_client_is_charged_its_share_of_a_batch():
    crowd = FakeCrowd(join=0.06)
    sim = _sim(crowd)
    budgets = [WorkBudget(0.1, 1.0, sim.scene_time) for _ in range(2)]
    for _ in range(2):
        _add(sim, 1, budgets[0])
    _add(sim, 2, budgets[1])
    _tick(sim)
    assert crowd.calls == [3]
    assert budgets[0]._left == pytest.approx(1.0 - 0.04)
    assert budgets[1]._left == pytest.approx(1.0 - 0.02)


def test_each_client_has_its_quota():
    sim = _sim(max_agents_per_client=3)
    mine = [_add(sim, 1) for _ in range(5)]
    theirs = [_add(sim, 2) for _ in range(2)]
    _tick(sim)
    _tick(sim)
    assert [f.exception() is None for f in mine] == [True] * 3 + [False] * 2
    assert "--max-agents-per-client 3" in str(mine[-1].exception())
    assert all(f.exception() is None for f in theirs) and sim.owned(1) == 3
    removed = sim.submit(Command("remove_agent", mine[0].result()["id"]), 2)
    again = _add(sim, 1)
    _tick(sim)
    _tick(sim)
    assert removed.result() == {"type": "ok"} and again.result()["type"] == "agent"


def _feed(sim: Simulation, fixed: float, slope: float) -> None:
    for agents in range(20, 60, 5):
        for _ in range(3):
            sim._measured(agents, fixed + slope * agents)


@settings(max_examples=50, deadline=None)
@given(fixed=st.floats(0.0, 0.005), slope=st.floats(2e-5, 5e-4))
def test_the_limit_is_where_the_fitted_step_time_crosses_the_budget(fixed, slope):
    sim = _sim(max_agents=10_000)
    _feed(sim, fixed, slope)
    expected = max(int((STEP_BUDGET / FPS - fixed) / slope), 55)
    assert abs(sim.capacity() - min(expected, 10_000)) <= 1


def test_adds_beyond_the_measured_limit_are_refused_naming_it():
    sim = _sim(max_agents=500)
    _feed(sim, 0.002, 0.0002)
    limit = sim.capacity()
    assert limit == pytest.approx((STEP_BUDGET / FPS - 0.002) / 0.0002, abs=1)
    futures = [_add(sim, k) for k in range(limit + 5)]
    for _ in range(limit // JOIN_PER_TICK + 2):
        _tick(sim)
    assert sum(f.exception() is None for f in futures) == limit
    refusal = futures[-1].exception()
    assert isinstance(refusal, MessageError)
    assert f"limit now {limit}" in str(refusal) and "--max-agents 500" in str(refusal)


def test_a_step_already_over_the_budget_holds_the_scene_where_it_is():
    sim = _sim()
    sim._measured(120, STEP_BUDGET / FPS * 1.5)
    assert sim.capacity() == 120
