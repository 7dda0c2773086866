"""Frames, codec, training loop and generation of the FCRBM on synthetic walks (no data)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from cli_helpers import assert_failed_cleanly
from emotive.core import Motion, Skeleton
from emotive.core.ops import canonicalize_facing
from emotive.errors import ConfigError, DataError, EmotionError, RigError
from emotive.models.fcrbm.checkpoint import export_fcrbm_checkpoint, load_fcrbm_checkpoint
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.data import FrameCodec, clip_context, frame_vectors, step_rate
from emotive.models.fcrbm.generate import (
    FCRBMDivergedError,
    FCRBMInputError,
    FCRBMModel,
    constant_context,
    decode_frames,
    emotion_context,
    generate_motion,
    load_fcrbm_model,
    schedule_context,
    seed_frames,
)
from emotive.models.fcrbm.model import FCRBM
from emotive.models.fcrbm.training import (
    ENERGY_CLIP,
    ENERGY_SPREAD,
    MIN_CONTEXT,
    FCRBMData,
    FCRBMTrainSettings,
    edge_energy_contexts,
    load_fcrbm_settings,
    train_fcrbm,
)
from emotive.transforms.np_rotations import axis_angle_to_quaternion
from rigs import RIG

FPS = 30.0


def walk(frames: int = 90, speed: float = 1.0, turn: float = 0.3, swing: float = 0.3) -> Motion:
    """A synthetic walk on :data:`RIG` curving at ``turn`` rad/s, legs and arms swinging."""
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    sk = Skeleton(tuple(r[0] for r in RIG), np.array([r[1] for r in RIG]),
                  np.array([r[2] for r in RIG], dtype=float),
                  end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends])
    idx = {r[0]: j for j, r in enumerate(RIG)}
    t = np.arange(frames) / FPS
    phase = 2 * np.pi * t * (1 + speed)
    aa = np.zeros((frames, len(RIG), 3))
    yaw = turn * t
    aa[:, 0, 1] = yaw
    for s, sign in (("L", 1.0), ("R", -1.0)):
        aa[:, idx[f"UpperLeg_{s}"], 0] = -0.2 + sign * swing * np.sin(phase)
        aa[:, idx[f"LowerLeg_{s}"], 0] = 0.4 + 0.2 * np.cos(phase)
        aa[:, idx[f"UpperArm_{s}"], 0] = -sign * swing * np.sin(phase)
    positions = np.broadcast_to(sk.offsets, (frames, len(RIG), 3)).copy()
    step = speed / FPS
    positions[:, 0, 0] += np.cumsum(step * np.sin(yaw))
    positions[:, 0, 2] += np.cumsum(step * np.cos(yaw))
    return Motion(sk, axis_angle_to_quaternion(aa), positions, FPS, {"name": "synthetic"})


def test_frames_round_trip_through_the_codec():
    m = walk()
    frames = frame_vectors(m)
    codec = FrameCodec.fit([frames, frame_vectors(walk(speed=0.5))], [m, walk(speed=0.5)])
    assert frames.shape == (m.num_frames, 4 + 3 * m.skeleton.num_joints)
    assert codec.dim < frames.shape[1]  # joints that never move are left out
    back = codec.decode(codec.encode(frames))
    a = canonicalize_facing(m).positions_with_end_sites()
    b = canonicalize_facing(back).positions_with_end_sites()
    assert np.abs(a - b).max() < 1e-4
    again = FrameCodec.from_dict(json.loads(json.dumps(codec.to_dict())))
    np.testing.assert_allclose(again.encode(frames), codec.encode(frames))


def test_joints_near_pi_encode_continuously_relative_to_their_mean_rotation():
    """A joint posed near 180 degrees (as the Bandai Namco upper legs) has a raw exponential
    map that flips to the opposite side whenever the angle crosses pi; the codec expresses it
    relative to the joint's mean rotation, where it is smooth, and decodes it back exactly."""
    from rigs import RIG

    m = walk(120)
    leg = [r[0] for r in RIG].index("UpperLeg_L")
    t = np.arange(m.num_frames) / FPS
    aa = np.zeros((m.num_frames, 3))
    aa[:, 0] = np.pi - 0.05 + 0.3 * np.sin(2 * np.pi * 1.5 * t)  # crosses pi every stride
    from emotive.transforms.np_rotations import quaternion_multiply

    rot = m.rotations.copy()
    rot[:, leg] = quaternion_multiply(axis_angle_to_quaternion(aa), rot[:, leg])
    m = m.replace(rotations=rot)
    frames = frame_vectors(m)
    raw = frames[:, 4 + 3 * leg: 7 + 3 * leg]
    assert np.abs(np.diff(raw, axis=0)).max() > 3.0  # the flips the codec must remove
    codec = FrameCodec.fit([frames], [m])
    cols = np.isin(codec.keep, np.arange(4 + 3 * leg, 7 + 3 * leg))
    assert cols.any()
    x = (codec.encode(frames) * codec.std)[:, cols]  # radians again
    # At most the walk's own swing plus the added one per frame (0.13 + 0.09 rad).
    assert np.abs(np.diff(x, axis=0)).max() < 0.25
    back = codec.decode(codec.encode(frames))
    a = canonicalize_facing(m).positions_with_end_sites()
    b = canonicalize_facing(back).positions_with_end_sites()
    assert np.abs(a - b).max() < 1e-4
    again = FrameCodec.from_dict(json.loads(json.dumps(codec.to_dict())))
    np.testing.assert_allclose(again.reference, codec.reference)
    np.testing.assert_allclose(again.encode(frames), codec.encode(frames), atol=1e-6)
    # A codec saved before the references existed still loads, relative to the identity.
    old = codec.to_dict() | {"reference": None}
    assert FrameCodec.from_dict(old).reference is None


