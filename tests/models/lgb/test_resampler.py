"""Per-emotion resampling on synthetic clips: closing, any length, determinism, continuity,
bone lengths, speed, IK chunks, typed errors; and 10 s of real resampled motion (data tests)."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.errors import EmotionError
from emotive.models.lgb.bootstrap import LGBError, TooLittleDataError
from emotive.models.lgb.features import clip_features
from emotive.models.lgb.rebuild import chunk_starts
from emotive.models.lgb.resampler import EmotionResampler
from lgb_clips import synthetic_clip, synthetic_motion

#: Smallest allowed nearest-neighbour distance between a generated 1-s window of the five end
#: effectors (head, wrists, ankles) and any captured one (RMS over frames and effectors,
#: metres). Replaying a captured window through the IK stays within a few millimetres, so
#: anything above 2 cm is new motion.
NOT_A_REPLAY = 0.02
EFFECTORS = ("head_torso:head", "left_arm:l_wrist", "right_arm:r_wrist", "left_leg:l_ankle",
             "right_leg:r_ankle")


@pytest.fixture(scope="module")
def model(sad_clips) -> EmotionResampler:
    return EmotionResampler.fit(sad_clips, "Sad")


def _cols(model: EmotionResampler, keys=EFFECTORS) -> np.ndarray:
    return np.concatenate([np.arange(model.layout[k].start, model.layout[k].start + 3)
                           for k in keys])


def test_the_closed_sequence_keeps_bone_lengths_at_the_junctions(model):
    """Cross-fading poses, not target positions, keeps the forearm length everywhere."""
    sk = model.reference.skeleton
    forearm = np.linalg.norm(sk.offsets[sk.names.index("Hand_L")])
    obs = model.observed
    elbow, wrist = (obs[:, model.layout[k].slice] for k in ("left_arm:l_elbow",
                                                            "left_arm:l_wrist"))
    np.testing.assert_allclose(np.linalg.norm(wrist - elbow, axis=1), forearm, atol=1e-9)
    # The bookkeeping columns are there: each arm's anchor and clavicle rotation.
    assert model.layout["link:left_arm"].width == 4
    assert len(obs) == 3 * (160 - 15)


def test_any_length_reproducible_for_a_seed(model):
    frames = len(model.observed) + 250
    a = model.generate(frames, seed=5)
    b = model.generate(frames, seed=5)
    c = model.generate(frames, seed=6)
    motion = a.motion
    assert motion.num_frames == frames and motion.fps == 30.0
    assert motion.skeleton.names == model.reference.skeleton.names
    assert np.isfinite(motion.rotations).all() and np.isfinite(motion.positions).all()
    np.testing.assert_array_equal(motion.rotations, b.motion.rotations)
    np.testing.assert_array_equal(motion.positions, b.motion.positions)
    assert np.abs(motion.rotations - c.motion.rotations).max() > 0.1
    # The IK reaches the (consistent) sampled targets and says so.
    for name, r in a.residuals.items():
        assert r.max() < 0.01, name
        assert len(a.off_target[name]) == 0
    assert model.generate(1, seed=0).motion.num_frames == 1


def test_the_motion_does_not_depend_on_the_workers(model):
    one = model.generate(400, seed=2, chunk=150)
    two = model.generate(400, seed=2, chunk=150, workers=2)
    np.testing.assert_array_equal(one.motion.rotations, two.motion.rotations)
    for name in one.residuals:
        np.testing.assert_array_equal(one.residuals[name], two.residuals[name])
    assert chunk_starts(3000) == [0] and chunk_starts(30000) == [0, 15000]
    assert chunk_starts(30001) == [0, 7500, 15000, 22501]


def test_generated_effectors_move_at_the_observed_speed_and_stay_on_the_data(model):
    result = model.generate(1500, seed=1)
    gen = clip_features(result.motion, model.chains, model.layout)[:, _cols(model)]
    obs = model.observed[:, _cols(model)]

    def speed(x):
        return np.linalg.norm(np.diff(x.reshape(len(x), -1, 3), axis=0), axis=2).mean()

    ratio = speed(gen) / speed(np.concatenate((obs, obs[:1])))
    print(f"end-effector speed vs observed: {ratio:.2f}")
    assert 0.8 < ratio < 1.25
    # No drift: each effector stays near its observed positions (chain frames, metres); the
    # effectors together make new combinations (the processes are independent).
    for k in range(len(EFFECTORS)):
        g, o = gen[:, 3 * k : 3 * k + 3], obs[:, 3 * k : 3 * k + 3]
        near = np.min(np.linalg.norm(g[:, None] - o[None], axis=2), axis=1)
        assert np.percentile(near, 99) < 0.03, EFFECTORS[k]


def test_too_little_data_names_frames_had_and_needed():
    clips = [synthetic_clip(60, s) for s in range(2)]
    with pytest.raises(TooLittleDataError,
                       match=r"emotion 'sad' in test data \(2 clips\) has 90 frames but at "
                             r"least 206 are needed .*add clips") as err:
        EmotionResampler.fit(clips, "sad", blend=15, source="test data")
    assert (err.value.have, err.value.need) == (90, 206)


def test_unknown_emotion_mixed_rigs_and_nan_raise_typed_errors(sad_clips):
    with pytest.raises(EmotionError, match=r"no clips of emotion 'sda' \(did you mean 'sad'\?\)"
                                           r".*\['happy', 'sad'\]"):
        EmotionResampler.fit(sad_clips, "sda")
    from emotive.core import Skeleton
    from rigs import RIG

    names = tuple(r[0] for r in RIG)
    other = Skeleton(names, np.array([r[1] for r in RIG]), np.array([r[2] for r in RIG], float))
    mixed = [*sad_clips[:2], synthetic_clip(160, 7, motion=synthetic_motion(160, 7, other))]
    with pytest.raises(LGBError, match=r"not on the rig of dataset-1_walk_sad_001"):
        EmotionResampler.fit(mixed, "sad")
    bad = sad_clips[1].motion
    rot = bad.rotations.copy()
    rot[10, 3] = np.nan
    clips = [sad_clips[0], synthetic_clip(160, 1, motion=bad.replace(rotations=rot)),
             sad_clips[2]]
    with pytest.raises(LGBError, match=r"trajectories of clip dataset-1_walk_sad_002.*NaN"):
        EmotionResampler.fit(clips, "sad")


def _windows(x: np.ndarray, size: int, hop: int) -> np.ndarray:
    """``(W, size * F)`` windows of ``(T, F)`` rows."""
    starts = np.arange(0, len(x) - size + 1, hop)
    return np.stack([x[s : s + size].ravel() for s in starts])


@pytest.mark.data
def test_resampled_real_motion_is_new_and_finite(bandai1_dir):
    from scipy.spatial import cKDTree

    from emotive.data.clips import load_clips

    clips = load_clips("bandai-namco-1")
    model = EmotionResampler.fit(clips, "sad")
    result = model.generate(300, seed=0)
    motion = result.motion
    data = next(c.motion for c in clips if c.info.emotion == "sad")
    assert motion.num_frames == 300 and motion.fps == 30.0
    assert motion.skeleton.names == data.skeleton.names
    np.testing.assert_array_equal(motion.skeleton.parents, data.skeleton.parents)
    assert np.isfinite(motion.rotations).all() and np.isfinite(motion.positions).all()
    assert all(len(f) == 0 for f in result.off_target.values())

    # End effectors (head, hands, ankles) of the rebuilt motion vs the captured sequence.
    cols = _cols(model)
    feats = clip_features(motion, model.chains, model.layout)
    captured = _windows(model.observed[:, cols], 30, 1)
    generated = _windows(feats[:, cols], 30, 5)
    dist, _ = cKDTree(captured).query(generated)
    rms = dist / np.sqrt(30 * len(cols) / 3)
    print(f"not-a-replay 1-s window NN distance (m): all end effectors min {rms.min():.4f}, "
          f"median {np.median(rms):.4f}")
    assert rms.min() > NOT_A_REPLAY


@pytest.mark.data
def test_nan_in_real_trajectories_raises(bandai1_dir):
    from emotive.data.clips import load_clips

    clips = [c for c in load_clips("bandai-namco-1") if c.info.emotion == "sad"]
    bad = clips[0].motion
    rot = bad.rotations.copy()
    rot[10, 3] = np.nan
    clips[0] = synthetic_clip(motion=bad.replace(rotations=rot))
    with pytest.raises(LGBError, match=rf"trajectories of clip {clips[0].info.name}.*NaN"):
        EmotionResampler.fit(clips, "sad")
