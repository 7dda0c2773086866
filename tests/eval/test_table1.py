"""Tests of :mod:`emotive.eval.table1`: the Table-1 prediction protocol and its baseline."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np
import pytest

from emotive.core import Motion, Skeleton
from emotive.core.ops import resample
from emotive.data.emotion import ALL_LABELS, DEFAULT_LABELS, Emotion
from emotive.eval import table1 as t1
from emotive.eval.table1 import Predictor, ZeroVelocity, table1
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    euler_to_quaternion,
    quaternion_multiply,
)

FPS = 30.0
#: Angular speed of every joint of the rotating clips, degrees per second.
OMEGA = 30.0


def clip(motion: Motion, name: str, emotion: str = "happy") -> SimpleNamespace:
    """A held-out clip as :func:`table1` reads it."""
    motion = motion.replace(metadata={**motion.metadata, "name": name})
    return SimpleNamespace(motion=motion, info=SimpleNamespace(name=name, emotion=emotion))


@dataclass
class Oracle:
    """Returns the true continuation: finds the primer in its clip (resampled to the same rate)
    and copies the frames that follow; records the emotion it was given."""

    truth: dict[str, Motion]
    name: str = "Oracle"
    given: list[tuple[np.ndarray, tuple[str, ...]]] = field(default_factory=list)

    def predict(self, primer, frames, emotion, labels):
        self.given.append((emotion, labels))
        motion = self.truth[primer.metadata["name"]]
        hits = np.flatnonzero((motion.rotations == primer.rotations[0]).all((1, 2)))
        start = int(hits[0]) + primer.num_frames
        return motion.replace(rotations=motion.rotations[start : start + frames],
                              positions=motion.positions[start : start + frames])


def rotating(random_motion, frames: int, first_axis: bool) -> Motion:
    """Every joint turns at :data:`OMEGA` about a fixed local axis; the root stands still.

    With ``first_axis`` each joint starts at the identity and turns about the first axis of its
    own Euler order (so its Euler angles change in one component only); otherwise it starts in
    a random pose and turns about a random axis.
    """
    base = random_motion(frames=1, seed=3)
    sk = base.skeleton
    angle = np.radians(OMEGA) * np.arange(frames) / FPS  # (T,)
    if first_axis:
        rot = np.stack([
            euler_to_quaternion(angle[:, None] * [1.0, 0.0, 0.0], sk.rotation_order(j))
            for j in range(sk.num_joints)
        ], axis=1)
    else:
        axes = np.random.default_rng(1).normal(size=(sk.num_joints, 3))
        axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
        turn = axis_angle_to_quaternion(angle[:, None, None] * axes)  # (T, J, 4)
        rot = quaternion_multiply(np.broadcast_to(base.rotations, turn.shape), turn)
    pos = np.repeat(base.positions, frames, axis=0)
    return Motion(sk, rot, pos, FPS)


def test_default_labels_are_the_projects_and_import_is_light():
    assert t1._DEFAULT_LABELS == DEFAULT_LABELS
    code = ("import sys, emotive.eval.table1; "
            "print(sorted(m for m in ('torch', 'scipy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_zero_velocity_is_a_predictor_holding_the_last_frame(random_motion):
    primer = random_motion(frames=5)
    model = ZeroVelocity()
    assert isinstance(model, Predictor)
    out = model.predict(primer, 4, Emotion.one_hot("sad").weights, DEFAULT_LABELS)
    assert out.num_frames == 4 and out.fps == primer.fps and out.skeleton is primer.skeleton
    np.testing.assert_array_equal(out.rotations, np.repeat(primer.rotations[-1:], 4, 0))
    np.testing.assert_array_equal(out.positions, np.repeat(primer.positions[-1:], 4, 0))
    with pytest.raises(ValueError, match="frames"):
        model.predict(primer, 0, Emotion.one_hot("sad").weights, DEFAULT_LABELS)


@pytest.mark.parametrize("fps", [10.0, 30.0])
def test_oracle_scores_zero_and_gets_the_intended_emotion(random_motion, fps):
    clips = [clip(random_motion(frames=240, seed=1), "a", "sad"),
             clip(random_motion(frames=200, seed=2), "b", "normal")]
    oracle = Oracle({c.info.name: resample(c.motion, fps) for c in clips})
    result = table1([oracle], clips, fps=fps)
    assert result.windows == 3 + 1 and result.clips == 2
    overall = result["Oracle"].overall
    for value in (overall.pose, overall.rotation, overall.euler):
        assert value == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(result["Oracle"].errors, 0.0, atol=1e-6)
    assert len(oracle.given) == result.windows
    for (emotion, labels), label in zip(oracle.given, result.window_emotions, strict=True):
        assert labels == DEFAULT_LABELS
        np.testing.assert_array_equal(emotion, Emotion.one_hot(label).weights)
    assert result.window_emotions == ("sad",) * 3 + ("neutral",)


@pytest.mark.parametrize("fps", [10.0, 30.0])
def test_zero_velocity_on_constant_rotation_gives_the_analytic_error(random_motion, fps):
    # The prediction holds the last primer frame; k frames later the truth has turned by
    # OMEGA k / fps about a fixed axis, so the mean over k = 1..H is OMEGA (H + 1) / (2 fps).
    horizon = round(4.2 * fps)
    expected = OMEGA * (horizon + 1) / (2 * fps)
    for first_axis in (False, True):
        motion = rotating(random_motion, 240, first_axis)
        result = table1([ZeroVelocity()], [clip(motion, "spin")], fps=fps)
        assert result.predicted_frames == horizon and result.windows == 3
        errors = result["Zero velocity"].errors
        np.testing.assert_allclose(errors[:, 1], expected, rtol=1e-6)
        assert result["Zero velocity"].overall.rotation_std == pytest.approx(0.0, abs=1e-6)
        assert np.all(errors[:, 0] > 0)
        if first_axis:
            # One Euler component changes, by the same angle: Euler and geodesic errors agree,
            # which they would not if the joints' own (mixed) Euler orders were ignored.
            np.testing.assert_allclose(errors[:, 2], expected, rtol=1e-6)


def test_zero_velocity_scores_zero_on_a_static_clip(random_motion):
    still = random_motion(frames=1, seed=4)
    still = still.replace(rotations=np.repeat(still.rotations, 200, 0),
                          positions=np.repeat(still.positions, 200, 0))
    result = table1([ZeroVelocity()], [clip(still, "still")], fps=10.0)
    assert result.windows == 1
    np.testing.assert_allclose(result["Zero velocity"].errors, 0.0, atol=1e-9)


def test_pose_error_ignores_a_ground_joint_above_the_hips(rng):
    # As on the Bandai Namco rig: joint_Root stays at the origin while the hips travel.
    names = ("joint_Root", "Hips", "Spine", "Head", "UpperLeg_L", "LowerLeg_L")
    offsets = np.array([[0, 0, 0], [0, 0.9, 0], [0, 0.1, 0], [0, 0.3, 0], [0.1, -0.05, 0],
                        [0, -0.4, 0]])
    sk = Skeleton(names, [-1, 0, 1, 2, 1, 4], offsets)
    frames = 200
    pose = rng.normal(size=(1, len(names), 4))
    pose /= np.linalg.norm(pose, axis=-1, keepdims=True)
    pos = np.repeat(offsets[None], frames, 0)
    pos[:, 1, 0] = 1.2 * np.arange(frames) / FPS  # walking along X, pose frozen
    walker = clip(Motion(sk, np.repeat(pose, frames, 0), pos, FPS), "glide")
    body = table1([ZeroVelocity()], [walker])["Zero velocity"].errors
    np.testing.assert_allclose(body, 0.0, atol=1e-9)
    world = table1([ZeroVelocity()], [walker], root="joint_Root")["Zero velocity"].errors
    assert np.all(world[:, 0] > 0.1)


def test_windows_strides_and_skipped_clips(random_motion):
    clips = [
        clip(random_motion(frames=240), "long", "happy"),  # 80 frames at 10 fps
        clip(random_motion(frames=180), "exact", "angry"),  # 60 frames: one window
        clip(random_motion(frames=177), "short", "happy"),  # 59 frames: none
        clip(random_motion(frames=240), "proud", "proud"),  # not among the default labels
    ]
    result = table1([ZeroVelocity()], clips, fps=10.0, stride_seconds=0.5)
    assert (result.primer_frames, result.predicted_frames, result.stride_frames) == (18, 42, 5)
    assert result.window_clips == ("long",) * 5 + ("exact",)
    np.testing.assert_array_equal(result.window_starts, [0, 5, 10, 15, 20, 0])
    assert result.skipped_short == ("short",) and result.skipped_label == ("proud",)
    scores = result["Zero velocity"]
    assert (scores.overall.windows, scores.overall.clips) == (6, 2)
    assert list(scores.per_emotion) == ["happy", "angry"]
    assert scores.per_emotion["happy"].windows == 5 and scores.per_emotion["angry"].clips == 1
    assert scores.per_emotion["happy"].pose == pytest.approx(scores.errors[:5, 0].mean())

    # Frame counts fixed by hand at 30 fps: 60-frame windows, every second.
    result = table1([ZeroVelocity()], clips, fps=30.0, primer_frames=18, predicted_frames=42,
                    labels=ALL_LABELS)
    assert result.stride_frames == 30 and not result.skipped_short and not result.skipped_label
    assert result.windows == 7 + 5 + 4 + 7 and result.clips == 4

    with pytest.raises(ValueError, match="no window of 60 frames"):
        table1([ZeroVelocity()], clips[2:3], fps=10.0)


def test_markdown_has_one_row_per_predictor(random_motion):
    clips = [clip(random_motion(frames=240), "a")]
    oracle = Oracle({"a": resample(clips[0].motion, 10.0)})
    result = table1([ZeroVelocity(), oracle], clips)
    lines = result.to_markdown().splitlines()
    assert len(lines) == 2 + 2 and lines[0].startswith("| Predictor | Pose error")
    assert lines[2].startswith("| Zero velocity | ") and lines[3].startswith("| Oracle | 0.000 ±")
    assert [row[0] for row in result.rows()] == ["Zero velocity", "Oracle"]
    assert all(row[-1] == 3 for row in result.rows())


class Wrong:
    name = "wrong"

    def __init__(self, extra: int = 0, fps: float | None = None) -> None:
        self.extra, self.fps = extra, fps

    def predict(self, primer, frames, emotion, labels):
        out = ZeroVelocity().predict(primer, frames + self.extra, emotion, labels)
        return out.replace(fps=self.fps) if self.fps else out


@pytest.mark.parametrize(("predictors", "kwargs", "match"), [
    ([], {}, "no predictors"),
    ([ZeroVelocity(), ZeroVelocity()], {}, "repeat"),
    ([object()], {}, "not a Predictor"),
    ([ZeroVelocity()], {"fps": 0.0}, "fps"),
    ([ZeroVelocity()], {"primer_frames": 0}, "primer_frames"),
    ([ZeroVelocity()], {"stride_seconds": 0.01}, "less than one frame"),
    ([ZeroVelocity()], {"labels": ("happy", "grumpy")}, "labels"),
    ([ZeroVelocity()], {"root": "Pelvis"}, "root joint 'Pelvis'"),
    ([Wrong(extra=1)], {}, "returned 43 frames, expected 42"),
    ([Wrong(fps=30.0)], {}, "30.0 fps"),
])
def test_bad_arguments(random_motion, predictors, kwargs, match):
    with pytest.raises(ValueError, match=match):
        table1(predictors, [clip(random_motion(frames=240), "a")], **kwargs)


def test_no_clips():
    with pytest.raises(ValueError, match="no clips"):
        table1([ZeroVelocity()], [])


@pytest.mark.data
def test_zero_velocity_on_the_locomotion_test_split(bandai1_dir):
    from emotive.data.clips import load_clips
    from emotive.data.splits import split_clips

    test = split_clips(load_clips("bandai-namco-1", locomotion=True))["test"]
    result = table1([ZeroVelocity()], test, fps=10.0, labels=ALL_LABELS)
    assert result.windows > 0 and result.clips + len(result.skipped_short) == len(test)
    o = result["Zero velocity"].overall
    values = np.array([o.pose, o.rotation, o.euler, o.pose_std, o.rotation_std, o.euler_std])
    assert np.all(np.isfinite(values)) and np.all(values[:3] > 0)
    assert o.pose < 1.0
    # Body rotations of a walk change by more than a degree within seconds, and by less than
    # a right angle on average.
    assert 1.0 < o.rotation < 90.0 and 1.0 < o.euler < 90.0


def test_pose_by_frame_averages_to_the_window_pose_error(random_motion):
    clips = [clip(random_motion(frames=240, seed=1), "a"), clip(random_motion(frames=90, seed=2),
                                                                "b", "sad")]
    result = table1([ZeroVelocity()], clips, fps=10.0)
    scores = result["Zero velocity"]
    assert scores.pose_by_frame.shape == (result.windows, result.predicted_frames)
    np.testing.assert_allclose(scores.pose_by_frame.mean(-1), scores.errors[:, 0], rtol=1e-12)


def test_merged_runs_equal_one_run_over_all_clips(random_motion):
    a = [clip(random_motion(frames=240, seed=1), "a"), clip(random_motion(frames=90, seed=2),
                                                            "b", "sad")]
    b = [clip(random_motion(frames=210, seed=3), "c", "angry")]
    oracle = Oracle({c.info.name: resample(c.motion, 10.0) for c in a + b})
    models = [ZeroVelocity(), oracle]
    whole = table1(models, a + b, fps=10.0)
    merged = t1.merge_results([table1(models, a, fps=10.0), table1(models, b, fps=10.0)])
    assert merged.window_clips == whole.window_clips
    assert merged.window_emotions == whole.window_emotions
    np.testing.assert_array_equal(merged.window_starts, whole.window_starts)
    for name in ("Zero velocity", "Oracle"):
        np.testing.assert_array_equal(merged[name].errors, whole[name].errors)
        np.testing.assert_array_equal(merged[name].pose_by_frame, whole[name].pose_by_frame)
        assert merged[name].overall == whole[name].overall
        assert merged[name].per_emotion == whole[name].per_emotion
    assert merged.to_dict() == whole.to_dict()


def test_merge_refuses_different_protocols(random_motion):
    clips = [clip(random_motion(frames=240, seed=1), "a")]
    with pytest.raises(ValueError, match="no results"):
        t1.merge_results([])
    with pytest.raises(ValueError, match="different predictors or protocol"):
        t1.merge_results([table1([ZeroVelocity()], clips, fps=10.0),
                          table1([ZeroVelocity()], clips, fps=30.0)])