def test_joint_axes_moving_less_than_a_degree_are_left_out():
    from rigs import RIG

    m = walk(120)
    head = [r[0] for r in RIG].index("Head")
    rng = np.random.default_rng(0)
    aa = np.zeros((m.num_frames, 3))
    aa[:, 2] = np.deg2rad(0.2) * rng.standard_normal(m.num_frames)  # capture noise only
    from emotive.transforms.np_rotations import quaternion_multiply

    rot = m.rotations.copy()
    rot[:, head] = quaternion_multiply(axis_angle_to_quaternion(aa), rot[:, head])
    m = m.replace(rotations=rot)
    codec = FrameCodec.fit([frame_vectors(m)], [m])
    cols = set(range(4 + 3 * head, 7 + 3 * head))
    assert not cols & set(codec.keep.tolist())
    assert set(codec.keep.tolist()) - cols  # the joints that do move are kept


def test_bad_clips_raise():
    m = walk()
    with pytest.raises(DataError, match="at least 2 frames"):
        frame_vectors(m.replace(rotations=m.rotations[:1], positions=m.positions[:1]))
    rot = m.rotations.copy()
    rot[3, 2] = np.nan
    with pytest.raises(DataError, match="NaN"):
        frame_vectors(m.replace(rotations=rot))
    sk = m.skeleton
    # Unknown names on a rest pose that tells neither left from right nor legs from arms.
    odd = Skeleton(tuple(f"bone{j}" for j in range(sk.num_joints)), sk.parents,
                   np.tile([0.0, 0.1, 0.0], (sk.num_joints, 1)))
    with pytest.raises(RigError, match="joint roles"):
        frame_vectors(Motion(odd, m.rotations, m.positions, FPS))


def test_context_scale_and_inputs(tmp_path):
    np.testing.assert_allclose(clip_context("normal", 3), 2.0)
    assert clip_context("happy", 1)[0, 0] > 2.9  # Russell's happy: high valence
    np.testing.assert_allclose(emotion_context("neutral"), [2.0, 2.0])
    for v, a in ((np.nan, 2), (2, 0), (2, -1), (2, 99)):
        with pytest.raises(FCRBMInputError, match="valence and arousal"):
            constant_context(v, a, 5)
    path = tmp_path / "s.json"
    path.write_text(json.dumps([{"t": 0, "valence": 3, "arousal": 1},
                                {"t": 1, "emotion": "neutral"}]))
    z = schedule_context(path, 61, FPS)
    np.testing.assert_allclose(z[0], [3, 1])
    np.testing.assert_allclose(z[15], [2.5, 1.5])
    np.testing.assert_allclose(z[-1], [2, 2])
    path.write_text(json.dumps([{"t": 0}]))
    with pytest.raises(FCRBMInputError, match="valence"):
        schedule_context(path, 5, FPS)
    path.write_text("not json")
    with pytest.raises(FCRBMInputError, match="cannot read"):
        schedule_context(path, 5, FPS)


