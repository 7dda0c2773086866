"""The streaming FCRBM (emotive.models.fcrbm.stream) on the committed checkpoint."""

from __future__ import annotations

import copy
import dataclasses
import time

import numpy as np
import pytest
import torch

from emotive.core.motion import Motion
from emotive.core.ops import heading
from emotive.data.emotion import ALL_LABELS
from emotive.errors import EmotionError, EmotiveError, PathError
from emotive.models.fcrbm.generate import (
    FCRBMDivergedError,
    FCRBMInputError,
    load_fcrbm_model,
    seed_frames,
)
from emotive.models.fcrbm.stream import MAX_SPEED, FCRBMAgentError, FCRBMStream
from emotive.models.fcrbm.stream_gibbs import ContextWeights, gibbs_frame
from emotive.paths import circle, line, waypoints

FRAMES = 150


@pytest.fixture(scope="module")
def model():
    return load_fcrbm_model()


def run(stream: FCRBMStream, frames: int) -> list:
    return [stream.step() for _ in range(frames)]


def test_three_agents_walk_their_paths(model):
    stream = FCRBMStream(model, seed=1)
    paths = [line(20.0), circle(3.0),
             waypoints(np.array([[2.0, 0.0], [4.0, 3.0], [2.0, 6.0], [4.0, 9.0]]))]
    ids = stream.add_agents(paths, ["happy", "sad", {"valence": 0.5, "arousal": 0.8}])
    frames = run(stream, FRAMES)
    last = frames[-1]
    j, p = stream.skeleton.num_joints, stream.skeleton.num_joints + len(
        stream.skeleton.end_site_parents)
    assert last.agents == tuple(ids) == stream.agents
    assert last.rotations.shape == (3, j, 4) and last.positions.shape == (3, j, 3)
    assert last.world.shape == (3, p, 3) and last.emotion.shape == (3, len(ALL_LABELS))
    assert last.root.shape == (3, 2) and last.valence_arousal.shape == (3, 2)
    for f in frames:
        assert all(np.isfinite(a).all() for a in (f.rotations, f.positions, f.world, f.root))
    # The frame is a consistent pose: world = FK of the local rotations and translations.
    fk = Motion(stream.skeleton, last.rotations, last.positions, stream.fps)
    np.testing.assert_allclose(fk.positions_with_end_sites(), last.world, atol=1e-9)
    mover = np.array([f.world[:, stream.mover] for f in frames])  # (T, B, 3)
    np.testing.assert_allclose(mover[:, :, [0, 2]], np.array([f.root for f in frames]))
    walked = np.linalg.norm(np.diff(mover[:, :, [0, 2]], axis=0), axis=-1)
    assert walked.max() <= MAX_SPEED / stream.fps + 1e-9
    for k, path in enumerate(paths):
        arc, distance = path.nearest(mover[:, k, [0, 2]])
        assert distance.max() < 0.5
        assert walked[:, k].sum() > 2.0  # metres in 5 s: the agent walks
        clip = Motion(stream.skeleton, np.array([f.rotations[k] for f in frames]),
                      np.array([f.positions[k] for f in frames]), stream.fps)
        turn = np.angle(np.exp(1j * (heading(clip) - path.heading(arc))))
        assert np.abs(turn).max() < 0.1  # facing along the path (radians)
        if not path.closed:
            assert arc[-1] - arc[0] > 2.0
            assert np.all(np.diff(arc) > -0.05)  # forward along the path, never back
    assert stream.diverged == 0
    np.testing.assert_allclose(last.emotion[0], np.eye(len(ALL_LABELS))[0])  # happy
    np.testing.assert_allclose(last.valence_arousal[2], [0.5, 0.8])


def test_set_emotion_arousal_changes_joint_speed(model):
    stream = FCRBMStream(model, seed=2)
    ids = stream.add_agents([line(40.0)] * 6, ["neutral"] * 6)
    run(stream, 10)
    for k, a in enumerate(ids):
        stream.set_emotion(a, {"valence": 0.0, "arousal": 1.0 if k < 3 else -1.0})
    frames = run(stream, FRAMES)
    world = np.array([f.world for f in frames])  # (T, B, P, 3)
    speed = np.linalg.norm(np.diff(world, axis=0), axis=-1).mean(axis=(0, 2)) * stream.fps
    high, low = speed[:3].mean(), speed[3:].mean()
    print(f"mean joint speed: arousal +1 {high:.2f} m/s, arousal -1 {low:.2f} m/s")
    assert high > 1.3 * low
    np.testing.assert_allclose(frames[-1].valence_arousal[:, 1], [1, 1, 1, -1, -1, -1])


