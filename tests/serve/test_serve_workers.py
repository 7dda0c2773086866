"""``workers=2``: one scene stepped by two worker processes, a lost worker, a clean stop.

The servers run in this process (:func:`~emotive.serve.testing.running_server`), so their
step workers are children of it, found in ``/proc`` by their command line. Waits are on what
the server makes (frames, replies); wall time only bounds a hang.
"""

from __future__ import annotations

import asyncio
import os
import signal
import sys

import httpx
import numpy as np
import pytest
from worker_procs import step_workers

from emotive.models.gait.generate import GaitFrame
from emotive.serve.errors import ServeError
from emotive.serve.settings import ServeSettings
from emotive.serve.shards import StepWorker
from emotive.serve.simulation import STEP_BUDGET, Simulation
from emotive.serve.testing import running_server
from emotive.serve.worker_process import WorkerSpec
from serve_client import WsClient, until_server

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="finds the worker processes in /proc (Linux)")

#: Frames the server may make before a lost worker's notice must have come (a budget in
#: scene time, 10 scene seconds).
NOTICE_FRAMES = 300
#: Frames that may wait in a client's outbox, sent after a notice that came later.
BUFFERED = ServeSettings().buffered_frames


def _worker_pids() -> set[int]:
    """Live step workers that are children of this process."""
    return step_workers(os.getpid())


def _ids(frame) -> list[int]:
    return sorted(frame.ids.tolist())


@pytest.mark.parametrize("kind", ["processes", "threads"])
def test_two_workers_step_one_scene_that_every_client_sees(kind):
    threads = kind == "threads"
    before = _worker_pids()
    with running_server(workers=2, max_agents=40, worker_kind=kind) as url:
        workers = _worker_pids() - before
        health = httpx.get(f"{url}/api/health").json()

        async def run():
            # One client of each frame layout.
            async with WsClient(url) as a, WsClient(url, encoding=1) as b:
                mine = await a.add_agents(3, path="figure8", emotion="happy")
                theirs = await b.add_agents(3, path="circle", emotion="sad")
                everyone = sorted(mine + theirs)
                for client in (a, b):
                    await client.wait_for(lambda c=client: c.frames
                                          and _ids(c.frames[-1][1]) == everyone)
                seen = [await a.frames_after(10), await b.frames_after(10)]
                states = (await a.request({"type": "state"}))["agents"]
                # Every command, to agents of both workers, from either client.
                replies = []
                for k, agent in enumerate(everyone):
                    client = (a, b)[k % 2]
                    replies += await client.requests([
                        {"type": "set_emotion", "id": agent, "emotion": "angry"},
                        {"type": "set_pace", "id": agent, "pace": 1.2},
                        {"type": "set_path", "id": agent,
                         "path": {"shape": "circle", "center": [k, 0], "radius": 1}}])
                replies.append(await a.request({"type": "set_target", "id": everyone[1],
                                                "target": [5, 5]}))
                recording = await b.request({"type": "start_recording"})
                await b.frames_after(5)
                stopped = await b.request({"type": "stop_recording"})
                gone = [everyone[0], everyone[-1]]
                replies += await b.requests([{"type": "remove_agent", "id": g} for g in gone])
                left = sorted(set(everyone) - set(gone))
                await a.wait_for(lambda: _ids(a.frames[-1][1]) == left)
                after = await a.request({"type": "state"})
                return everyone, seen, states, replies, recording, stopped, left, after

        everyone, seen, states, replies, recording, stopped, left, after = asyncio.run(run())
        stats = httpx.get(f"{url}/api/stats").json()
    assert len(workers) == (0 if threads else 2)
    assert health["workers"] == health["live_workers"] == 2
    assert len(set(everyone)) == 6
    for frames in seen:
        assert all(_ids(f) == everyone for f in frames)
        assert all(f.world.shape == (6, 27, 3) for f in frames)
        assert all(np.isfinite(f.world).all() for f in frames)
        assert [f.number for f in frames] == sorted({f.number for f in frames})
    # Both workers step agents of both clients.
    assert {s["worker"] for s in states} == {0, 1}
    assert all(r["type"] == "ok" for r in replies), replies
    assert recording["state"] == "started" and stopped["agents"] == everyone
    assert stopped["frames"] >= 5
    rows = {s["id"]: s for s in after["agents"]}
    assert sorted(rows) == left
    assert all(r["emotion"] == {"angry": 1.0} and r["pace"] == 1.2 for r in rows.values())
    # The path its worker made for the target, reported after the worker's next answer.
    np.testing.assert_allclose(rows[everyone[1]]["path"][-1], [5, 5], atol=1e-3)
    assert stats["workers"] == 2 and stats["agents"] == 4 and stats["lost_agents"] == 0
    # Stopping the server stopped its workers: no process outlives it.
    assert _worker_pids() & workers == set()


