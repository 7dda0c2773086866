"""Tests of :mod:`emotive.eval.horizon`: pose error by prediction horizon."""

from __future__ import annotations

import numpy as np
import pytest
from test_table1 import FPS, Oracle, clip, rotating

from emotive.eval.horizon import HORIZON_FRAMES, by_horizon
from emotive.eval.table1 import ZeroVelocity, table1


def test_zero_velocity_drifts_further_with_the_horizon_and_the_oracle_not(random_motion):
    motion = rotating(random_motion, 240, first_axis=False)
    clips = [clip(motion, "spin")]
    result = table1([ZeroVelocity(), Oracle({"spin": motion})], clips, fps=FPS)
    errors = by_horizon(result)
    assert errors.frames.tolist() == [*HORIZON_FRAMES, result.predicted_frames]
    assert errors.windows == result.windows and errors.fps == FPS
    # Holding a turning pose: every joint's error grows with the time since the primer.
    assert np.all(np.diff(errors["Zero velocity"]) > 0)
    np.testing.assert_allclose(errors["Oracle"], 0.0, atol=1e-9)
    assert errors.beats("Oracle", "Zero velocity").tolist() == errors.frames.tolist()
    assert errors.beats("Zero velocity", "Oracle").tolist() == []


def test_every_horizon_averages_to_the_table1_pose_error(random_motion):
    clips = [clip(random_motion(frames=240, seed=1), "a"), clip(random_motion(frames=80, seed=2),
                                                                "b", "sad")]
    result = table1([ZeroVelocity()], clips, fps=10.0)
    errors = by_horizon(result, range(1, result.predicted_frames + 1))
    assert errors["Zero velocity"].mean() == pytest.approx(
        result["Zero velocity"].overall.pose, rel=1e-12)


def test_report_and_bad_horizons(random_motion):
    result = table1([ZeroVelocity()], [clip(random_motion(frames=240, seed=1), "a")], fps=10.0)
    errors = by_horizon(result, (10, 1))
    assert errors.frames.tolist() == [1, 10, 42]
    d = errors.to_dict()
    assert d["seconds"] == pytest.approx([0.1, 1.0, 4.2])
    assert d["pose"]["Zero velocity"] == pytest.approx(errors["Zero velocity"].tolist())
    lines = errors.to_markdown().splitlines()
    assert lines[0] == "| frames ahead | seconds | Zero velocity |" and len(lines) == 2 + 3
    assert lines[3].startswith("| 10 | 1.0 | **")
    for bad in ((0,), (43,)):
        with pytest.raises(ValueError, match=r"1\.\.42"):
            by_horizon(result, bad)
    with pytest.raises(KeyError, match="Oracle"):
        errors["Oracle"]
