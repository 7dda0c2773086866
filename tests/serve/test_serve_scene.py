"""``emotive serve --scene``: clients get the geometry, add agents with goals, draw obstacles.

One server on a small scene (8 m x 4 m, two agents waiting by the west wall) for the module.
Walks are watched for a span of scene time (frame number / fps), which holds on a busy
machine where the server skips ticks; wall time only bounds a hang.
"""

from __future__ import annotations

import asyncio

import httpx
import numpy as np
import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")

from emotive.serve.testing import running_server
from serve_client import WsClient

SCENE = """
[area]
polygon = [[0, 0], [8, 0], [8, 4], [0, 4]]

[[groups]]
name = "waiting"
spawn = [[0.3, 0.3], [1.6, 0.3], [1.6, 1.6], [0.3, 1.6]]
count = 2
goal = { waypoints = [[1.0, 1.0]] }
emotion = "sad"
"""
#: An obstacle across the middle, with a way round it on the south side.
BLOCK = [[3.5, 1.5], [4.5, 1.5], [4.5, 4.0], [3.5, 4.0]]
#: Scene seconds an agent has to cross the room.
WALK_SECONDS = 20.0


@pytest.fixture(scope="module")
def url(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "room.toml"
    path.write_text(SCENE, encoding="utf-8")
    with running_server(scene=str(path), max_agents=10) as base:
        yield base


def _ground(frame, agent: int) -> np.ndarray | None:
    ids = list(frame.ids)
    return frame.root[ids.index(agent)][[0, 2]] if agent in ids else None


async def _walk(client: WsClient, agent: int, goal, seconds: float = WALK_SECONDS
                ) -> np.ndarray:
    """``(T, 2)`` the agent's track until it is within 0.5 m of ``goal`` or ``seconds`` of
    scene time passed."""
    start = len(client.frames)
    await client.frames_after(1)
    t0 = client.frames[start][1].time
    while True:
        track = [g for _, f in client.frames[start:] if (g := _ground(f, agent)) is not None]
        if (track and np.linalg.norm(track[-1] - goal) < 0.5) or \
                client.frames[-1][1].time - t0 >= seconds:
            return np.array(track)
        await client.frames_after(10)


def test_a_client_gets_the_geometry_when_it_joins(url):
    async def run():
        async with WsClient(url) as client:
            await client.wait_for(lambda: client.replies)
            return client.replies[0]

    first = asyncio.run(run())
    assert first["type"] == "scene" and first["version"] >= 1
    assert first["area"] == [[0, 0], [8, 0], [8, 4], [0, 4]]
    assert first["groups"] == [{"name": "waiting", "spawn": [[0.3, 0.3], [1.6, 0.3],
                                                             [1.6, 1.6], [0.3, 1.6]],
                                "goal": {"kind": "waypoints", "points": [[1.0, 1.0]]}}]
    assert httpx.get(f"{url}/api/scene").json() == first
    agents = httpx.get(f"{url}/api/agents").json()["agents"]
    assert {a["group"] for a in agents} == {"waiting"} and len(agents) == 2
    assert all(set(a["emotion"]) == {"sad"} for a in agents)


def test_an_agent_added_with_a_goal_walks_there(url):
    goal = np.array([7.0, 1.0])

    async def run():
        async with WsClient(url) as client:
            reply = await client.request({"type": "add_agent", "at": [2.5, 0.8],
                                          "goal": goal.tolist(), "emotion": "happy"})
            assert reply["type"] == "agent", reply
            return reply["id"], await _walk(client, reply["id"], goal)

    agent, track = asyncio.run(run())
    assert np.linalg.norm(track[-1] - goal) < 0.5, f"it stopped at {track[-1]}"
    state = {a["id"]: a for a in httpx.get(f"{url}/api/agents").json()["agents"]}[agent]
    assert state["group"] == "" and state["goal"]["kind"] == "waypoints"
    assert max(state["emotion"], key=state["emotion"].get) == "happy"
    remove = {"type": "remove_agent", "id": agent}

    async def clean():
        async with WsClient(url) as client:
            return await client.request(remove)

    assert asyncio.run(clean())["type"] == "ok"


def test_an_obstacle_reaches_every_client_and_agents_walk_around_it(url):
    goal = np.array([6.5, 3.0])

    async def run():
        async with WsClient(url) as watcher, WsClient(url) as client:
            await watcher.wait_for(lambda: watcher.replies)
            version = watcher.replies[0]["version"]
            reply = await client.request({"type": "add_obstacle", "polygon": BLOCK})
            await watcher.wait_for(lambda: len(watcher.replies) > 1)
            numbers = [f.number for f in await watcher.frames_after(10)]
            added = await client.request({"type": "add_agent", "at": [2.2, 3.0],
                                          "goal": goal.tolist()})
            track = await _walk(client, added["id"], goal)
            return version, reply, watcher.replies[1], numbers, track

    version, reply, notice, numbers, track = asyncio.run(run())
    assert reply["type"] == "obstacle" and reply["index"] == 1
    assert reply["version"] == version + 1
    assert notice["type"] == "scene" and notice["version"] == version + 1
    assert notice["obstacles"] == [BLOCK]
    assert httpx.get(f"{url}/api/scene").json()["obstacles"] == [BLOCK]
    # The stream went on while the navigation was rebuilt, frame after frame.
    assert np.all(np.diff(numbers) >= 1)
    assert np.linalg.norm(track[-1] - goal) < 0.5, f"it stopped at {track[-1]}"
    inside = ((track[:, 0] > 3.55) & (track[:, 0] < 4.45) & (track[:, 1] > 1.55))
    assert not inside.any(), "the agent walked through the obstacle"


@pytest.mark.parametrize(("message", "words"), [
    ({"type": "add_obstacle", "polygon": [[5, 1], [6, 2], [6, 1], [5, 2]]}, "crosses itself"),
    ({"type": "add_obstacle", "polygon": [[20, 20], [21, 20], [21, 21]]},
     "lies outside the area"),
    ({"type": "add_obstacle", "polygon": [[5, 1], [6, 1]]}, "at least 3"),
    ({"type": "add_obstacle", "polygon": [[5.5, -1], [6, -1], [6, 5], [5.5, 5]]},
     "splits the walkable area"),
    ({"type": "add_agent", "at": [9, 1], "goal": [2, 2]}, '"at" [9, 1] lies outside'),
    ({"type": "add_agent", "at": [2, 1], "goal": [4, 3]}, '"goal" [4, 3] lies outside'),
    ({"type": "add_agent", "goal": [2, 2]}, 'needs "at"'),
    ({"type": "add_agent", "at": [2, 1], "goal": [3, 1], "path": "line"}, "not both"),
    ({"type": "add_agent", "path": "circle"}, 'not with a "path"'),
    ({"type": "set_goal", "id": 10_000, "goal": [2, 2]}, "no agent with id 10000"),
])
def test_bad_requests_are_refused_in_one_line(url, message, words):
    async def run():
        async with WsClient(url) as client:
            return await client.request(message)

    reply = asyncio.run(run())
    assert reply["type"] == "error", reply
    assert words in reply["message"] and "\n" not in reply["message"]


def test_scene_agents_take_goals_emotions_and_no_paths(url):
    async def run():
        async with WsClient(url) as client:
            state = await client.request({"type": "state"})
            agent = next(a["id"] for a in state["agents"] if a["group"] == "waiting")
            replies = await client.requests([
                {"type": "set_emotion", "id": agent, "emotion": "angry"},
                {"type": "set_goal", "id": agent, "goal": [[2.5, 0.8], [2.0, 2.0]]},
                {"type": "set_path", "id": agent, "path": "line"},
                {"type": "scene"},
            ])
            return agent, replies

    agent, (emotion, goal, path, scene) = asyncio.run(run())
    assert emotion["type"] == "ok" and goal["type"] == "ok"
    assert path["type"] == "error" and "send set_goal" in path["message"]
    assert scene["type"] == "scene" and scene["obstacles"] == [BLOCK]
    state = {a["id"]: a for a in httpx.get(f"{url}/api/agents").json()["agents"]}[agent]
    assert state["goal"]["points"][-1] == [2.0, 2.0]
    assert state["valence"] < 0 < state["arousal"]


def test_without_a_scene_its_requests_are_refused():
    with running_server(max_agents=5) as base:
        async def run():
            async with WsClient(base) as client:
                return await client.requests([
                    {"type": "add_obstacle", "polygon": BLOCK},
                    {"type": "set_goal", "id": 0, "goal": [1, 1]},
                    {"type": "scene"},
                    {"type": "add_agent", "at": [0, 0], "goal": [1, 1]},
                ])

        replies = asyncio.run(run())
        missing = httpx.get(f"{base}/api/scene")
    for reply in replies:
        assert reply["type"] == "error" and "needs a scene" in reply["message"], reply
    assert missing.status_code == 404 and "--scene" in missing.json()["message"]