def test_a_killed_worker_is_reported_and_the_scene_goes_on():
    before = _worker_pids()
    with running_server(workers=2, max_agents=40, worker_kind="processes") as url:
        workers = _worker_pids() - before

        async def run():
            async with WsClient(url) as client:
                agents = await client.add_agents(6, path="figure8")
                await client.wait_for(lambda: client.frames
                                      and _ids(client.frames[-1][1]) == agents)
                states = (await client.request({"type": "state"}))["agents"]
                victim = sorted(workers)[0]
                os.kill(victim, signal.SIGKILL)
                await client.wait_for(lambda: any("left the scene" in r.get("message", "")
                                                  for r in client.replies))
                notice = next(r for r in client.replies
                              if "left the scene" in r.get("message", ""))
                count = len(client.frames)
                await client.frames_after(BUFFERED + 5)
                # The notice goes before the frames waiting in the client's outbox.
                later = [f for _, f in client.frames[count + BUFFERED:]]
                added = await client.add_agents(2)
                await client.wait_for(lambda: set(added) <= set(client.frames[-1][1].ids))
                return agents, states, victim, notice, later, added

        agents, states, victim, notice, later, added = asyncio.run(run())
        stats = asyncio.run(until_server(url, lambda s: s["workers"] == 1 and s,
                                         "the server still counts two workers",
                                         frames=NOTICE_FRAMES))
        health = httpx.get(f"{url}/api/health").json()
        survivor = _worker_pids() & workers
    assert notice["type"] == "error" and f"process {victim}" in notice["message"]
    assert "killed by signal 9" in notice["message"]
    by_worker = {w: sorted(s["id"] for s in states if s["worker"] == w) for w in (0, 1)}
    lost = next(ids for ids in by_worker.values() if str(ids[0]) in notice["message"])
    kept = sorted(set(agents) - set(lost))
    assert lost and kept
    assert all(_ids(f) == kept for f in later)
    assert stats["lost_agents"] == len(lost) and stats["agents"] == len(kept) + len(added)
    assert health["status"] == "degraded" and health["live_workers"] == 1
    assert survivor == workers - {victim}
    assert _worker_pids() & workers == set()


class _Shards:
    """Two step workers' worth of standing agents, for the admission limit alone."""

    fps = 30.0
    labels = ("happy", "sad")
    mover = 0

    def __len__(self) -> int:
        return 0

    def step(self) -> GaitFrame:
        return GaitFrame((), np.zeros((0, 3, 4)), np.zeros((0, 3, 3)), np.zeros((0, 4, 3)),
                         np.zeros((0, 2)), np.zeros((0, 2)))


def test_the_scene_admits_the_sum_of_its_workers_limits():
    sim = Simulation(_Shards(), ServeSettings(max_agents=10_000), _Quiet())
    budget = STEP_BUDGET / 30.0
    for agents in range(20, 60, 5):
        sim._measured(agents, 0.001 + 2e-4 * agents, shard=0)
        sim._measured(agents, 0.002 + 2.5e-4 * agents, shard=1)
    one = int((budget - 0.001) / 2e-4)
    two = int((budget - 0.002) / 2.5e-4)
    assert min(one, two) > 55  # both beyond the counts measured (the floor of each limit)
    assert abs(sim.capacity() - (one + two)) <= 2


class _Quiet:
    def encodings(self) -> frozenset[int]:
        return frozenset()

    def frame(self, data: dict[int, bytes]) -> None:
        pass

    def notice(self, client: int | None, message: dict) -> None:
        pass


def test_a_worker_that_dies_before_it_is_ready_is_a_start_error():
    worker = StepWorker(WorkerSpec(0, "gait", "torch", 0, 4, 22, 27, 19))
    try:
        worker.process.kill()
        with pytest.raises(ServeError, match=r"killed by signal 9 .*did not start"):
            worker.started()
    finally:
        worker.close()
    assert worker.process.poll() is not None
