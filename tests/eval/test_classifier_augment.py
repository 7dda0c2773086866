"""Augmentation of the classifier's role tracks: layouts, proportions, height, mirror, rates."""

from __future__ import annotations

import numpy as np
import pytest
from stick_figures import FPS, figure

from emotive.core.roles import ROLES
from emotive.eval.classifier import ClassifierConfig, track_features
from emotive.eval.classifier_augment import (
    MIRROR_ORDER,
    ROLE_PARENT,
    SEGMENT_GROUPS,
    AugmentConfig,
    augment,
    jitter_layout,
    mirror,
    resample,
    scale_segments,
    scale_to_height,
    standing_height,
)
from emotive.eval.classifier_nets import ROLE_EDGES

IDX = {r: k for k, r in enumerate(ROLES)}


def walker(frames: int = 90) -> np.ndarray:
    """A stick figure gliding forward along +Z at 1.2 m/s while turning slowly, swinging its
    arms and lifting its feet in turn."""
    t = np.arange(frames) / FPS
    p = figure(np.stack((0.1 * np.sin(t), 1.2 * t), -1), 0.2 * np.sin(0.5 * t))
    swing = 0.2 * np.sin(2 * np.pi * t)
    for side, sign in (("l_", 1.0), ("r_", -1.0)):
        p[:, IDX[side + "wrist"], 2] += sign * swing
        p[:, IDX[side + "handtip"], 2] += sign * swing
        lift = np.maximum(0.0, sign * np.sin(2 * np.pi * t)) * 0.1
        for role in ("ankle", "toe"):
            p[:, IDX[side + role], 1] += lift
    return p


def lengths(p: np.ndarray) -> dict[str, np.ndarray]:
    return {r: np.linalg.norm(p[:, IDX[r]] - p[:, IDX[q]], axis=-1) for r, q in ROLE_PARENT.items()}


def test_role_tree_is_the_classifier_skeleton():
    assert {frozenset(e) for e in ROLE_EDGES} == {frozenset(e) for e in ROLE_PARENT.items()}
    assert set(ROLE_PARENT) == set(ROLES) - {"root"}
    grouped = [r for roles in SEGMENT_GROUPS.values() for r in roles]
    assert len(grouped) == len(set(grouped)) and set(grouped) <= set(ROLE_PARENT)


def test_mirror_swaps_sides_and_is_its_own_inverse():
    p = walker()
    m = mirror(p)
    np.testing.assert_allclose(mirror(m), p)
    np.testing.assert_allclose(m[:, IDX["l_wrist"]], p[:, IDX["r_wrist"]] * [-1, 1, 1])
    np.testing.assert_allclose(m[:, IDX["head"]], p[:, IDX["head"]] * [-1, 1, 1])
    assert sorted(MIRROR_ORDER) == list(range(len(ROLES)))
    # A symmetric standing figure facing +Z mirrors onto itself.
    still = figure(np.zeros((5, 2)), np.zeros(5))
    np.testing.assert_allclose(mirror(still), still, atol=1e-12)


def test_scale_segments_lengthens_only_the_named_groups_and_keeps_feet_on_the_ground():
    p = walker()
    np.testing.assert_allclose(scale_segments(p, {}), p, atol=1e-12)
    q = scale_segments(p, {"legs": 1.2, "arms": 0.9})
    before, after = lengths(p), lengths(q)
    for role in ROLE_PARENT:
        factor = 1.2 if role in SEGMENT_GROUPS["legs"] else (
            0.9 if role in SEGMENT_GROUPS["arms"] else 1.0)
        np.testing.assert_allclose(after[role], factor * before[role], rtol=1e-9)
    # The root's path scales with the legs: the figure still stands on the ground.
    for side in ("l_", "r_"):
        foot = side + "toe"
        assert abs(q[:, IDX[foot], 1].min() - 1.2 * p[:, IDX[foot], 1].min()) < 1e-9
    np.testing.assert_allclose(np.diff(q[:, 0, 2]), 1.2 * np.diff(p[:, 0, 2]), rtol=1e-9)
    with pytest.raises(ValueError, match="unknown segment groups"):
        scale_segments(p, {"tail": 2.0})


def test_scale_to_height():
    p = walker()
    for height in (1.4, 2.0):
        assert standing_height(scale_to_height(p, height)) == pytest.approx(height)


def test_layout_jitter_moves_only_the_spine_shoulders_and_toes_a_little():
    p = walker()
    q = jitter_layout(p, np.random.default_rng(0), shift=0.15, fallback_probability=0.0)
    moved = {r for r in ROLES if not np.allclose(q[:, IDX[r]], p[:, IDX[r]])}
    assert moved <= {"spine", "chest", "neck", "l_shoulder", "r_shoulder", "l_toe", "r_toe"}
    assert {"chest", "l_shoulder"} <= moved
    assert np.abs(q - p).max() < 0.15 * 0.5
    always = jitter_layout(p, np.random.default_rng(0), fallback_probability=1.0)
    np.testing.assert_array_equal(always[:, IDX["chest"]], always[:, IDX["spine"]])
    np.testing.assert_array_equal(always[:, IDX["l_handtip"]], always[:, IDX["l_wrist"]])


def test_resample_keeps_the_duration_and_interpolates_linearly():
    p = walker(91)
    for fps in (24.0, 60.0, 120.0):
        q = resample(p, FPS, fps)
        assert len(q) == int(90 * fps / FPS) + 1
        np.testing.assert_allclose(q[0], p[0])
        # The root glides at constant speed along Z: linear resampling keeps it exact.
        np.testing.assert_allclose(q[:, 0, 2], 1.2 * np.arange(len(q)) / fps, atol=1e-9)
    np.testing.assert_allclose(resample(p, FPS, FPS), p)
    with pytest.raises(ValueError, match="frame rates must be positive"):
        resample(p, FPS, 0.0)


def test_augment_draws_variants_the_features_can_read():
    p = walker()
    cfg = AugmentConfig()
    rng = np.random.default_rng(3)
    rates, heights = set(), []
    base = track_features(p, FPS, ClassifierConfig())
    for _ in range(12):
        q, fps = augment(p, FPS, rng, cfg)
        rates.add(fps)
        heights.append(standing_height(q))
        assert q.dtype == np.float32 and np.isfinite(q).all()
        assert len(q) == int(89 * fps / FPS) + 1
        feats = track_features(q, fps, ClassifierConfig())
        assert abs(len(feats) - len(base)) <= 1 and np.isfinite(feats).all()
    assert rates <= set(cfg.frame_rates) and len(rates) >= 3
    assert min(heights) >= 1.4 - 1e-6 and max(heights) <= 2.0 + 1e-6
    assert max(heights) - min(heights) > 0.2
    # Same seed, same variant.
    a = augment(p, FPS, np.random.default_rng(9), cfg)[0]
    np.testing.assert_array_equal(a, augment(p, FPS, np.random.default_rng(9), cfg)[0])
    with pytest.raises(ValueError, match=r"role tracks must be \(T, 21, 3\)"):
        augment(p[:, :5], FPS, rng, cfg)
