"""Not-a-replay measure (windows, nearest distance, distinct-clip threshold) and the resampler's
guard that redraws stretches too close to a captured window."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from emotive.models.lgb.features import effector_columns, layout_columns
from emotive.models.lgb.novelty import NoveltyReference, nearest_distance, windows
from emotive.models.lgb.resampler import GUARD_HOP, GUARD_ROUNDS, PROCESSES, EmotionResampler


@pytest.fixture(scope="module")
def model(sad_clips) -> EmotionResampler:
    return EmotionResampler.fit(sad_clips, "sad")


def _points(model: EmotionResampler, features: np.ndarray) -> np.ndarray:
    return features[:, effector_columns(model.layout)]


def test_windows_are_frame_major_and_hop():
    x = np.arange(24.0).reshape(8, 3)
    starts, w = windows(x, 3, hop=2)
    assert starts.tolist() == [0, 2, 4]
    np.testing.assert_array_equal(w[1], x[2:5].ravel())
    assert windows(x, 9)[1].shape == (0, 27)


def test_nearest_distance_is_rms_per_point():
    rng = np.random.default_rng(0)
    clip = rng.normal(size=(50, 15))
    _, pool = windows(clip, 10)
    # A replayed window is at distance 0; every point moved by 3 cm is at 3 cm.
    _, same = windows(clip[5:25], 10)
    np.testing.assert_allclose(nearest_distance(same, pool), 0.0, atol=1e-6)
    shifted = clip[5:25] + np.tile([0.03, 0.0, 0.0], 5)
    np.testing.assert_allclose(nearest_distance(windows(shifted, 10)[1], pool), 0.03, rtol=1e-6)
    assert np.isinf(nearest_distance(same, pool[:0])).all()


def test_threshold_is_how_close_distinct_clips_come():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(40, 15))
    b = a + np.tile([0.0, 0.05, 0.0], 5)
    ref = NoveltyReference.fit([a, b], 10)
    assert len(ref.pool) == 2 * 31
    np.testing.assert_allclose(ref.distinct, 0.05, rtol=1e-6)
    assert ref.threshold == pytest.approx(0.05)
    assert NoveltyReference.fit([a], 10).threshold == 0.0


def test_fitted_reference_holds_every_captured_window(model, sad_clips):
    ref = model.novelty
    assert ref.length == 30
    # Three sad clips of 160 frames: 131 windows each.
    assert len(ref.pool) == 3 * 131
    assert len(ref.distinct) == 3 * 131 and ref.threshold > 0


def test_guard_redraws_until_every_window_is_above_the_threshold(model):
    plain = replace(model, novelty=None)
    features, _, report = plain.sample_features(900, seed=3)
    assert report is None
    _, dist = model.novelty.novelty(_points(model, features), GUARD_HOP)
    # A threshold that some windows of this draw do not clear.
    low = float(np.quantile(dist, 0.03))
    strict = replace(model, novelty=replace(model.novelty, threshold=low))
    guarded, samples, report = strict.sample_features(900, seed=3)
    assert report.redrawn > 0 and report.below == 0
    assert report.windows == len(dist) and report.closest > strict.novelty.threshold
    # Independently of the report: every window of the rows is now new enough.
    _, after = strict.novelty.novelty(_points(model, guarded), 1)
    assert after.min() > strict.novelty.threshold * 0.9
    # The rows are still the drawn observations (chains jump where stretches were redrawn).
    for name, s in samples.items():
        np.testing.assert_array_equal(s.states, model.observed[s.index][:, layout_columns(
            model.layout, PROCESSES[name][0])])
    again, _, _ = strict.sample_features(900, seed=3)
    np.testing.assert_array_equal(guarded, again)


def test_guard_gives_up_and_reports_an_impossible_threshold(model):
    impossible = replace(model, novelty=replace(model.novelty, threshold=10.0))
    features, _, report = impossible.sample_features(300, seed=0)
    assert report.rounds == GUARD_ROUNDS
    assert report.below == report.windows > 0
    assert np.isfinite(features).all() and features.shape == (300, model.observed.shape[1])
