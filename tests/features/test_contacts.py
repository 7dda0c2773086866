"""Tests of foot contact detection."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from emotive.core.roles import resolve_roles
from emotive.features.contacts import (
    ContactThresholds,
    _clean_runs,
    _hysteresis,
    foot_contacts,
    foot_positions,
    foot_strikes,
    leg_length,
)
from emotive.features.movement import movement_features
from emotive.io.bvh import read_bvh


def strike_frames(contacts: np.ndarray, foot: int) -> np.ndarray:
    return np.flatnonzero(foot_strikes(contacts)[:, foot])


class TestHelpers:
    def test_hysteresis_holds_between_thresholds(self):
        on = np.array([0, 1, 0, 0, 0, 0, 1, 0], dtype=bool)
        off = np.array([1, 0, 0, 0, 1, 0, 0, 0], dtype=bool)
        np.testing.assert_array_equal(_hysteresis(on, off), [0, 1, 1, 1, 0, 0, 1, 1])

    def test_hysteresis_starts_cleared(self):
        on = np.zeros((4, 3), dtype=bool)
        np.testing.assert_array_equal(_hysteresis(on, on), np.zeros((4, 3), dtype=bool))

    def test_clean_runs(self):
        mask = np.array([1, 0, 1, 1, 1, 0, 0, 0, 1, 0, 1, 1, 1, 1, 0], dtype=bool)
        # Interior 1-frame gaps are filled (joining the runs around them), the 3-frame gap
        # and the gap at the end are kept.
        out = _clean_runs(mask, min_contact=3, min_gap=2)
        np.testing.assert_array_equal(out, [1, 1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 1, 1, 0])
        np.testing.assert_array_equal(
            _clean_runs(np.array([0, 1, 0, 0, 1, 1, 1], dtype=bool), 2, 1),
            [0, 0, 0, 0, 1, 1, 1],
        )

    def test_edge_gaps_are_not_filled(self):
        mask = np.array([0, 1, 1, 1, 0], dtype=bool)
        np.testing.assert_array_equal(_clean_runs(mask, 1, 5), mask)

    def test_strikes_are_rising_edges(self):
        c = np.array([[1, 0], [1, 0], [0, 1], [1, 1]], dtype=bool)
        np.testing.assert_array_equal(foot_strikes(c), [[0, 0], [0, 0], [0, 1], [1, 0]])

    def test_thresholds_validated(self):
        with pytest.raises(ValueError):
            ContactThresholds(height_on=0.1, height_off=0.05)

    def test_foot_positions_numpy_and_torch(self, stick_walk):
        p, roles, _ = stick_walk(frames=5)
        feet = foot_positions(p, roles)
        assert feet.shape == (5, 2, 2, 3)
        np.testing.assert_array_equal(feet[:, 1, 0], p[:, roles.index["r_ankle"]])
        np.testing.assert_array_equal(feet[:, 0, 1], p[:, roles.index["l_toe"]])
        np.testing.assert_array_equal(foot_positions(torch.from_numpy(p), roles).numpy(), feet)


class TestSynthetic:
    def test_strikes_and_stances(self, stick_walk):
        p, roles, truth = stick_walk(frames=150)
        c = foot_contacts(p, roles, 30.0)
        assert c.shape == (150, 2) and c.dtype == bool
        for foot in range(2):
            found, expected = strike_frames(c, foot), np.flatnonzero(truth["strikes"][:, foot])
            assert len(found) == len(expected)
            assert np.all(np.abs(found - expected) <= 2), (found, expected)
        assert np.mean(c == truth["planted"]) > 0.9

    @pytest.mark.parametrize("scale", [0.01, 100.0])
    def test_thresholds_follow_the_rig_size(self, stick_walk, scale):
        p, roles, _ = stick_walk(frames=120)
        small, _, _ = stick_walk(frames=120, scale=scale)
        assert leg_length(small, roles) == pytest.approx(scale * leg_length(p, roles))
        np.testing.assert_array_equal(foot_contacts(small, roles, 30), foot_contacts(p, roles, 30))

    def test_thresholds_follow_the_frame_rate(self, stick_walk):
        p30, roles, _ = stick_walk(frames=120, fps=30.0)
        p120, _, _ = stick_walk(frames=480, fps=120.0)
        s30 = [strike_frames(foot_contacts(p30, roles, 30.0), f) / 30.0 for f in range(2)]
        s120 = [strike_frames(foot_contacts(p120, roles, 120.0), f) / 120.0 for f in range(2)]
        for a, b in zip(s30, s120, strict=True):
            assert len(a) == len(b) and np.all(np.abs(a - b) <= 2 / 30)

    def test_standing_is_in_contact_and_flying_is_not(self, stick_walk):
        p, roles, _ = stick_walk(frames=1)
        p = np.repeat(p, 60, axis=0)  # both feet planted in the first frame
        assert foot_contacts(p, roles, 30.0).all()
        lifted = p.copy()
        feet = [roles.index[r] for r in ("l_ankle", "l_toe", "r_ankle", "r_toe")]
        lifted[30:, feet, 1] += np.linspace(0, 1.0, 30)[:, None]
        c = foot_contacts(lifted, roles, 30.0)
        assert c[:25].all() and not c[40:].any()

    def test_tiny_clips(self, stick_walk):
        p, roles, _ = stick_walk(frames=1)
        assert foot_contacts(p, roles, 30.0).shape == (1, 2)
        assert foot_contacts(p[:0], roles, 30.0).shape == (0, 2)


#: Clips with enough steps to measure a cadence (take 002 of the normal walk has two).
REAL_WALKS = (
    "walk_normal_001", "walk_happy_001", "walk_happy_002", "walk_sad_001",
    "walk_angry_001", "walk_angry_002",
)


@pytest.mark.data
@pytest.mark.parametrize("name", REAL_WALKS)
def test_real_walks_alternate_with_a_human_cadence(walk_dir, name):
    motion = read_bvh(walk_dir / f"dataset-1_{name}.bvh")
    roles = resolve_roles(motion.skeleton)
    p = motion.positions_with_end_sites()
    c = foot_contacts(p, roles, motion.fps)
    frames, feet = np.nonzero(foot_strikes(c))
    order = np.argsort(frames, kind="stable")
    frames, feet = frames[order], feet[order]
    assert len(frames) >= 6
    assert np.all(feet[1:] != feet[:-1]), f"strikes do not alternate: {feet}"
    # Walking keeps a foot on the ground nearly all the time.
    assert c.any(1).mean() > 0.9
    seconds = (frames[-1] - frames[0]) / motion.fps
    step_hz = (len(frames) - 1) / seconds
    root = p[frames[0]:frames[-1] + 1, roles.index["root"]][:, [0, 2]]
    speed = np.linalg.norm(np.diff(root, axis=0), axis=1).sum() / seconds
    stride = speed / step_hz
    assert 1.0 <= step_hz <= 2.8, step_hz
    assert 0.4 <= stride <= 1.0, stride
    # The movement features' step frequency agrees with the counted strikes.
    omega = movement_features(p, roles, motion.fps, contacts=c).step_frequency
    inside = slice(frames[0] + 1, frames[-1] + 1)
    assert omega[inside].mean() * motion.fps / np.pi == pytest.approx(step_hz, rel=1e-6)


@pytest.mark.data
def test_strikes_alternate_in_every_locomotion_clip_of_both_datasets(bandai1_dir, bandai2_dir):
    from emotive.data import load_clips

    checked, too_few = 0, []
    for dataset in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        clips = load_clips(dataset, locomotion=True)
        roles = resolve_roles(clips[0].motion.skeleton)
        for clip in clips:
            m = clip.motion
            frames, feet = np.nonzero(foot_strikes(
                foot_contacts(m.positions_with_end_sites(), roles, m.fps)
            ))
            feet = feet[np.argsort(frames, kind="stable")]
            if len(feet) < 2:
                too_few.append(clip.name)
                continue
            assert np.all(feet[1:] != feet[:-1]), f"{clip.name}: strikes {feet.tolist()}"
            checked += 1
    # Walks, turns, walking back and sideways, runs, dashes: 1067 clips in all; only very short
    # dashes may hold fewer than two strikes.
    assert checked + len(too_few) == 1067
    assert all("_dash_" in name for name in too_few) and len(too_few) <= 2, too_few