def synthetic_data(order: int) -> FCRBMData:
    """Slow low-arousal walks and fast high-arousal walks."""
    clips = {"slow": (walk(120, speed=0.4, swing=0.15), 1.0),
             "fast": (walk(120, speed=1.4, swing=0.4), 3.0),
             "slow-val": (walk(90, speed=0.4, swing=0.15), 1.0)}
    frames = {k: frame_vectors(m) for k, (m, _) in clips.items()}
    codec = FrameCodec.fit([frames["slow"], frames["fast"]],
                           [clips["slow"][0], clips["fast"][0]])

    def item(k):
        return (k, codec.encode(frames[k]),
                np.tile([2.0, clips[k][1]], (len(frames[k]), 1)))

    return FCRBMData(codec, {"train": [item("slow"), item("fast")], "val": [item("slow-val")]})


def test_training_writes_checkpoints_resumes_and_generates(tmp_path):
    torch.manual_seed(0)
    config = FCRBMConfig(visible=1, order=3, hidden=32, factors=16, factors_past_visible=16,
                         factors_past_hidden=16, learning_rate=1e-3, gibbs=5)
    settings = FCRBMTrainSettings(epochs=2, batch_size=32, past_noise=0.5)
    data = synthetic_data(config.order)
    result = train_fcrbm(config, settings, progress=False, out_dir=tmp_path, data=data)
    assert [r["epoch"] for r in result.history] == [1, 2]
    assert all(np.isfinite(r["val_one_step"]) for r in result.history)
    assert (tmp_path / "best.pt").exists() and (tmp_path / "log.csv").exists()
    more = train_fcrbm(config, replace(settings, epochs=3), progress=False, out_dir=tmp_path,
                       data=data, resume=True)
    assert [r["epoch"] for r in more.history] == [1, 2, 3]
    with pytest.raises(ConfigError, match=r"other \[train\] settings"):
        train_fcrbm(config, replace(settings, batch_size=7, epochs=4), progress=False,
                    out_dir=tmp_path, data=data, resume=True)
    network, codec, _ = load_fcrbm_checkpoint(tmp_path / "last.pt")
    model = FCRBMModel(network, codec)
    motion, _ = generate_motion(model, constant_context(2, 2, 40), seed=1)
    assert motion.num_frames == 40 and np.isfinite(motion.positions).all()
    again, _ = generate_motion(model, constant_context(2, 2, 40), seed=1)
    np.testing.assert_array_equal(again.positions, motion.positions)
    with pytest.raises(FCRBMInputError, match="initial frames"):
        seed_frames(model, walk(3))


def test_training_without_visible_autoregression(tmp_path):
    config = FCRBMConfig(visible=1, order=3, hidden=16, factors=8, factors_past_visible=8,
                         factors_past_hidden=8, gibbs=3, init_std=0.1,
                         visible_autoregression=False)
    batches = []
    result = train_fcrbm(config, FCRBMTrainSettings(epochs=2, batch_size=32,
                                                    balance_contexts=True),
                         progress=False, out_dir=tmp_path, data=synthetic_data(config.order),
                         on_batch=lambda epoch, batch: batches.append(batch))
    assert [r["ar_radius"] for r in result.history] == [0.0, 0.0]
    # Two contexts of 117 examples each: balanced already, 234 a epoch in 8 batches of 32.
    assert batches == list(range(8)) * 2
    network, codec, _ = load_fcrbm_checkpoint(tmp_path / "last.pt")
    assert not network.config.visible_autoregression and not hasattr(network, "a_past")
    for name, value in network.state_dict().items():
        torch.testing.assert_close(value, result.model.state_dict()[name])
    motion, frames = generate_motion(FCRBMModel(network, codec), constant_context(3.5, 3.5, 60))
    assert motion.num_frames == 60 and np.isfinite(frames).all()
    slim = export_fcrbm_checkpoint(tmp_path / "last.pt", tmp_path / "slim.pt")
    assert "velocity" not in torch.load(slim, weights_only=True)
    again, _ = generate_motion(FCRBMModel(*load_fcrbm_checkpoint(slim)[:2]),
                               constant_context(3.5, 3.5, 60))
    np.testing.assert_allclose(again.positions, motion.positions, atol=1e-5)
    with pytest.raises(ConfigError, match="not a usable FCRBM"):
        export_fcrbm_checkpoint(tmp_path / "log.csv", tmp_path / "bad.pt")
    assert not (tmp_path / "bad.pt").exists()