def test_schedule_keeps_changing_the_context(model):
    stream = FCRBMStream(model)
    a = stream.add_agent(circle(2.0))
    stream.set_emotion(a, [{"t": 0, "valence": 0.0, "arousal": -1.0},
                           {"t": 2, "valence": 0.0, "arousal": 1.0}])
    frames = run(stream, 90)
    arousal = np.array([f.valence_arousal[0, 1] for f in frames])
    np.testing.assert_allclose(arousal[[0, 29, 59, 89]], [-1 + 1 / 30, 0.0, 1.0, 1.0],
                               atol=1e-9)
    assert np.all(np.diff(arousal) >= 0)


def test_remove_and_add_in_the_middle(model):
    stream = FCRBMStream(model)
    ids = stream.add_agents([line(20.0), circle(2.0), line(10.0)], ["happy", "sad", "angry"])
    before = run(stream, 20)[-1]
    stream.remove_agent(ids[1])
    after = stream.step()
    assert after.agents == (ids[0], ids[2]) and after.world.shape[0] == 2
    # The others go on where they were (no jump from the removal).
    step = np.linalg.norm(after.root - before.root[[0, 2]], axis=1)
    assert step.max() <= MAX_SPEED / stream.fps + 1e-9
    new = stream.add_agent(circle(3.0), "neutral", start=1.0, pace=1.2)
    assert new not in ids
    frames = run(stream, 20)
    assert frames[-1].agents == (ids[0], ids[2], new)
    assert np.isfinite(frames[-1].world).all()
    with pytest.raises(FCRBMAgentError, match="no live agent") as err:
        stream.remove_agent(ids[1])
    assert isinstance(err.value, KeyError) and isinstance(err.value, EmotiveError)


def test_an_agent_does_not_depend_on_its_batch(model):
    alone = FCRBMStream(model)
    alone.add_agent(line(10.0), "happy", seed=7)
    crowd = FCRBMStream(model)
    crowd.add_agents([circle(2.0), line(10.0), line(5.0)], ["sad", "happy", "happy"],
                     seeds=[1, 7, 3])
    a = np.array([f.world[0] for f in run(alone, 10)])
    b = np.array([f.world[1] for f in run(crowd, 10)])
    np.testing.assert_allclose(a, b, atol=1e-3)


def test_set_target_and_set_path(model):
    stream = FCRBMStream(model)
    a = stream.add_agent(line(30.0))
    run(stream, 10)
    target = np.array([1.5, 4.0])
    path = stream.set_target(a, target)
    np.testing.assert_allclose(path.position(path.length), target, atol=1e-6)
    frames = run(stream, 180)
    assert np.linalg.norm(frames[-1].root[0] - target) < 0.1  # arrives, stays at the end
    here = frames[-1].root[0]
    new = waypoints(np.array([[here[0] + 1.0, here[1]], [here[0] + 1.0, here[1] + 20.0]]))
    stream.set_path(a, new)
    frames = run(stream, 90)
    roots = np.array([f.root[0] for f in frames])
    assert np.linalg.norm(roots[0] - here) <= MAX_SPEED / stream.fps + 1e-9  # no jump
    _, distance = new.nearest(roots)
    assert distance[0] > 0.9 and distance[-1] < 0.05  # merges onto the new path


def test_bad_inputs_raise_typed_errors(model):
    stream = FCRBMStream(model)
    a = stream.add_agent(line(5.0))
    bad = [
        (PathError, lambda: stream.add_agent("circle")),
        (PathError, lambda: stream.add_agent(line(5.0), start=float("nan"))),
        (FCRBMInputError, lambda: stream.add_agent(line(5.0), pace=2.0)),
        (FCRBMInputError, lambda: stream.set_pace(a, "fast")),
        (EmotionError, lambda: stream.add_agent(line(5.0), "furious")),
        (EmotionError, lambda: stream.set_emotion(a, {"valence": float("nan"), "arousal": 0})),
        (EmotionError, lambda: stream.set_emotion(a, {"valence": 3.0, "arousal": 0})),
        (FCRBMAgentError, lambda: stream.set_emotion(99, "happy")),
        (FCRBMAgentError, lambda: stream.set_path(99, line(5.0))),
        (FCRBMAgentError, lambda: stream.set_target(99, (1.0, 1.0))),
        (FCRBMAgentError, lambda: stream.set_pace(99, 1.0)),
        (PathError, lambda: stream.set_path(a, [[0, 0], [1, 1]])),
        (PathError, lambda: stream.set_target(a, (float("nan"), 0.0))),
        (PathError, lambda: stream.set_target(a, (1.0, 2.0, 3.0))),
        (PathError, lambda: stream.set_target(a, "home")),
        (FCRBMInputError, lambda: stream.add_agents([line(5.0)], ["happy", "sad"])),
        (FCRBMInputError, lambda: stream.add_agent(line(5.0), seed=-1)),
        (FCRBMInputError, lambda: stream.add_agent(line(5.0), seed="seven")),
        (FCRBMInputError, lambda: FCRBMStream(model, gibbs=0)),
    ]
    for error, call in bad:
        with pytest.raises(error) as err:
            call()
        assert isinstance(err.value, EmotiveError) and str(err.value)
    assert stream.agents == (a,)  # nothing half-added
    assert np.isfinite(stream.step().world).all()


