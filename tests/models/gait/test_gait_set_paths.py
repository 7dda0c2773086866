"""Tests of :meth:`GaitGenerator.set_paths`: many agents sent along new paths in one batch
walk as when each is sent in turn, from the point of its path nearest to where it stands.
An untrained narrow network on the small rig, its speed pinned, as in test_gait_generate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from gait_helpers import NUM_JOINTS, make_skeleton

from emotive.errors import PathError
from emotive.models.gait import GaitConfig, GaitNetwork
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.paths import GroundPath, circle, line, waypoints

LABELS = ("happy", "sad", "angry", "neutral")
SPEED = 0.05  # metres per frame, pinned in the network's speed head
AGENTS = 12


@pytest.fixture(scope="module")
def model() -> GaitModel:
    torch.manual_seed(0)
    cfg = GaitConfig(labels=LABELS, num_joints=NUM_JOINTS, enc1_hidden=16, enc1_out=8,
                     enc2_hidden=16, enc2_out=8, gru_hidden=24, root_hidden=8, versor_hidden=24)
    net = GaitNetwork(cfg)
    with torch.no_grad():
        net.fc_s[0].weight.zero_()
        net.fc_s[0].bias.zero_()
        net.root_mean[1] = SPEED
    net.eval()
    sk = make_skeleton()
    rest = np.zeros((NUM_JOINTS, 4))
    rest[:, 0] = 1.0
    controls = GaitControls(
        LABELS, np.array([0.2, 0.1, 0.25, 0.18]), np.array([0.045, 0.015, 0.06, 0.04]), rest,
        sk.offsets.copy(), 0.0, 0.0, 0, sk, 30.0,
    )
    return GaitModel(net, controls, Path("test-model"))


def random_paths(rng: np.random.Generator, count: int) -> list[GroundPath]:
    """A mix: the crowd's 2-point straight paths, random polylines (open and closed), dense
    splines and circles, scattered over 10 m."""
    paths = []
    for k in range(count):
        at = rng.uniform(-5.0, 5.0, 2)
        kind = k % 4
        if kind == 0:
            ahead = rng.uniform(0.3, 2.0) * np.array([np.sin(t := rng.uniform(0, 6.3)), np.cos(t)])
            paths.append(GroundPath.from_polyline(np.stack((at, at + ahead)), name="straight"))
        elif kind == 1:
            steps = rng.normal(0.0, 1.0, (int(rng.integers(2, 7)), 2))
            pts = at + np.concatenate((np.zeros((1, 2)), np.cumsum(steps, 0)))
            paths.append(GroundPath.from_polyline(pts, closed=bool(rng.integers(2))))
        elif kind == 2:
            paths.append(waypoints(at + np.cumsum(rng.uniform(0.5, 2.0, (4, 2)), 0)))
        else:
            paths.append(circle(rng.uniform(0.5, 3.0)))
    return paths


def walking(model: GaitModel, seed: int) -> GaitGenerator:
    """``AGENTS`` agents walked 5 frames along lines, each its own."""
    gen = GaitGenerator(model, seed=seed)
    gen.add_agents([line(5.0 + k) for k in range(AGENTS)], [LABELS[k % 4] for k in range(AGENTS)],
                   starts=[0.3 * k for k in range(AGENTS)])
    for _ in range(5):
        gen.step()
    return gen


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_set_paths_walks_as_set_path_for_each_agent_in_turn(model, seed):
    rng = np.random.default_rng(seed)
    paths = random_paths(rng, AGENTS)
    order = rng.permutation(AGENTS)
    batched, each = walking(model, seed), walking(model, seed)
    agents = [batched.agents[k] for k in order]
    batched.set_paths(agents, [paths[k] for k in order])
    for k in order:
        each.set_path(each.agents[k], paths[k])
    np.testing.assert_allclose(batched.agent_field("arc"), each.agent_field("arc"), atol=1e-9)
    for _ in range(20):
        a, b = batched.step(), each.step()
        np.testing.assert_allclose(a.world, b.world, atol=1e-5)


@pytest.mark.parametrize("seed", [3, 4])
def test_each_agent_starts_from_its_paths_nearest_point(model, seed):
    """The arc each agent gets is ``GroundPath.nearest`` of where it stands, path by path."""
    gen = walking(model, seed)
    paths = random_paths(np.random.default_rng(seed), AGENTS)
    before = gen.step().root
    gen.set_paths(list(gen.agents), paths)
    want = np.array([p.nearest(xz[None])[0][0] for p, xz in zip(paths, before, strict=True)])
    np.testing.assert_allclose(gen.agent_field("arc"), want, atol=1e-9)
    # No jump: the first step after the change moves each agent about one stride of speed.
    after = gen.step().root
    assert np.linalg.norm(after - before, axis=1).max() < 2.0 * SPEED


def test_shared_and_repeated_paths_and_the_last_path_named_wins(model):
    gen = walking(model, 0)
    a, b, c = gen.agents[:3]
    shared, first, last = line(3.0), line(4.0), circle(1.0)
    gen.set_paths([a, b, c, c], [shared, shared, first, last])
    assert gen._agents[c].path is last
    assert gen._agents[a].path is gen._agents[b].path is shared
    assert len(gen._paths) == AGENTS - 3 + 2   # a and b share one slot; c's first is dropped
    gen.set_paths([], [])
    gen.step()


def test_bad_calls_change_nothing(model):
    gen = walking(model, 0)
    arc = gen.agent_field("arc")
    held = [gen._agents[a].path for a in gen.agents]
    with pytest.raises(ValueError, match="one path per agent"):
        gen.set_paths(list(gen.agents), [line(2.0)])
    with pytest.raises(KeyError, match="no live agent with id 99"):
        gen.set_paths([gen.agents[0], 99], [line(2.0), line(3.0)])
    with pytest.raises(PathError, match="GroundPath"):
        gen.set_paths(list(gen.agents[:2]), [line(2.0), [[0, 0], [1, 1]]])
    np.testing.assert_array_equal(gen.agent_field("arc"), arc)
    assert [gen._agents[a].path for a in gen.agents] == held
    assert len(gen._paths) == AGENTS
