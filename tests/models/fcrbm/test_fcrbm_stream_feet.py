"""Streamed FCRBM agents on par with the gait stream: feet, stops, any emotion, cheap adds."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.roles import resolve_roles
from emotive.data.emotion import ALL_LABELS, valence_arousal
from emotive.eval.feet import foot_skating
from emotive.models.fcrbm import stream as stream_module
from emotive.models.fcrbm.adapter import SCALE_OFFSET
from emotive.models.fcrbm.generate import load_fcrbm_model
from emotive.models.fcrbm.stream import WARMUP_BUDGET, FCRBMStream
from emotive.paths import figure8, line

#: Mean skate (m/s, :func:`emotive.eval.feet.foot_skating`, contacts detected) of the real
#: dataset-1 walks, measured by ``python -m bench.bench_fcrbm`` (rows
#: ``fcrbm_stream_skate[...]``, baseline column) on 2026-12-05.
REAL_SKATE = {"happy": 0.111, "sad": 0.046}


@pytest.fixture(scope="module")
def model():
    return load_fcrbm_model()


@pytest.mark.parametrize("emotion", sorted(REAL_SKATE))
def test_streamed_walks_skate_within_real_walks(model, emotion):
    stream = FCRBMStream(model)
    stream.add_agents([figure8()] * 2, [emotion] * 2)
    world = np.stack([stream.step().world for _ in range(150)], 1)  # (B, T, P, 3)
    roots = world[:, :, stream.mover, [0, 2]]
    assert np.linalg.norm(np.diff(roots, axis=1), axis=-1).sum(1).min() > 1.5  # they walk
    skate = [float(foot_skating(w, resolve_roles(stream.skeleton), stream.fps).mean_speed)
             for w in world]
    print(f"{emotion}: skate {np.round(skate, 3)} m/s, real {REAL_SKATE[emotion]}")
    assert max(skate) <= 1.5 * REAL_SKATE[emotion]


def test_an_agent_stops_at_the_end_of_an_open_path(model):
    stream = FCRBMStream(model)
    path = line(3.0)
    stream.add_agent(path, "happy")
    for _ in range(20 * round(stream.fps)):  # until it stands (observable), at most 20 s
        frame = stream.step()
        if stream._rows.stop[0] >= 1.0:
            break
    last = np.stack([stream.step().world[0] for _ in range(round(stream.fps))])  # 1 s
    roots = last[:, stream.mover, [0, 2]]
    np.testing.assert_allclose(roots[-1], path.position(path.length), atol=0.02)
    assert np.abs(np.diff(roots, axis=0)).max() < 1e-9  # root speed 0 over the last second
    roles = resolve_roles(stream.skeleton)
    feet = last[:, [roles.index[r] for r in ("l_ankle", "l_toe", "r_ankle", "r_toe")]]
    assert np.abs(np.diff(feet, axis=0)).max() < 1e-9  # feet planted, not stepping on the spot
    assert feet[..., 1].min() < 0.05  # standing on the ground
    assert np.isfinite(frame.world).all()


def test_any_blend_or_valence_arousal_point_sets_the_context(model):
    stream = FCRBMStream(model)
    a, b = stream.add_agents([line(5.0)] * 2, ["happy=0.5,tired=0.5",
                                                "valence=0.3,arousal=-0.6"])
    rows = stream._rows
    blend = np.zeros(len(ALL_LABELS))
    blend[[ALL_LABELS.index("happy"), ALL_LABELS.index("tired")]] = 0.5
    np.testing.assert_allclose(rows.context[0], SCALE_OFFSET + valence_arousal(blend, ALL_LABELS))
    np.testing.assert_allclose(rows.context[1], SCALE_OFFSET + np.array([0.3, -0.6]))
    frame = stream.step()
    np.testing.assert_allclose(frame.emotion[0], blend)
    # A point is shown as a blend of the four emotions; the model reads the point itself.
    shown = {ALL_LABELS[k] for k in np.flatnonzero(frame.emotion[1] > 0)}
    assert shown <= set(stream.points_over)
    stream.set_emotion(a, {"valence": -0.5, "arousal": 0.5})
    np.testing.assert_allclose(stream._rows.context[0], SCALE_OFFSET + np.array([-0.5, 0.5]))
    stream.set_emotion(b, "old=1")
    np.testing.assert_allclose(stream._rows.context[1],
                               SCALE_OFFSET + valence_arousal(np.eye(len(ALL_LABELS))[
                                   ALL_LABELS.index("old")], ALL_LABELS))


def test_deferred_adds_sample_nothing_and_bound_the_work_per_step(model, monkeypatch):
    sampled: list[int] = []
    gibbs = stream_module.gibbs_frame

    def counted(network, weights, window, context, uniforms):
        sampled.append(len(window))
        return gibbs(network, weights, window, context, uniforms)

    monkeypatch.setattr(stream_module, "gibbs_frame", counted)
    stream = FCRBMStream(model, deferred=True)
    stream.add_agents([figure8()] * 2, ["happy", "sad"])
    while stream.warming:
        stream.step()
    sampled.clear()
    ids = stream.add_agents([figure8()] * 50, ["happy", "sad", "angry", "neutral"] * 12
                            + ["old", "proud"])
    assert sampled == []  # adding is bookkeeping only: no warm-up on the caller's thread
    assert set(stream.warming) == set(ids)
    steps = 0
    while stream.warming:
        sampled.clear()
        frame = stream.step()
        steps += 1
        # Each agent once per model frame, plus at most the warm-up budget.
        assert sum(sampled) <= len(stream) + WARMUP_BUDGET
        assert set(frame.agents) == set(stream.agents) - set(stream.warming)
    assert steps <= stream._warm_frames  # every waiting agent gets a frame per step at least
    assert set(stream.step().agents) == set(stream.agents)
