"""A small crowd: no hips closer than 0.3 m, everyone reaches the goal, the same seed walks the
same way, emotions change navigation, and JuPedSim stays out of ``import emotive``."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.distance import pdist

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")

from tests.crowd.conftest import CORRIDOR, write_scene

from emotive.crowd.crowd import Crowd
from emotive.crowd.scene import Goal, load_scene
from emotive.models.gait.model import load_gait_model


@pytest.fixture(scope="module")
def model():
    return load_gait_model()


def run(scene, model, frames, seed=0):
    crowd = Crowd(scene, model=model, seed=seed)
    mover = crowd.gait.graph.mover
    frames_out = []
    for _ in range(frames):
        frames_out.append(crowd.step())
    return crowd, frames_out, mover


def test_a_two_way_corridor_keeps_hips_apart_and_everyone_arrives(tmp_path, model):
    scene = load_scene(write_scene(tmp_path, CORRIDOR.format(count=3)))
    crowd, frames, mover = run(scene, model, 450)
    closest = min(pdist(f.positions[:, mover][:, [0, 2]]).min() for f in frames
                  if len(f.agents) > 1)
    assert closest >= 0.3
    assert all(crowd.goal_reached().values()), crowd.goal_reached()
    tie = np.concatenate([np.hypot(*(f.root - f.navigation).T) for f in frames])
    assert np.percentile(tie, 99) <= 0.10


def test_the_same_seed_walks_the_same_way(tmp_path, model):
    scene = load_scene(write_scene(tmp_path, CORRIDOR.format(count=2)))
    _, a, _ = run(scene, model, 45, seed=7)
    _, b, _ = run(scene, model, 45, seed=7)
    _, c, _ = run(scene, model, 45, seed=8)
    assert [f.agents for f in a] == [f.agents for f in b]
    np.testing.assert_allclose(np.stack([f.root for f in a]), np.stack([f.root for f in b]),
                               atol=1e-5)
    assert not np.allclose(a[0].root, c[0].root, atol=1e-3)


def test_an_emotion_change_changes_the_navigation(tmp_path, model):
    scene = load_scene(write_scene(tmp_path, CORRIDOR.format(count=1)))
    crowd = Crowd(scene, model=model, spawn=False)
    a = crowd.add_agent((1.0, 1.5), Goal("waypoints", points=((6.0, 1.5),)), "sad")
    sad = crowd.nav_params(a)
    crowd.step()
    crowd.set_emotion(a, "angry")
    angry = crowd.nav_params(a)
    assert angry.desired_speed > 2 * sad.desired_speed
    speeds = dict(zip(model.labels, model.controls.speed * model.fps, strict=False))
    assert angry.desired_speed == pytest.approx(speeds["angry"], rel=1e-6)
    assert angry.radius < sad.radius and angry.time_gap < sad.time_gap
    assert angry.yield_strength < sad.yield_strength
    for _ in range(5):
        crowd.step()
    assert crowd.nav_params(a) == angry


def test_emotive_import_and_help_do_not_load_jupedsim():
    code = ("import sys, emotive\nfrom emotive.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print('jupedsim' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr


def test_without_avoidance_no_one_steps_aside(tmp_path, model):
    scene = load_scene(write_scene(tmp_path, CORRIDOR.format(count=1)))
    goals = [Goal("waypoints", points=((6.0, 1.5),)), Goal("waypoints", points=((1.0, 1.5),))]
    for avoidance, aside in ((False, False), (True, True)):
        crowd = Crowd(scene, model=model, spawn=False, avoidance=avoidance)
        a, b = crowd.add_agents(np.array([[2.0, 1.5], [4.0, 1.5]]), goals, ["neutral"] * 2)
        crowd.step()
        targets = np.array([crowd.nav._targets[a], crowd.nav._targets[b]])
        assert (np.abs(targets[:, 1] - 1.5) > 0.3).all() == aside, targets


def test_a_waiting_navigation_agent_stands_its_body(tmp_path, model):
    scene = load_scene(write_scene(tmp_path, CORRIDOR.format(count=1)))
    crowd = Crowd(scene, model=model, spawn=False)
    here = np.array([2.0, 1.5])
    slow = crowd._body_path(0, here, here + np.array([0.1 / crowd.fps, 0.0]), 0.0, 1.1)
    walk = crowd._body_path(1, here, here + np.array([0.8 / crowd.fps, 0.0]), 0.0, 1.1)
    assert slow is not None and slow.length <= 0.011
    assert walk is not None and walk.length > 0.2
