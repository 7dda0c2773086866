"""Novel trajectories and emotions: within their stated ranges, a function of (seed, index)."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.emotion import VALENCE_AROUSAL, valence_arousal
from emotive.synth import emotions as emo
from emotive.synth import trajectories as tr


@pytest.mark.parametrize("seconds", [1.0, 4.0, 10.0])
def test_trajectories_are_within_their_ranges(seconds):
    for p in range(10):
        t = tr.trajectory(0, p, seconds)
        low, high = tr.LENGTH_PER_SECOND
        assert seconds * low + tr.LENGTH_MARGIN - 0.05 <= t.length <= (
            seconds * high + tr.LENGTH_MARGIN + 0.05)
        assert np.allclose(t.path.points[0], 0.0)
        assert abs(float(t.path.heading(0.0))) < 1e-6          # starts facing +Z
        assert t.turns >= 1
        assert all(abs(a) <= tr.TURN_ANGLE_DEG[1] + 1e-6 for a in t.turn_angles_deg)
        assert t.max_curvature <= tr.CURVATURE[1] * 1.02
        # Measured along the path, the curvature stays within the range too.
        s = np.linspace(0.3, t.length - 0.3, 400)
        assert np.abs(t.path.curvature(s)).max() <= tr.CURVATURE[1] * 1.1


def test_trajectories_depend_on_seed_and_index_alone():
    a = tr.trajectory(7, 3, 10.0).path.points
    assert np.array_equal(a, tr.trajectory(7, 3, 10.0).path.points)
    for other in (tr.trajectory(7, 4, 10.0), tr.trajectory(8, 3, 10.0)):
        assert not np.allclose(a[-1], other.path.points[-1])


def test_a_later_draw_is_another_trajectory_of_the_same_seed_and_index():
    first = tr.trajectory(7, 3, 3.0)
    assert first.draw == 0 and first.summary()["draw"] == 0
    assert np.array_equal(first.path.points, tr.trajectory(7, 3, 3.0, 0).path.points)
    later = [tr.trajectory(7, 3, 3.0, k) for k in (1, 2)]
    assert [t.draw for t in later] == [1, 2]
    assert np.array_equal(later[0].path.points, tr.trajectory(7, 3, 3.0, 1).path.points)
    ends = [t.path.points[-1] for t in (first, *later)]
    assert not np.allclose(ends[0], ends[1]) and not np.allclose(ends[1], ends[2])


def test_blends_keep_away_from_the_corners():
    draws = [emo.novel_emotion(0, e, point=False) for e in range(200)]
    w = np.array([d.weights for d in draws])
    assert np.allclose(w.sum(1), 1.0) and (w >= 0).all()
    assert w.max() <= emo.MAX_WEIGHT
    va = np.array([[d.valence, d.arousal] for d in draws])
    assert np.allclose(va, valence_arousal(w))
    assert len({d.weights for d in draws}) == 200
    assert emo.novel_emotion(0, 5, False) == draws[5]


def test_points_keep_away_from_the_data_labels():
    draws = [emo.novel_emotion(1, e, point=True) for e in range(200)]
    va = np.array([[d.valence, d.arousal] for d in draws])
    assert np.linalg.norm(va, axis=1).max() <= emo.VA_RADIUS
    labelled = np.array([[p.valence, p.arousal] for p in VALENCE_AROUSAL.values()])
    gaps = np.linalg.norm(va[:, None] - labelled[None], axis=-1)
    assert gaps.min() >= emo.VA_CLEARANCE
    assert draws[0].keyframe(2.0) == {"t": 2.0, "valence": draws[0].valence,
                                      "arousal": draws[0].arousal}


def test_pairs_are_drawn_without_replacement():
    pairs = emo.pairs(0, 3, 100, 50)
    assert pairs.shape == (50, 2)
    assert sorted(pairs.ravel().tolist()) == list(range(100))
    assert not np.array_equal(pairs, emo.pairs(0, 4, 100, 50))


def test_transition_schedule():
    start, ramp = emo.switch_time(0, 12, 10.0)
    assert 4.0 <= start <= 6.0 and ramp == emo.RAMP_SECONDS
    assert emo.switch_time(0, 12, 4.0)[1] == pytest.approx(0.8)
    a, b = emo.novel_emotion(0, 0, False), emo.novel_emotion(0, 1, False)
    frames = emo.schedule_keyframes(a, b, start, ramp)
    assert [f["t"] for f in frames] == [0.0, start, start + ramp]
    assert frames[1]["emotion"] == frames[0]["emotion"] != frames[2]["emotion"]
