"""Tests of animation with the gait network: streaming agents, path following, outputs, bad
input. An untrained narrow network on the small rig, with its predicted speed pinned, so that
path following can be checked exactly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch
from gait_helpers import NUM_JOINTS, make_skeleton

from emotive.core import Motion
from emotive.data.emotion import Emotion, EmotionSchedule
from emotive.errors import ConfigError, EmotionError, OutputError, PathError, RigError
from emotive.io.bvh import read_bvh
from emotive.models.gait import GaitConfig, GaitNetwork
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.generate import STOP_DISTANCE, GaitGenerator, to_model_schedule
from emotive.models.gait.model import GaitModel, load_gait_model
from emotive.models.gait.walks import generate_walks
from emotive.paths import circle, figure8, line, waypoints

LABELS = ("happy", "sad", "angry", "neutral")
SPEED = 0.05  # metres per frame, pinned in the network's speed head


def make_model(fps: float = 30.0, seed: int = 0, turn_slowing: float = 0.0) -> GaitModel:
    torch.manual_seed(seed)
    cfg = GaitConfig(labels=LABELS, num_joints=NUM_JOINTS, fps=fps, enc1_hidden=16, enc1_out=8,
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
        sk.offsets.copy(), 0.0, turn_slowing, 0, sk, fps,
    )
    return GaitModel(net, controls, Path("test-model"))


@pytest.fixture(scope="module")
def model() -> GaitModel:
    return make_model()


def test_agents_stand_on_the_path_advance_by_the_predicted_speed_and_face_along_it(model):
    gen = GaitGenerator(model)
    path = line(20.0)
    gen.add_agent(path, "happy")
    frames = [gen.step() for _ in range(60)]
    root = np.stack([f.root[0] for f in frames])
    np.testing.assert_allclose(root[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(root[:, 1], SPEED * np.arange(1, 61), atol=1e-5)
    # The world hips sit on the path; the body faces +Z (the line's direction).
    world = np.stack([f.world[0] for f in frames])
    np.testing.assert_allclose(world[:, 0, [0, 2]], root, atol=1e-5)
    np.testing.assert_allclose(gen.agent_field("heading"), 0.0, atol=1e-9)
    assert all(np.isfinite(f.world).all() and np.isfinite(f.rotations).all() for f in frames)
    np.testing.assert_allclose(np.linalg.norm(frames[-1].rotations, axis=-1), 1.0, atol=1e-5)


def test_heading_turns_with_a_circle_and_kappa_follows_its_curvature(model):
    gen = GaitGenerator(model)
    path = circle(2.0)
    gen.add_agent(path, "neutral")
    for _ in range(40):
        frame = gen.step()
    arc = SPEED * 40
    tangent = path.heading(arc)
    # delta turns the body towards the inside of the turn (left on this circle), by at most pi.
    assert 0.0 <= gen.agent_field("heading")[0] - tangent <= math.pi + 1e-9
    np.testing.assert_allclose(gen.agent_field("kappa")[0], SPEED**2 * 0.5, rtol=0.05)
    np.testing.assert_allclose(frame.root[0], path.position(arc), atol=1e-6)


def test_the_target_speed_drops_in_turns_by_the_controls_slowing():
    model = make_model(turn_slowing=0.5)
    gen = GaitGenerator(model)
    gen.add_agent(line(30.0), "happy")
    gen.add_agent(circle(1.0), "happy")
    for _ in range(150):
        gen.step()
    # s_lowpass converges to the happy pace, halved on a circle of 1 m (1 - 0.5 * 1/m).
    np.testing.assert_allclose(gen.agent_field("speed_lowpass"), [0.045, 0.0225], rtol=0.02)


def test_a_batch_of_agents_steps_exactly_like_each_agent_alone(model):
    specs = [(line(10.0), "happy"), (figure8(), "sad=0.5,angry=0.5"), (circle(), "neutral")]
    together = GaitGenerator(model, seed=3)
    for path, emotion in specs:
        together.add_agent(path, emotion)
    batched = [together.step() for _ in range(25)]
    for k, (path, emotion) in enumerate(specs):
        alone = GaitGenerator(model, seed=3)
        alone._next_id = k  # the same id, so the same starting phase
        alone.add_agent(path, emotion)
        frames = [alone.step() for _ in range(25)]
        for a, b in zip(frames, batched, strict=True):
            np.testing.assert_allclose(a.world[0], b.world[k], atol=1e-5)


def test_agents_come_and_go_and_change_emotion_and_path_between_steps(model):
    gen = GaitGenerator(model)
    a = gen.add_agent(line(10.0), "happy")
    gen.step()
    b = gen.add_agent(circle(), "sad")
    frame = gen.step()
    assert frame.agents == (a, b) and frame.world.shape[0] == 2
    gen.set_emotion(b, "angry=0.25,neutral=0.75")
    frame = gen.step()
    np.testing.assert_allclose(frame.emotion[1], [0, 0, 0.25, 0.75])
    gen.remove_agent(a)
    frame = gen.step()
    assert frame.agents == (b,) and gen.agents == (b,)
    with pytest.raises(KeyError, match="no live agent"):
        gen.remove_agent(a)
    # A new path: no jump, the gap closes over time.
    before = frame.root[0].copy()
    gen.set_path(b, waypoints(np.array([[3.0, 0.0], [3.0, 10.0]])))
    first = gen.step().root[0]
    assert np.linalg.norm(first - before) < 1.2 * SPEED
    for _ in range(150):
        last = gen.step().root[0]
    assert abs(last[0] - 3.0) < 0.01


def test_an_emotion_schedule_plays_on_the_agent_clock(model):
    gen = GaitGenerator(model)
    schedule = EmotionSchedule.from_keyframes(
        [{"t": 0, "emotion": {"angry": 1}}, {"t": 1, "emotion": {"happy": 1}}], LABELS)
    gen.add_agent(figure8(), schedule)
    emotions = np.stack([gen.step().emotion[0] for _ in range(45)])
    times = np.arange(1, 46) / 30.0
    np.testing.assert_allclose(emotions, schedule.at(times), atol=1e-9)


def test_an_agent_stops_at_the_end_of_an_open_path(model):
    gen = GaitGenerator(model)
    path = line(2.0)
    gen.add_agent(path, "happy")
    for _ in range(300):
        frame = gen.step()
    np.testing.assert_allclose(frame.root[0], path.position(path.length), atol=1e-9)
    assert gen.agent_field("arc")[0] <= path.length
    # Within the last STOP_DISTANCE the target speed falls to zero, so the phase stops too.
    theta = gen.agent_field("theta")
    gen.step()
    np.testing.assert_allclose(gen.agent_field("theta"), theta, atol=1e-3)
    assert STOP_DISTANCE > 0


def test_non_finite_predictions_keep_the_previous_pose():
    model = make_model()
    with torch.no_grad():
        model.network.fc_versors[-1].bias[:] = float("nan")
    gen = GaitGenerator(model)
    gen.add_agent(line(), "happy")
    frames = [gen.step() for _ in range(5)]
    assert all(np.isfinite(f.world).all() for f in frames)


def test_standing_start_and_seed(model):
    a = generate_walks(model, [line()], ["happy"], 1.0, seed=1, foot_lock=False)[0]
    b = generate_walks(model, [line()], ["happy"], 1.0, seed=1, foot_lock=False)[0]
    c = generate_walks(model, [line()], ["happy"], 1.0, seed=2, foot_lock=False)[0]
    np.testing.assert_array_equal(a.motion.rotations, b.motion.rotations)
    assert not np.allclose(a.motion.rotations, c.motion.rotations)
    # Frame 0 is the standing pose at the start of the path; 1 s is 30 steps after it.
    assert a.motion.num_frames == 31 and a.emotion.shape == (31, 4)
    np.testing.assert_allclose(a.motion.rotations[0], model.controls.standing_rotations)


def test_primer_start_and_primer_on_another_rig(model, random_motion):
    sk = model.controls.skeleton
    rest = np.broadcast_to(model.controls.standing_rotations, (20, NUM_JOINTS, 4)).copy()
    positions = np.broadcast_to(sk.offsets, (20, NUM_JOINTS, 3)).copy()
    positions[:, 0, 2] = np.linspace(0, 1, 20)
    primer = Motion(sk, rest, positions, 30.0)
    walk = generate_walks(model, [line()], ["sad"], 0.5, primer=primer)[0]
    assert np.isfinite(walk.motion.positions_with_end_sites()).all()
    with pytest.raises(RigError, match="another rig"):
        generate_walks(model, [line()], ["sad"], 0.5, primer=random_motion())


@pytest.mark.parametrize("emotion, match", [
    ("furious", "unknown"),
    ("happy=-1", r"is -1, outside 0\.\.1"),
    ("happy=nan", "finite|NaN|nan"),
    ("happy=0,sad=0", "zero"),
    ("proud=1", "no emotion 'proud'"),
])
def test_bad_emotions_are_one_line_errors(model, emotion, match):
    with pytest.raises(EmotionError, match=match):
        gen = GaitGenerator(model)
        if emotion == "proud=1":
            gen.add_agent(line(), Emotion.parse(emotion, (*LABELS, "proud")))
        else:
            gen.add_agent(line(), emotion)


def test_bad_paths(model):
    gen = GaitGenerator(model)
    with pytest.raises(PathError):
        gen.add_agent(np.zeros((3, 2)), "happy")
    with pytest.raises(PathError, match="two distinct"):
        waypoints(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(PathError, match="exceeds"):
        waypoints(np.array([[0.0, 0.0], [1e9, 0.0]]))


def test_emotions_over_other_labels_map_onto_the_model(model):
    s = to_model_schedule(Emotion.parse("happy=1", (*LABELS, "proud")), LABELS)
    np.testing.assert_allclose(s.weights, [[1, 0, 0, 0]])
    s = to_model_schedule({"sad": 0.3, "neutral": 0.3}, LABELS)
    np.testing.assert_allclose(s.weights, [[0, 0.5, 0, 0.5]])


def test_files_are_written_at_30_fps_whatever_the_network_rate(tmp_path):
    from emotive.data.emotion import coerce_emotion
    from emotive.models.api import GenerationRequest
    from emotive.models.gait.adapter import GaitWalkGenerator
    from emotive.render.outputs import write_generated

    model = make_model(fps=15.0)
    walk = generate_walks(model, [figure8()], ["angry"], 2.0)[0]
    assert walk.motion.fps == 15.0
    request = GenerationRequest("w", coerce_emotion("angry", LABELS), 2.0, figure8())
    generated = GaitWalkGenerator(model).generate(request)
    written = write_generated(generated, tmp_path / "w.bvh", npz=tmp_path / "w.npz",
                              preview=tmp_path / "w.gif")
    assert [p.name for p in written] == ["w.bvh", "w.npz", "w.gif"]
    motion = read_bvh(tmp_path / "w.bvh")
    # 31 frames at 15 fps are resampled to 62 at 30 fps (emotive.core.ops.resample).
    assert motion.fps == 30.0 and motion.num_frames == 62
    data = np.load(tmp_path / "w.npz")
    assert data["positions"].shape == (62, NUM_JOINTS + 5, 3)
    assert data["emotion"].shape == (62, 4) and float(data["fps"]) == 30.0
    assert list(data["labels"]) == list(LABELS)
    np.testing.assert_allclose(data["positions"], motion.positions_with_end_sites(), atol=1e-3)
    with pytest.raises(OutputError, match="ending in"):
        write_generated(generated, tmp_path / "w.txt")
    with pytest.raises(OutputError, match="does not exist"):
        write_generated(generated, tmp_path / "missing" / "w.bvh")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.bvh", "w.gif", "w.npz"]


def test_corrupt_and_missing_checkpoints(tmp_path):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    with pytest.raises(ConfigError, match="not a gait checkpoint"):
        load_gait_model(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_gait_model(tmp_path / "none.pt")


def test_a_thousand_own_paths_walk_as_the_same_paths_shared(model):
    """Distinct path objects (the bank) give exactly what one shared object gives."""
    own, shared = GaitGenerator(model), GaitGenerator(model)
    one = circle(2.0)
    for i in range(12):
        own.add_agent(circle(2.0), "happy", start=0.3 * i, seed=i)
        shared.add_agent(one, "happy", start=0.3 * i, seed=i)
    for _ in range(40):
        a, b = own.step(), shared.step()
    np.testing.assert_allclose(a.world, b.world, atol=1e-9)


def test_set_target_walks_to_the_point_without_a_jump_and_stops_there(model):
    gen = GaitGenerator(model)
    a = gen.add_agent(line(20.0), "happy")
    for _ in range(30):
        before = gen.step().root[0]
    path = gen.set_target(a, (2.0, 4.0))
    assert np.linalg.norm(path.position(0.0) - before) < 1e-9
    roots = np.stack([gen.step().root[0] for _ in range(400)])
    assert np.linalg.norm(roots[0] - before) <= SPEED + 1e-6  # one frame's walk, no jump
    np.testing.assert_allclose(roots[-1], (2.0, 4.0), atol=1e-6)
    with pytest.raises(PathError, match="two finite numbers"):
        gen.set_target(a, (np.nan, 1.0))
    with pytest.raises(KeyError, match="no live agent"):
        gen.set_target(99, (0.0, 0.0))


def test_pace_scales_the_emotions_target_speed_and_is_bounded(model):
    gen = GaitGenerator(model)
    slow = gen.add_agent(line(50.0), "happy", pace=0.5)
    gen.add_agent(line(50.0), "happy")
    fast = gen.add_agent(line(50.0), "happy")
    gen.set_pace(fast, 1.5)
    for _ in range(150):
        gen.step()
    target = model.controls.speed[0]
    np.testing.assert_allclose(gen.agent_field("speed_lowpass"),
                               [0.5 * target, target, 1.5 * target], rtol=0.02)
    with pytest.raises(ValueError, match=r"between 0\.5 and 1\.5"):
        gen.set_pace(slow, 2.0)
    with pytest.raises(ValueError, match=r"between 0\.5 and 1\.5"):
        gen.add_agent(line(), "happy", pace=float("nan"))


def test_adding_and_removing_agents_keeps_every_field_in_step(model):
    gen = GaitGenerator(model)
    ids = [gen.add_agent(circle(1.0 + 0.1 * i), "sad", seed=i) for i in range(5)]
    for _ in range(5):
        gen.step()
    kept_rows = gen._batch.rows[[0, 2, 4]].clone()
    kept_state = gen._batch.state[:, [0, 2, 4]].clone()
    kept_world = gen.first_frame().world[[0, 2, 4]]
    gen.remove_agent(ids[1])
    gen.remove_agent(ids[3])
    assert gen.agents == (ids[0], ids[2], ids[4])
    b = gen._batch
    assert {len(b), b.state.shape[1], len(b.rows), len(b.emotion), len(b.slot)} == {3}
    # The kept agents' fields are copied, so they are the same to the bit; their pose is
    # computed again in float32 over a batch of another shape, whose kernels may round
    # differently (3e-8 m seen), so it is compared within float32's spread over a chain
    # of joints about a metre from the root: 20 products of eps 1.2e-7 each, 1e-5 m.
    assert torch.equal(b.rows, kept_rows) and torch.equal(b.state, kept_state)
    np.testing.assert_allclose(gen.first_frame().world, kept_world, rtol=0, atol=1e-5)
    assert len(gen._paths) == 3