def test_rbf_context_features_train_resume_and_generate(tmp_path):
    config = FCRBMConfig(visible=1, order=3, hidden=16, factors=8, factors_past_visible=8,
                         factors_past_hidden=8, gibbs=3, init_std=0.1,
                         visible_autoregression=False, context_features="rbf")
    settings = FCRBMTrainSettings(epochs=1, batch_size=32)
    data = synthetic_data(config.order)
    train_fcrbm(config, settings, progress=False, out_dir=tmp_path, data=data)
    more = train_fcrbm(config, replace(settings, epochs=2), progress=False, out_dir=tmp_path,
                       data=data, resume=True)
    assert [r["epoch"] for r in more.history] == [1, 2]
    with pytest.raises(ConfigError, match=r"another \[model\] config"):
        train_fcrbm(replace(config, context_features="linear"), replace(settings, epochs=3),
                    progress=False, out_dir=tmp_path, data=data, resume=True)
    network, codec, _ = load_fcrbm_checkpoint(tmp_path / "last.pt")
    assert network.config.context_features == "rbf" and network.w_ctx.shape == (11, 8)
    motion, frames = generate_motion(FCRBMModel(network, codec), constant_context(3.5, 1, 60))
    assert motion.num_frames == 60 and np.isfinite(frames).all()


def test_a_checkpoint_from_before_context_features_resumes_as_linear(tmp_path):
    config = FCRBMConfig(visible=1, order=3, hidden=8, factors=4, factors_past_visible=4,
                         factors_past_hidden=4, gibbs=2, visible_autoregression=False)
    settings = FCRBMTrainSettings(epochs=1, batch_size=64)
    data = synthetic_data(config.order)
    train_fcrbm(config, settings, progress=False, out_dir=tmp_path, data=data)
    ckpt = torch.load(tmp_path / "last.pt", weights_only=False)
    del ckpt["config"]["context_features"]
    torch.save(ckpt, tmp_path / "last.pt")
    more = train_fcrbm(config, replace(settings, epochs=2), progress=False, out_dir=tmp_path,
                       data=data, resume=True)
    assert [r["epoch"] for r in more.history] == [1, 2]
    assert more.model.config.context_features == "linear"


def test_divergence_is_a_clear_error(tmp_path):
    config = FCRBMConfig(visible=1, order=3, hidden=8, factors=4, factors_past_visible=4,
                         factors_past_hidden=4, gibbs=2)
    data = synthetic_data(config.order)
    result = train_fcrbm(config, FCRBMTrainSettings(epochs=1), progress=False,
                         out_dir=tmp_path, data=data)
    with torch.no_grad():
        # An autoregressive gain far above one: every frame grows without bound.
        result.model.a_vis.fill_(3.0)
        result.model.a_past.fill_(3.0)
        result.model.a_ctx.fill_(3.0)
    with pytest.raises(FCRBMDivergedError, match="diverged"):
        generate_motion(FCRBMModel(result.model, result.codec), constant_context(2, 2, 30))


def test_settings_file(tmp_path):
    config, settings = load_fcrbm_settings("configs/fcrbm.toml")
    assert (config.order, config.hidden, config.factors) == (6, 1000, 600)
    assert not config.visible_autoregression
    assert settings.contents == ("walk",)
    bad = tmp_path / "bad.toml"
    for text, words in (("[model]\nvisible = 5", "set from the data"),
                        ("[train]\npast_noise = -1", "past_noise"),
                        ("[train]\ncontext_noise = 1.5", "context_noise"),
                        ("[train]\nedge_energy = -0.1", "edge_energy"),
                        ("[train]\nlow_arousal_weight = 0", "low_arousal_weight")):
        bad.write_text(text + "\n")
        with pytest.raises(ConfigError, match=words):
            load_fcrbm_settings(bad)


#: A tiny model for tests of what training feeds it.
TINY = FCRBMConfig(visible=1, order=3, hidden=8, factors=4, factors_past_visible=4,
                   factors_past_hidden=4, gibbs=2, visible_autoregression=False)


