"""Tests of the animation controls a gait checkpoint carries, on the real dataset-1 clips."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from emotive.core import Motion
from emotive.data.emotion import ALL_LABELS
from emotive.errors import DataError
from emotive.models.gait import GaitConfig
from emotive.models.gait.controls import GaitControls, gait_controls, mean_rotations
from emotive.models.gait.data import load_gait_data


@pytest.fixture(scope="module")
def controls(bandai1_dir):
    data = load_gait_data(GaitConfig(labels=ALL_LABELS), ("bandai-namco-1",), 20, 20)
    return data["train"], gait_controls(data["train"])


@pytest.mark.data
def test_walking_paces_follow_the_data(controls):
    data, c = controls
    pace = dict(zip(c.labels, c.speed * data.fps, strict=True))
    steps = dict(zip(c.labels, c.step_frequency * data.fps / math.pi, strict=True))
    assert pace["sad"] == min(pace.values()) or pace["sad"] < 0.6
    assert pace["sad"] < min(pace["neutral"], pace["happy"]) < pace["angry"]
    assert all(0.9 <= steps[e] <= 3.0 for e in ("happy", "sad", "angry", "neutral"))
    assert 0.3 < pace["sad"] and pace["angry"] < 2.5
    # Walkers slow down in turns, by a few percent per 1/m of curvature.
    assert 0.01 < c.turn_slowing < 0.3


@pytest.mark.data
def test_standing_pose_and_round_trip(controls):
    data, c = controls
    np.testing.assert_allclose(np.linalg.norm(c.standing_rotations, axis=-1), 1.0, atol=1e-9)
    assert c.standing_positions[c.mover, [0, 2]].tolist() == [0.0, 0.0]
    pose = Motion(c.skeleton, c.standing_rotations[None], c.standing_positions[None], data.fps)
    world = pose.positions_with_end_sites()[0]
    hips, head = c.skeleton.index("Hips"), c.skeleton.index("Head")
    assert 0.7 < world[hips, 1] < 1.1 and world[head, 1] > world[hips, 1] + 0.4
    np.testing.assert_allclose(world[hips, [0, 2]], 0.0, atol=0.05)
    back = GaitControls.from_dict(c.to_dict())
    np.testing.assert_array_equal(back.speed, c.speed)
    assert back.skeleton.names == c.skeleton.names and back.turn_slowing == c.turn_slowing
    with pytest.raises(ValueError, match="one value per label"):
        GaitControls.from_dict({**c.to_dict(), "speed": [1.0]})


@pytest.mark.data
def test_data_without_walks_is_refused(controls):
    data, _ = controls
    runs = tuple(dataclasses.replace(info, content="run") for info in data.clips)
    with pytest.raises(DataError, match="no 'walk' clip"):
        gait_controls(dataclasses.replace(data, clips=runs))


def test_mean_rotations_ignores_signs():
    q = np.array([[[1.0, 0, 0, 0]], [[-1.0, 0, 0, 0]], [[0.0, 1, 0, 0]]])
    q[2] = [np.cos(0.1), np.sin(0.1), 0, 0]
    mean = mean_rotations(q)
    assert mean.shape == (1, 4) and mean[0, 0] > 0.99