def test_a_diverged_agent_is_reset_not_fatal(model):
    broken = copy.deepcopy(model)
    stream = FCRBMStream(broken)
    ids = stream.add_agents([line(10.0), line(10.0)], ["happy", "sad"])
    run(stream, 3)
    seed = stream._rows.seed.clone()
    with torch.no_grad():
        broken.network.vis_bias[0] += 100.0  # every new frame leaves the data's range
    frames = run(stream, 5)
    assert stream.diverged == 10 and frames[-1].agents == tuple(ids)
    assert all(np.isfinite(f.world).all() for f in frames)
    torch.testing.assert_close(stream._rows.window, seed)
    with pytest.raises(FCRBMDivergedError, match="warming up"):
        stream.add_agent(line(5.0))


@pytest.mark.parametrize("rate", [60.0, 20.0])
def test_other_model_rates_are_resampled_to_30_fps(model, rate):
    other = dataclasses.replace(model, codec=dataclasses.replace(model.codec, fps=rate))
    stream = FCRBMStream(other)
    stream.add_agent(line(20.0), "happy")
    frames = run(stream, 15)
    assert stream.fps == 30.0 and stream.model_frames == round(15 * rate / 30)
    roots = np.array([f.root[0] for f in frames])
    assert np.all(np.isfinite(roots))
    assert np.linalg.norm(np.diff(roots, axis=0), axis=1).max() <= MAX_SPEED / 30 + 1e-9


def test_context_weights_and_gibbs_frame_match_the_network(model):
    net = model.network
    context = np.array([[2.0, 2.0], [3.0, 1.5], [2.0, 2.0], [1.2, 2.7], [3.0, 1.5]])
    cache = ContextWeights(net)
    with torch.no_grad():
        direct = net.context_weights(net.features(torch.tensor(context, dtype=torch.float32)))
        torch.testing.assert_close(cache.weights(torch.tensor(context, dtype=torch.float32)),
                                   direct, atol=1e-4, rtol=1e-4)
        rng = torch.Generator().manual_seed(0)
        window = torch.from_numpy(seed_frames(model))[None].repeat(5, 1, 1)
        window = window + 0.3 * torch.randn(window.shape, generator=rng)
        # One mean-field iteration: no sampling, so the frames must equal generate's.
        ours = gibbs_frame(net, cache, window, context, torch.zeros(0, 5, net.config.hidden))
        theirs = net.generate(window, torch.tensor(context, dtype=torch.float32)[None], gibbs=1)
    torch.testing.assert_close(ours, theirs[:, 0], atol=1e-4, rtol=1e-4)
    assert len(cache) == 3


def test_rest_pose_and_attributes(model):
    stream = FCRBMStream(model)
    assert stream.labels == ALL_LABELS and stream.fps == 30.0
    rest = stream.rest
    assert rest.num_frames == 1 and rest.skeleton is stream.skeleton
    world = rest.positions_with_end_sites()[0]
    assert np.isfinite(world).all() and 0.7 < world[stream.mover, 1] < 1.1
    assert world[:, 1].min() < 0.15  # feet near the ground: a standing pose


@pytest.mark.parametrize("agents", [1, 50])
def test_step_time(model, agents):
    stream = FCRBMStream(model)
    rng = np.random.default_rng(0)
    emotions = [f"happy={w:.2f},sad={1 - w:.2f}" for w in rng.choice([0.0, 0.5, 1.0], agents)]
    start = time.perf_counter()
    stream.add_agents([circle(2.0)] * agents, emotions)
    added = time.perf_counter() - start
    stream.step()
    times = []
    for _ in range(10):
        start = time.perf_counter()
        frame = stream.step()
        times.append(time.perf_counter() - start)
    print(f"{agents} agents (3 emotions): add {added:.2f} s, step median "
          f"{1e3 * np.median(times):.1f} ms")
    assert frame.world.shape[0] == agents and np.isfinite(frame.world).all()