def training_contexts(monkeypatch) -> list[torch.Tensor]:
    """The list that every later ``train_step`` appends its ``(B, 2)`` context to."""
    seen = []
    step = FCRBM.train_step

    def recording(self, v, past, context, generator=None):
        seen.append(context.clone())
        return step(self, v, past, context, generator)

    monkeypatch.setattr(FCRBM, "train_step", recording)
    return seen


@pytest.mark.parametrize("noise", [0.0, 0.5])
def test_context_noise_jitters_each_training_context(tmp_path, monkeypatch, noise):
    config, seen = TINY, training_contexts(monkeypatch)
    data = synthetic_data(config.order)
    train_fcrbm(config, FCRBMTrainSettings(epochs=1, batch_size=50, context_noise=noise),
                progress=False, out_dir=tmp_path, data=data)
    z = torch.cat(seen)
    clean = {(2.0, 1.0), (2.0, 3.0)}  # the synthetic slow and fast walks
    if not noise:
        assert {tuple(row) for row in z.tolist()} == clean
        return
    valence = z[:, 0].double()
    assert abs(float(valence.mean()) - 2.0) < 0.1
    assert abs(float(valence.std()) - noise) < 0.05
    assert float(z.min()) >= MIN_CONTEXT


def contacts_at(strikes: list[int], frames: int) -> np.ndarray:
    """``(frames, 2)`` contacts whose rising edges are ``strikes``, feet alternating."""
    contacts = np.zeros((frames, 2), dtype=bool)
    for k, frame in enumerate(strikes):
        contacts[frame:frame + 5, k % 2] = True
    return contacts


def test_step_rate_is_the_rate_between_the_strikes_around_each_frame(monkeypatch):
    from emotive.models.fcrbm import data as fcrbm_data

    strikes = [*range(15, 91, 15), *range(100, 171, 10)]  # 2 steps/s, then 3
    monkeypatch.setattr(fcrbm_data, "foot_contacts",
                        lambda positions, roles, fps: contacts_at(strikes, len(positions)))
    motion = walk(180)
    codec = FrameCodec.fit([frame_vectors(motion)], [motion])
    rate = step_rate(codec.encode(frame_vectors(motion)), codec)
    assert rate.shape == (180,)
    np.testing.assert_allclose(rate[:75], 2.0)  # before the first strike too
    np.testing.assert_allclose(rate[115:], 3.0)  # after the last strike too
    assert np.all(np.diff(rate) >= 0)
    strikes = [40]  # one strike: no interval to measure (the patched contacts read it)
    assert not step_rate(codec.encode(frame_vectors(motion)), codec).any()


@pytest.mark.data
def test_step_rate_of_a_real_walk_matches_its_counted_strikes(bandai1_dir):
    from emotive.core.roles import resolve_roles
    from emotive.features.contacts import foot_contacts, foot_strikes
    from emotive.io.bvh import read_bvh

    motion = read_bvh(bandai1_dir / "data" / "dataset-1_walk_angry_001.bvh")
    codec = FrameCodec.fit([frame_vectors(motion)], [motion])
    rate = step_rate(codec.encode(frame_vectors(motion)), codec)
    strikes = np.flatnonzero(foot_strikes(foot_contacts(
        motion.positions_with_end_sites(), resolve_roles(motion.skeleton), motion.fps)).any(1))
    counted = (len(strikes) - 1) * motion.fps / (strikes[-1] - strikes[0])
    assert 2.0 < counted < 3.0
    assert rate[strikes[0]:strikes[-1]].mean() == pytest.approx(counted, rel=0.05)


#: Metres of root path per step of :func:`stride_contacts`.
STEP_LENGTH = 0.35


def stride_contacts(positions: np.ndarray, roles, fps: float) -> np.ndarray:
    """Contacts of a walker whose every step is :data:`STEP_LENGTH` of its root's path."""
    root = positions[:, roles.index["root"]][:, [0, 2]]
    travelled = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(root, axis=0), axis=1))))
    strikes = np.flatnonzero(np.diff(np.floor(travelled / STEP_LENGTH)) > 0) + 1
    return contacts_at(list(strikes), len(positions))


