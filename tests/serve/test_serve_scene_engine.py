"""The crowd engine of ``emotive serve --scene``, stepped directly: geometry, placed agents,
obstacles drawn while the crowd runs (navigation rebuilt, bodies walk around), and refusals.

Walks are bounded in frames, not wall time: the engine is stepped by the test itself.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")

from emotive.crowd.errors import CrowdError, SceneError
from emotive.serve.crowd_engine import load_crowd_engine
from emotive.serve.errors import MessageError
from emotive.serve.messages import to_command

#: An 8 m x 4 m room: two agents wait at a waypoint near the west wall, two walk to an exit
#: in the east.
SCENE = """
[area]
polygon = [[0, 0], [8, 0], [8, 4], [0, 4]]

[[groups]]
name = "waiting"
spawn = [[0.3, 0.3], [1.6, 0.3], [1.6, 1.6], [0.3, 1.6]]
count = 2
goal = { waypoints = [[1.0, 1.0]] }
emotion = "neutral"

[[groups]]
name = "leaving"
spawn = [[0.3, 2.6], [1.6, 2.6], [1.6, 3.7], [0.3, 3.7]]
count = 2
goal = [[7.4, 2.5], [8, 2.5], [8, 4], [7.4, 4]]
emotion = { choices = ["happy", "angry"] }
"""
#: An obstacle in the middle of the room, with room to pass it on the south side.
BLOCK = [[3.5, 1.5], [4.5, 1.5], [4.5, 4.0], [3.5, 4.0]]
#: Frames an agent may take to walk the room (20 s of scene time).
WALK_FRAMES = 600


@pytest.fixture
def engine(tmp_path):
    path = tmp_path / "room.toml"
    path.write_text(SCENE, encoding="utf-8")
    return load_crowd_engine(path, seed=3)


def _place(engine, at, goal, emotion="neutral"):
    command = to_command({"type": "add_agent", "at": at, "goal": goal, "emotion": emotion},
                         engine.labels, engine.points_over)
    (agent,) = engine.place_agents([command.value])
    return agent


def _walk(engine, agent, goal, frames=WALK_FRAMES):
    """``(T, 2)`` the agent's ground track until it is within 0.5 m of ``goal``."""
    track = []
    for _ in range(frames):
        frame = engine.step(full=False)
        track.append(frame.root[frame.agents.index(agent)].copy())
        if np.linalg.norm(track[-1] - goal) < 0.5:
            break
    return np.array(track)


def _inside(track, box):
    (x0, z0), (x1, z1) = np.min(box, 0), np.max(box, 0)
    return (track[:, 0] > x0) & (track[:, 0] < x1) & (track[:, 1] > z0) & (track[:, 1] < z1)


def test_the_scene_message_describes_the_geometry(engine):
    message = engine.scene_message
    assert message["type"] == "scene" and message["version"] == 1
    assert message["area"] == [[0, 0], [8, 0], [8, 4], [0, 4]]
    assert message["obstacles"] == []
    assert [g["name"] for g in message["groups"]] == ["waiting", "leaving"]
    assert message["groups"][0]["goal"] == {"kind": "waypoints", "points": [[1.0, 1.0]]}
    assert message["groups"][1]["goal"]["kind"] == "exit"
    assert message["groups"][1]["spawn"][0] == [0.3, 2.6]


def test_spawned_agents_are_reported_once_and_leavers_when_they_leave(engine):
    engine.step()
    joined, left = engine.take_changes()
    assert len(joined) == 4 and left == []
    assert {engine.crowd.info(a).group for a, _, _ in joined} == {"waiting", "leaving"}
    leavers = {a for a, _, _ in joined if engine.crowd.info(a).group == "leaving"}
    gone: set[int] = set()
    for _ in range(WALK_FRAMES):
        frame = engine.step(full=False)
        joined, left = engine.take_changes()
        assert joined == []
        gone.update(left)
        assert not set(left) & set(engine.agents)
        if gone == leavers:
            break
    assert gone == leavers
    assert frame.world is None


def test_full_frames_carry_world_positions_from_the_rig(engine):
    frame = engine.step(full=True)
    assert frame.world.shape == (len(frame.agents), engine.rig.num_points, 3)
    np.testing.assert_allclose(frame.world[:, engine.mover], frame.positions[:, engine.mover])


def test_a_placed_agent_walks_to_its_goal(engine):
    engine.step()
    agent = _place(engine, [2.5, 0.8], [7.0, 1.0], "happy")
    track = _walk(engine, agent, np.array([7.0, 1.0]))
    assert np.linalg.norm(track[-1] - [7.0, 1.0]) < 0.5, track[-1]
    state = engine.agent_state(agent, track[-1])
    assert state["group"] == "" and state["goal"] == {"kind": "waypoints", "points": []}


def test_a_point_near_a_wall_is_moved_off_it(engine):
    agent = _place(engine, [6.0, 0.05], [6.0, 2.0])
    frame = engine.step()
    start = frame.root[frame.agents.index(agent)]
    assert start[1] >= 0.2, start


