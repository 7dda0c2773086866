"""Tests of the Table 1 predictors of the gait network and of QuaterNet, and of their use by
:func:`emotive.eval.table1.table1`, on the small rig with untrained networks."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import torch
from gait_helpers import NUM_JOINTS
from test_gait_generate import LABELS, make_model

from emotive.core import Motion
from emotive.core.ops import heading
from emotive.eval.table1 import table1
from emotive.models.gait.predict import GaitPredictor, straight_ahead
from emotive.models.gait.quaternet import QuaterNetConfig, QuaterNetwork
from emotive.models.gait.quaternet.predict import QuaterNetPredictor
from emotive.transforms.np_rotations import quaternion_multiply, yaw_quaternion


def walking_primer(model, frames: int = 30, fps: float = 30.0, yaw: float = 0.7) -> Motion:
    """The standing pose gliding along ``yaw`` at 1 m/s."""
    c = model.controls
    rot = np.broadcast_to(c.standing_rotations, (frames, NUM_JOINTS, 4)).copy()
    rot[:, 0] = quaternion_multiply(yaw_quaternion(np.full(frames, yaw)), rot[:, 0])
    pos = np.broadcast_to(c.skeleton.offsets, (frames, NUM_JOINTS, 3)).copy()
    travel = np.arange(frames) / fps
    pos[:, 0, 0] = np.sin(yaw) * travel
    pos[:, 0, 2] = np.cos(yaw) * travel
    return Motion(c.skeleton, rot, pos, fps, {"name": "glide", "style": "happy"})


def test_straight_ahead_starts_at_the_primer_end_along_its_heading():
    model = make_model()
    primer = walking_primer(model)
    path = straight_ahead(primer, model.controls)
    np.testing.assert_allclose(path.position(0.0), primer.positions[-1, 0, [0, 2]], atol=1e-9)
    np.testing.assert_allclose(path.heading(1.0), heading(primer)[-1], atol=1e-6)


@pytest.mark.parametrize("fps", [10.0, 30.0])
def test_predictors_continue_the_primer_at_its_rate(fps):
    model = make_model()
    primer = walking_primer(model, frames=18 if fps == 10 else 54, fps=fps)
    emotion = np.array([1.0, 0.0, 0.0, 0.0])
    torch.manual_seed(0)
    qnet = QuaterNetwork(QuaterNetConfig(labels=LABELS, num_joints=NUM_JOINTS, gru_hidden=16))
    for predictor in (GaitPredictor(model), QuaterNetPredictor(qnet, model.controls)):
        out = predictor.predict(primer, 42, emotion, LABELS)
        assert out.num_frames == 42 and out.fps == fps
        assert out.skeleton.names == primer.skeleton.names
        world = out.positions_with_end_sites()
        assert np.isfinite(world).all()
        np.testing.assert_allclose(np.linalg.norm(out.rotations, axis=-1), 1.0, atol=1e-5)
        # The root keeps walking forward along the primer's heading from where it ended.
        start = primer.positions[-1, 0, [0, 2]]
        ahead = world[:, 0, [0, 2]] - start
        direction = np.array([np.sin(0.7), np.cos(0.7)])
        assert (ahead @ direction)[-1] > 0
        lateral = ahead - np.outer(ahead @ direction, direction)
        assert np.abs(lateral).max() < 1e-6


def test_table1_runs_both_predictors_side_by_side():
    model = make_model()
    clips = [SimpleNamespace(name=f"glide-{y}", motion=walking_primer(model, 200, yaw=y),
                             info=SimpleNamespace(emotion="happy")) for y in (0.0, 1.0)]
    qnet = QuaterNetwork(QuaterNetConfig(labels=LABELS, num_joints=NUM_JOINTS, gru_hidden=16))
    result = table1([GaitPredictor(model), QuaterNetPredictor(qnet, model.controls)], clips,
                    fps=10.0, labels=LABELS)
    assert result.windows > 0
    assert {s.name for s in result.scores} == {"Ours", "QuaterNet"}