def energetic_data() -> FCRBMData:
    """Clips of a low-edge, a middle and a high-edge style whose second half walks faster."""
    def clip(arousal):
        first, second = walk(90, speed=0.8, swing=0.2), walk(90, speed=1.6, swing=0.4)
        return frame_vectors(first), frame_vectors(second), arousal

    parts = {"tired": clip(1.0), "neutral": clip(2.0), "angry": clip(3.0)}
    codec = FrameCodec.fit([f for a, b, _ in parts.values() for f in (a, b)],
                           [walk(90, speed=0.8, swing=0.2), walk(90, speed=1.6, swing=0.4)] * 3)
    items = [(k, codec.encode(np.concatenate((a, b))), np.tile([2.0, z], (180, 1)))
             for k, (a, b, z) in parts.items()]
    return FCRBMData(codec, {"train": items, "val": items[2:]})


@pytest.fixture
def stepping(monkeypatch):
    """Foot contacts from :func:`stride_contacts`: the synthetic walks' feet slide."""
    from emotive.models.fcrbm import data as fcrbm_data

    monkeypatch.setattr(fcrbm_data, "foot_contacts", stride_contacts)


def test_edge_energy_raises_only_the_high_edge_style_by_how_fast_it_steps(stepping):
    data = energetic_data()
    moved = edge_energy_contexts(data, 0.25)
    for (name, frames, base), (name2, frames2, shifted) in zip(
            data.splits["train"], moved.splits["train"], strict=True):
        assert name == name2 and frames2 is frames
        np.testing.assert_array_equal(shifted[:, 0], base[:, 0])  # valence untouched
        change = shifted[:, 1] - base[:, 1]
        assert np.abs(change).max() <= 0.25 * ENERGY_CLIP + 1e-12
        if name == "angry":  # the faster half is labelled more aroused, the slower kept
            assert (change >= 0).all() and change[120:].min() > 0.1 and not change[:60].any()
        else:  # neutral, and tired at the low edge
            assert not change.any()
    # the energy score is the z-score of the step rate over ENERGY_SPREAD
    rate = step_rate(data.splits["train"][2][1], data.codec)
    score = (rate - rate.mean()) / rate.std()
    expected = 0.25 * np.clip(score / ENERGY_SPREAD, -ENERGY_CLIP, ENERGY_CLIP).clip(0)
    np.testing.assert_allclose(moved.splits["train"][2][2][:, 1] - 3.0, expected)
    np.testing.assert_array_equal(moved.splits["val"][0][2], moved.splits["train"][2][2])
    lonely = FCRBMData(data.codec, {"train": data.splits["train"][:1],
                                    "val": data.splits["train"][2:]})
    with pytest.raises(DataError, match="no training clip"):
        edge_energy_contexts(lonely, 0.25)


def test_training_with_edge_energy_sees_the_moved_arousal_and_balances_by_style(
        tmp_path, monkeypatch, stepping):
    config, seen = TINY, training_contexts(monkeypatch)
    data = energetic_data()
    name, frames, context = data.splits["train"][1]
    data.splits["train"][1] = (name, frames[:90], context[:90])  # neutral: half as long
    settings = FCRBMTrainSettings(epochs=1, batch_size=60, edge_energy=0.25,
                                  balance_contexts=True)
    train_fcrbm(config, settings, progress=False, out_dir=tmp_path, data=data)
    z = torch.cat(seen).double()
    # balanced by style, not by the moved values: the neutral examples twice, the others once
    assert len(z) == 2 * (180 - config.order) + 2 * (90 - config.order)
    assert float(z[:, 1].max()) > 3.1 and float(z[:, 1].min()) == 1.0
    middle = z[(z[:, 1] > 1.5) & (z[:, 1] < 2.5), 1]
    assert len(middle) == 2 * (90 - config.order) and (middle == 2.0).all()


@pytest.mark.parametrize("weight", [1, 3])
def test_low_arousal_weight_repeats_the_low_edge_styles(tmp_path, monkeypatch, weight):
    config, seen = TINY, training_contexts(monkeypatch)
    settings = FCRBMTrainSettings(epochs=1, batch_size=60, low_arousal_weight=weight)
    train_fcrbm(config, settings, progress=False, out_dir=tmp_path,
                data=energetic_data())
    arousal = torch.cat(seen)[:, 1]
    per_style = 180 - config.order
    assert int((arousal == 1.0).sum()) == weight * per_style
    assert int((arousal == 2.0).sum()) == int((arousal == 3.0).sum()) == per_style


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    """A tiny FCRBM trained for one epoch on the synthetic walks."""
    out = tmp_path_factory.mktemp("fcrbm")
    config = FCRBMConfig(visible=1, order=3, hidden=16, factors=8, factors_past_visible=8,
                         factors_past_hidden=8, gibbs=3, init_std=0.1)
    train_fcrbm(config, FCRBMTrainSettings(epochs=1, batch_size=32, past_noise=0.5),
                progress=False, out_dir=out, data=synthetic_data(config.order))
    return out / "last.pt"


