"""Admission at the tick: batches of new agents, per-client quotas, the measured limit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.models.gait.generate import GaitFrame
from emotive.serve.errors import MessageError
from emotive.serve.messages import AddAgent, Command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import JOIN_PER_TICK, STEP_BUDGET, Simulation

FPS = 30.0


class FakeCrowd:
    """Agents that stand still; ``add_agents`` counts its calls."""

    fps = FPS
    labels = ("happy", "sad")
    mover = 0

    def __init__(self) -> None:
        self.ids: list[int] = []
        self.calls: list[int] = []
        self.paces: dict[int, float] = {}

    def __len__(self) -> int:
        return len(self.ids)

    def add_agents(self, paths, schedules, starts, paces) -> list[int]:
        new = list(range(len(self.ids), len(self.ids) + len(paths)))
        self.ids += new
        self.calls.append(len(paths))
        return new

    def remove_agent(self, agent: int) -> None:
        self.ids.remove(agent)

    def set_pace(self, agent: int, pace: float) -> None:
        self.paces[agent] = pace

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


def _sim(**settings) -> Simulation:
    return Simulation(FakeCrowd(), ServeSettings(**settings), Sink())


def _add(sim: Simulation, client: int):
    return sim.submit(Command("add_agent", None, AddAgent(None, None)), client)


def test_agents_join_in_batches_and_a_clients_later_messages_wait_in_order():
    sim = _sim()
    adds = [_add(sim, 1) for _ in range(JOIN_PER_TICK + 8)]
    pace = sim.submit(Command("set_pace", JOIN_PER_TICK + 7, 1.2), 1)
    other = _add(sim, 2)
    sim._apply_pending()
    assert sum(f.done() for f in adds) == JOIN_PER_TICK and not pace.done()
    assert not other.done()
    sim._apply_pending()
    assert all(f.done() for f in adds) and other.result()["type"] == "agent"
    assert pace.result() == {"type": "ok"} and sim.engine.paces == {JOIN_PER_TICK + 7: 1.2}
    # The set_pace between them splits the second tick's joins in two calls, in order.
    assert sim.engine.calls == [JOIN_PER_TICK, 8, 1]
    assert [f.result()["id"] for f in adds] == list(range(JOIN_PER_TICK + 8))


def test_each_client_has_its_quota():
    sim = _sim(max_agents_per_client=3)
    mine = [_add(sim, 1) for _ in range(5)]
    theirs = [_add(sim, 2) for _ in range(2)]
    sim._apply_pending()
    assert [f.exception() is None for f in mine] == [True] * 3 + [False] * 2
    assert "--max-agents-per-client 3" in str(mine[-1].exception())
    assert all(f.exception() is None for f in theirs) and sim.owned(1) == 3
    removed = sim.submit(Command("remove_agent", mine[0].result()["id"]), 2)
    again = _add(sim, 1)
    sim._apply_pending()
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
        sim._apply_pending()
    assert sum(f.exception() is None for f in futures) == limit
    refusal = futures[-1].exception()
    assert isinstance(refusal, MessageError)
    assert f"limit now {limit}" in str(refusal) and "--max-agents 500" in str(refusal)


def test_a_step_already_over_the_budget_holds_the_scene_where_it_is():
    sim = _sim()
    sim._measured(120, STEP_BUDGET / FPS * 1.5)
    assert sim.capacity() == 120