def test_an_obstacle_rebuilds_navigation_and_agents_walk_around_it(engine):
    engine.step()
    agent = _place(engine, [2.2, 3.0], [6.5, 3.0])
    keys, nav = list(engine.crowd.nav.keys), engine.crowd.nav
    assert engine.add_obstacle(np.array(BLOCK)) == 1
    assert engine.crowd.nav is not nav and engine.crowd.nav.keys == keys
    assert engine.version == 2 and engine.scene_message["version"] == 2
    assert engine.scene_message["obstacles"] == [BLOCK]
    track = _walk(engine, agent, np.array([6.5, 3.0]))
    assert np.linalg.norm(track[-1] - [6.5, 3.0]) < 0.5, "it did not get round the obstacle"
    # Its hips never entered the obstacle (5 cm in, for the body's sway): it went round the
    # south.
    inner = np.array(BLOCK) + np.array([[0.05, 0.05], [-0.05, 0.05], [-0.05, -0.05],
                                        [0.05, -0.05]])
    assert not _inside(track, inner).any()
    assert track[np.abs(track[:, 0] - 4.0) < 0.5, 1].max() < 1.5


def test_a_destination_on_a_new_obstacle_moves_to_the_nearest_free_point(engine):
    engine.step()
    agent = _place(engine, [2.5, 0.8], [[4.0, 3.0], [6.0, 1.0]])
    engine.add_obstacle(np.array(BLOCK))
    destination = np.array(engine.crowd.info(agent).goal.destination)
    assert not _inside(destination[None], np.array(BLOCK)).any()
    assert np.linalg.norm(destination - [4.0, 3.0]) < 1.0


@pytest.mark.parametrize(("corners", "words"), [
    ([[3, 1], [5, 3], [5, 1], [3, 3]], "crosses itself"),
    ([[20, 20], [21, 20], [21, 21]], "lies outside the area"),
    ([[3.5, -1], [4.5, -1], [4.5, 5], [3.5, 5]], "splits the walkable area"),
    ([[3.5, 0.4], [4.5, 0.4], [4.5, 4.0], [3.5, 4.0]], "closes a way"),
    ([[0.6, 0.6], [1.4, 0.6], [1.4, 1.4], [0.6, 1.4]], "covers a waypoint of group 'waiting'"),
    ([[7.0, 3.0], [7.6, 3.0], [7.6, 3.6], [7.0, 3.6]], "covers the exit of group 'leaving'"),
])
def test_bad_obstacles_are_refused_in_one_line_and_nothing_changes(engine, corners, words):
    engine.step()
    nav = engine.crowd.nav
    with pytest.raises(SceneError) as err:
        engine.add_obstacle(np.array(corners, dtype=float))
    assert words in str(err.value) and "\n" not in str(err.value)
    assert engine.crowd.nav is nav and engine.version == 1
    assert engine.crowd.scene.obstacles == ()


def test_an_obstacle_on_an_agent_is_refused_naming_it(engine):
    engine.step()
    agent = _place(engine, [5.0, 2.0], [5.0, 2.5])
    engine.step()
    with pytest.raises(CrowdError) as err:
        engine.add_obstacle(np.array([[4.6, 1.6], [5.4, 1.6], [5.4, 2.4], [4.6, 2.4]]))
    assert f"agent(s) {agent} stand on it" in str(err.value)
    assert engine.crowd.scene.obstacles == () and engine.version == 1


def test_points_off_the_walkable_area_and_paths_are_refused(engine):
    engine.add_obstacle(np.array(BLOCK))
    with pytest.raises(MessageError, match=r'"at" \[9, 1\] lies outside the walkable area'):
        _place(engine, [9.0, 1.0], [2.0, 2.0])
    with pytest.raises(MessageError, match=r'"goal" \[4, 3\] lies outside the walkable area'):
        _place(engine, [2.0, 1.0], [4.0, 3.0])
    engine.step()
    (agent,) = engine.agents[:1]
    with pytest.raises(MessageError, match="goal point 2"):
        engine.set_goal(agent, np.array([[2.0, 2.0], [4.0, 2.0]]))
    path = to_command({"type": "add_agent", "path": "line"}, engine.labels).value
    with pytest.raises(MessageError, match='not with a "path"'):
        engine.place_agents([path])
    with pytest.raises(MessageError, match="send set_goal"):
        engine.set_path(agent, path.path)


def test_set_goal_and_set_target_send_an_agent_elsewhere(engine):
    engine.step()
    agent = _place(engine, [2.5, 0.8], [2.5, 3.0])
    engine.set_target(agent, [6.5, 1.0])
    track = _walk(engine, agent, np.array([6.5, 1.0]))
    assert np.linalg.norm(track[-1] - [6.5, 1.0]) < 0.5
    engine.set_goal(agent, np.array([[6.5, 3.0], [2.5, 3.0]]))
    state = engine.agent_state(agent, track[-1])
    assert state["goal"]["points"] == [[6.5, 3.0], [2.5, 3.0]]
    assert state["path"][0] == [round(float(v), 4) for v in track[-1]]
