"""Tests of the gait training data on real clips: shapes, next-frame targets, heading-canonical
windows, emotion one-hots, statistics and windows that never cross clips."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.ops import canonicalize_facing, crop, heading
from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.data.emotion import ALL_LABELS, DEFAULT_LABELS, style_to_label
from emotive.errors import DataError, EmotionError
from emotive.features.movement import movement_features
from emotive.models.gait import GaitConfig, GaitNetwork
from emotive.models.gait.affect import gait_affective_np
from emotive.models.gait.data import build_gait_data, load_gait_data
from emotive.transforms.kinematics import forward_kinematics_np
from emotive.transforms.np_rotations import quaternion_apply

pytestmark = pytest.mark.data

LENGTH, STRIDE = 20, 10
CONFIG = GaitConfig(labels=ALL_LABELS)


@pytest.fixture(scope="module")
def clips(bandai1_dir):
    return {c.name: c for c in load_clips("bandai-namco-1", locomotion=True)}


@pytest.fixture(scope="module")
def splits(bandai1_dir):
    return load_gait_data(CONFIG, ("bandai-namco-1",), LENGTH, STRIDE, max_clips=3)


@pytest.fixture(scope="module")
def train(splits):
    return splits["train"]


def world_with_end_sites(rotations, positions, skeleton):
    """``(..., J + E, 3)`` FK positions of joints and end sites (NumPy, float64)."""
    grot, gpos = forward_kinematics_np(rotations.astype(np.float64),
                                       positions.astype(np.float64), skeleton.parents)
    p = list(skeleton.end_site_parents)
    ends = quaternion_apply(grot[..., p, :], skeleton.end_site_offsets) + gpos[..., p, :]
    return np.concatenate((gpos, ends), -2)


def test_shapes_and_inputs(train):
    assert len(train) > 4 and train.length == LENGTH
    b = train.batch(np.arange(4))
    assert b.rotations.shape == (4, LENGTH + 1, 22, 4)
    assert b.positions.shape == (4, LENGTH + 1, 22, 3)
    assert b.affective.shape == (4, LENGTH + 1, 18)
    assert b.movement.shape == (4, LENGTH + 1, 5) and b.root.shape == (4, LENGTH + 1, 3)
    assert b.emotion.shape == (4, len(ALL_LABELS))
    inputs = b.inputs()
    assert inputs.rotations.shape == (4, LENGTH, 22, 4)
    assert b.next_rotations.shape == (4, LENGTH, 22, 4) and b.next_root.shape == (4, LENGTH, 3)
    # The network accepts the inputs as they are.
    out, _ = GaitNetwork(CONFIG)(inputs)
    assert out.rotations.shape == b.next_rotations.shape


def test_windows_never_cross_clips_and_splits_are_disjoint(splits):
    for data in splits.values():
        lo = data.clip_offsets[data.window_clip]
        hi = data.clip_offsets[data.window_clip + 1]
        assert np.all(data.starts >= lo) and np.all(data.starts + LENGTH + 1 <= hi)
        assert np.all(np.diff(data.starts)[np.diff(data.window_clip) == 0] == STRIDE)
    names = [{c.name for c in d.clips} for d in splits.values()]
    assert not names[0] & names[1] and not names[0] & names[2] and not names[1] & names[2]


def test_targets_are_the_clip_frames_shifted_by_one(train, clips):
    for n in (0, len(train) - 1):
        k = train.window_clip[n]
        motion = clips[train.clips[k].name].motion
        s = int(train.starts[n] - train.clip_offsets[k])
        b = train.batch([n])
        world = motion.positions_with_end_sites()
        roles = resolve_roles(motion.skeleton)
        mf = movement_features(world, roles, motion.fps)
        np.testing.assert_allclose(b.next_root[0].numpy(), np.stack(
            (mf.root_height, mf.root_speed, mf.orientation_difference), 1)[s + 1:s + LENGTH + 1],
            atol=1e-5)
        np.testing.assert_allclose(b.inputs().affective[0].numpy(),
                                   gait_affective_np(world, roles)[s:s + LENGTH], atol=1e-4)
        theta = mf.step_phase[s:s + LENGTH]
        np.testing.assert_allclose(b.inputs().movement[0, :, :2].numpy(),
                                   np.stack((np.sin(theta), np.cos(theta)), 1), atol=1e-5)
        # Same rotations up to sign (joints below the hips are not moved by canonicalization).
        dots = np.abs((b.next_rotations[0, :, 2:].numpy()
                       * motion.rotations[s + 1:s + LENGTH + 1, 2:]).sum(-1))
        np.testing.assert_allclose(dots, 1.0, atol=1e-5)


def test_every_frame_is_canonicalize_facing_of_that_frame(train, clips):
    n = len(train) // 2
    k = train.window_clip[n]
    motion = clips[train.clips[k].name].motion
    s = int(train.starts[n] - train.clip_offsets[k])
    b = train.batch([n])
    got = world_with_end_sites(b.rotations[0].numpy(), b.positions[0].numpy(), train.skeleton)
    for t in (0, LENGTH // 2, LENGTH):
        expected = canonicalize_facing(crop(motion, s + t, s + t + 1)).positions_with_end_sites()
        # canonicalize_facing moves the file root joint_Root, which carries no body point; the
        # data moves the hips instead, so every body point must agree.
        np.testing.assert_allclose(got[t, 1:], expected[0, 1:], atol=1e-4)
    # The hips carry the heading (joint_Root stays at the identity): facing +Z in every frame.
    assert train.mover == 1
    np.testing.assert_allclose(np.abs(b.rotations[0, :, 0, 0].numpy()), 1.0, atol=1e-6)
    placed = motion.replace(rotations=b.rotations[0].numpy(), positions=b.positions[0].numpy())
    np.testing.assert_allclose(heading(placed), 0.0, atol=1e-4)


def test_mover_quaternions_share_one_hemisphere(train):
    q = train.rotations[:, train.mover]
    assert np.all((q * q[:1]).sum(-1) > 0)


def test_rotations_are_sign_continuous_within_clips(train):
    dots = (train.rotations[1:] * train.rotations[:-1]).sum(-1)
    same_clip = np.ones(train.num_frames - 1, dtype=bool)
    same_clip[train.clip_offsets[1:-1] - 1] = False
    assert np.all(dots[same_clip] >= 0)


def test_emotion_one_hot_matches_the_clip_style(train):
    b = train.batch(np.arange(len(train)))
    emotion = b.emotion.numpy()
    np.testing.assert_array_equal(emotion.sum(1), 1.0)
    for n in range(len(train)):
        style = train.clips[train.window_clip[n]].style
        assert ALL_LABELS[int(emotion[n].argmax())] == style_to_label(style)


def test_statistics_are_finite_and_set_on_the_network(train):
    stats = train.statistics()
    for name, size in (("affective", 18), ("movement", 5), ("root", 3)):
        mean, std = stats[name]
        assert mean.shape == std.shape == (size,)
        assert np.isfinite(mean).all() and np.isfinite(std).all() and (std > 0).all()
    net = GaitNetwork(CONFIG)
    net.set_feature_statistics(**stats)
    np.testing.assert_allclose(net.root_std.numpy(), stats["root"][1])


def test_labels_filter_clips_and_bad_input_raises(clips):
    some = list(clips.values())[:6]
    with pytest.raises(EmotionError):
        build_gait_data([c for c in some if style_to_label(c.style) not in DEFAULT_LABELS],
                        DEFAULT_LABELS, LENGTH, STRIDE)
    with pytest.raises(DataError, match="no clips"):
        build_gait_data([], ALL_LABELS, LENGTH, STRIDE)
    with pytest.raises(DataError, match="frames a window needs"):
        build_gait_data(some, ALL_LABELS, 100_000, STRIDE)


def test_fold_into_root_moves_the_trajectory_into_the_hips(clips):
    from emotive.core.root import fold_into_root

    motion = clips["dataset-1_walk_normal_002"].motion
    assert np.abs(motion.positions[:, 0]).max() > 1.0  # joint_Root carries the trajectory
    folded = fold_into_root(motion, 1)
    np.testing.assert_allclose(folded.positions_with_end_sites()[:, 1:],
                               motion.positions_with_end_sites()[:, 1:], atol=1e-9)
    np.testing.assert_array_equal(folded.positions[:, 0], 0.0)
    np.testing.assert_array_equal(folded.rotations[:, 0], [[1, 0, 0, 0]] * motion.num_frames)
