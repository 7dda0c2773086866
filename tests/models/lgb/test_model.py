"""Per-emotion resampling: closing clips, typed errors, and 10 s of real resampled motion."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.clips import Clip, ClipInfo
from emotive.errors import EmotionError
from emotive.models.lgb.bootstrap import LGBError, TooLittleDataError
from emotive.models.lgb.model import EmotionResampler, close_sequences

#: Smallest allowed nearest-neighbour distance between a generated 1-s window of end-effector
#: trajectories and any captured one (RMS over frames and targets, metres). Replaying a captured
#: window through the IK stays within a few millimetres (tests/ik: 5 mm), so anything above
#: 2 cm is new motion.
NOT_A_REPLAY = 0.02


def _clip(motion, name: str = "dataset-1_walk_sad_001", style: str = "sad") -> Clip:
    info = ClipInfo("bandai-namco-1", name, motion.metadata.get("source", name), "walk", style, 1)
    return Clip(info, motion)


def test_close_sequences_is_continuous_and_closed():
    a = np.zeros((40, 2))
    b = np.ones((50, 2))
    out = close_sequences([a, b], blend=10)
    assert out.shape == (40 + 50 - 20, 2)
    # Every step, including the wrap-around from the last row to the first, is small.
    steps = np.abs(np.diff(np.concatenate((out, out[:1])), axis=0))
    assert steps.max() < 0.2
    with pytest.raises(LGBError, match="more than 20 frames"):
        close_sequences([a[:15], b], blend=10)


def test_too_little_data_names_frames_had_and_needed(random_motion):
    clips = [_clip(random_motion(frames=60, seed=i)) for i in range(2)]
    with pytest.raises(TooLittleDataError,
                       match=r"emotion 'sad' \(2 clips\) has 90 frames but at least 203"):
        EmotionResampler.fit(clips, "sad", blend=15)
    with pytest.raises(EmotionError, match=r"no clips of emotion 'happy'.*\['sad'\]"):
        EmotionResampler.fit(clips, "Happy")


def _windows(x: np.ndarray, size: int, hop: int) -> np.ndarray:
    """``(W, size * F)`` windows of ``(T, F)`` rows."""
    starts = np.arange(0, len(x) - size + 1, hop)
    return np.stack([x[s : s + size].ravel() for s in starts])


@pytest.mark.data
def test_resampled_real_motion_is_new_and_finite(bandai1_dir):
    from scipy.spatial import cKDTree

    from emotive.data.clips import load_clips
    from emotive.ik import extract_trajectories
    from emotive.models.lgb.model import trajectory_features

    clips = load_clips("bandai-namco-1")
    model = EmotionResampler.fit(clips, "sad")
    result = model.generate(300, seed=0)
    motion = result.motion
    data = next(c.motion for c in clips if c.info.emotion == "sad")
    assert motion.num_frames == 300 and motion.fps == 30.0
    assert motion.skeleton.names == data.skeleton.names
    np.testing.assert_array_equal(motion.skeleton.parents, data.skeleton.parents)
    assert np.isfinite(motion.rotations).all() and np.isfinite(motion.positions).all()

    # End effectors (head, hands, ankles) of the rebuilt motion vs the captured sequence.
    feats = trajectory_features(extract_trajectories(motion, model.chains), model.layout)
    cols = np.concatenate([np.arange(feats.shape[1])[model.layout[k].slice]
                           for k in ("head_torso:head", "left_arm:l_wrist", "right_arm:r_wrist",
                                     "left_leg:l_ankle", "right_leg:r_ankle")])
    captured = _windows(model.observed[:, cols], 30, 1)
    generated = _windows(feats[:, cols], 30, 5)
    dist, _ = cKDTree(captured).query(generated)
    rms = dist / np.sqrt(30 * len(cols) / 3)
    print(f"not-a-replay 1-s window NN distance (m): all end effectors min {rms.min():.4f}, "
          f"median {np.median(rms):.4f}")
    assert rms.min() > NOT_A_REPLAY
    # Per effector only reported: a still head's window is close to any captured still window.
    for k in range(0, len(cols), 3):
        one = cols[k : k + 3]
        d, _ = cKDTree(_windows(model.observed[:, one], 30, 1)).query(
            _windows(feats[:, one], 30, 5))
        d /= np.sqrt(30)
        print(f"  effector {k // 3}: min {d.min():.4f}, median {np.median(d):.4f}")


@pytest.mark.data
def test_nan_in_trajectories_raises(bandai1_dir):
    from emotive.data.clips import load_clips

    clips = [c for c in load_clips("bandai-namco-1") if c.info.emotion == "sad"]
    bad = clips[0].motion
    rot = bad.rotations.copy()
    rot[10, 3] = np.nan
    clips[0] = _clip(bad.replace(rotations=rot), clips[0].info.name)
    with pytest.raises(LGBError, match=rf"trajectories of clip {clips[0].info.name}.*NaN"):
        EmotionResampler.fit(clips, "sad")