def invoke_fcrbm(*args: object):
    from typer.testing import CliRunner

    from emotive.commands.fcrbm import app

    return CliRunner().invoke(app, [*map(str, args)], env={"COLUMNS": "200"})


def test_generate_command_writes_bvh_and_preview(checkpoint, tmp_path):
    from emotive.io.bvh import read_bvh

    out, video = tmp_path / "walk.bvh", tmp_path / "walk.gif"
    result = invoke_fcrbm("generate", "--model", checkpoint, "--valence", 0.5, "--arousal", 1,
                          "--seconds", 1, "--out", out, "--preview", video)
    assert result.exit_code == 0, result.output
    assert result.output.startswith("deprecated: `emotive fcrbm generate`")
    motion = read_bvh(out)
    assert motion.num_frames == 30 and np.isfinite(motion.positions).all()
    assert video.stat().st_size > 0
    schedule = tmp_path / "s.json"
    schedule.write_text(json.dumps([{"t": 0, "emotion": "sad"}, {"t": 1, "valence": 1,
                                                                "arousal": 1}]))
    result = invoke_fcrbm("generate", "--model", checkpoint, "--schedule", schedule,
                          "--seconds", 1, "--out", tmp_path / "t.bvh")
    assert result.exit_code == 0, result.output
    result = invoke_fcrbm("generate", "--model", checkpoint, "--emotion", "happy",
                          "--seconds", 0.5, "--out", tmp_path / "h.bvh")
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(
    ("args", "error", "words"),
    [
        (["--valence", 0, "--emotion", "sad"], EmotionError, ["exactly one", "--emotion"]),
        (["--valence", 0], EmotionError, ["both --valence and --arousal"]),
        ([], EmotionError, ["exactly one"]),
        (["--valence", "nan", "--arousal", 0], EmotionError, ["valence"]),
        (["--valence", 3, "--arousal", 1], EmotionError, ["old FCRBM 1..3 scale",
                                                          "subtract 2: valence=1"]),
        (["--emotion", "bored"], EmotionError, ["bored"]),
        (["--emotion", "sad", "--root", "hips"], FCRBMInputError, ["--root", "feet", "model"]),
        (["--emotion", "sad", "--model", "missing.pt"], ConfigError, ["missing.pt",
                                                                    "checkpoint not found"]),
    ],
)
def test_generate_command_errors_write_nothing(checkpoint, tmp_path, args, error, words):
    args = [a if a != "missing.pt" else tmp_path / "missing.pt" for a in args]
    if "--model" not in args:
        args += ["--model", checkpoint]
    before = sorted(tmp_path.iterdir())
    result = invoke_fcrbm("generate", *args, "--seconds", 1, "--out", tmp_path / "x.bvh")
    assert_failed_cleanly(result, error, words, tmp_path, before)


def test_the_root_path_is_rebuilt_from_the_feet_unless_asked_for_the_models(checkpoint):
    from emotive.ik import root_from_stance

    model = load_fcrbm_model(checkpoint)
    context = constant_context(2, 2, 60)
    feet, frames = generate_motion(model, context, seed=3)
    own, same = generate_motion(model, context, seed=3, root="model")
    np.testing.assert_array_equal(frames, same)
    np.testing.assert_array_equal(own.positions, model.codec.decode(frames).positions)
    np.testing.assert_allclose(feet.positions, root_from_stance(own).positions)
    np.testing.assert_array_equal(feet.rotations, own.rotations)
    assert not np.allclose(feet.positions[:, 0], own.positions[:, 0])
    with pytest.raises(FCRBMInputError, match="--root must be one of feet, model"):
        decode_frames(model, frames, root="hips")


def test_generate_command_refuses_a_primer_that_is_no_humanoid(checkpoint, tmp_path):
    """A primer on any humanoid rig is retargeted; one that is no humanoid is refused."""
    from emotive.errors import RigError
    from emotive.io.bvh import write_bvh

    chain = Skeleton(("A", "B", "C"), np.array([-1, 0, 1]),
                     np.array([[0.0, 0.9, 0.0], [0.0, 0.4, 0.0], [0.0, 0.4, 0.0]]),
                     end_site_parents=[2], end_site_offsets=[[0.0, 0.1, 0.0]])
    rot = np.zeros((20, 3, 4))
    rot[..., 0] = 1.0
    primer = write_bvh(Motion(chain, rot, np.broadcast_to(chain.offsets, (20, 3, 3)).copy(),
                              FPS), tmp_path / "p.bvh")
    result = invoke_fcrbm("generate", "--model", checkpoint, "--emotion", "sad", "--primer",
                          primer, "--seconds", 1, "--out", tmp_path / "x.bvh")
    assert isinstance(result.exception, RigError | FCRBMInputError), result.exception
    assert "another rig" in str(result.exception)
    assert not (tmp_path / "x.bvh").exists()


def test_train_command_reports_config_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[train]\nmax_ar_radius = 2\n")
    result = invoke_fcrbm("train", "--config", bad, "--out", tmp_path / "run")
    assert isinstance(result.exception, ConfigError)
    assert "max_ar_radius" in str(result.exception)
    assert not (tmp_path / "run").exists()


def test_generate_without_a_model_says_how_to_get_one(tmp_path, monkeypatch):
    from emotive.models.fcrbm import generate

    monkeypatch.setattr(generate, "default_checkpoint_path", lambda: tmp_path / "none.pt")
    result = invoke_fcrbm("generate", "--emotion", "sad", "--out", tmp_path / "x.bvh")
    assert isinstance(result.exception, ConfigError)
    assert "emotive fcrbm train" in str(result.exception) and "--model" in str(result.exception)
    assert not (tmp_path / "x.bvh").exists()


@pytest.mark.data
def test_the_styles_setting_trains_on_the_named_styles_only(bandai1_dir):
    from emotive.errors import DataError
    from emotive.models.fcrbm.training import load_fcrbm_data

    settings = FCRBMTrainSettings(datasets=("bandai-namco-1",),
                                  styles=("bandai-namco-1:happy", "bandai-namco-1:sad"))
    data = load_fcrbm_data(settings)
    names = [n for items in data.splits.values() for n, *_ in items]
    assert {n.split("_")[2] for n in names} == {"happy", "sad"}
    with pytest.raises(DataError, match=r"no walk clips of \['cheerful'\].*'happy'"):
        load_fcrbm_data(replace(settings, styles=("bandai-namco-1:cheerful",)))
    with pytest.raises(ValueError, match="data set:style"):
        FCRBMTrainSettings(styles=("happy",))


def test_balanced_epochs_weigh_every_valence_arousal_point_alike():
    from emotive.models.fcrbm.training import epoch_examples

    context = np.array([[1.0, 1.0]] * 40 + [[2.0, 2.0]] * 10 + [[3.0, 2.1]] * 3)
    np.testing.assert_array_equal(epoch_examples(context, False), np.arange(53))
    pool = epoch_examples(context, True)
    counts = np.unique(context[pool], axis=0, return_counts=True)[1]
    np.testing.assert_array_equal(counts, [40, 40, 39])  # 10 x 4, 3 x round(13.3)
    assert set(pool) == set(range(53))
    with pytest.raises(ValueError, match="balance_contexts"):
        FCRBMTrainSettings(balance_contexts="yes")


def test_the_warm_up_walks_at_the_neutral_point_then_changes_to_the_request():
    from emotive.models.fcrbm.generate import warmup_context

    first = np.array([[3.0, 1.0], [2.0, 2.0]])
    lead = warmup_context(first, FPS)
    assert lead.shape == (90, 2, 2)  # 2 s held, 1 s of change, at 30 fps
    np.testing.assert_allclose(lead[:60], 2.0)
    step = np.diff(lead[59:, 0], axis=0)
    np.testing.assert_allclose(step, np.broadcast_to(step[0], step.shape))  # linear, to (3, 1)
    np.testing.assert_allclose(lead[-1, 0] + step[0], first[0])
    np.testing.assert_allclose(lead[:, 1], 2.0)
