"""Tests of the ``table1`` suite (:func:`emotive.eval.suites.table1_suite`) on stand-in clips."""

from __future__ import annotations

import numpy as np
import pytest
from test_table1 import Oracle, clip

from emotive.errors import DataError
from emotive.eval import suites
from emotive.eval.table1 import ZeroVelocity


@pytest.fixture
def stand_in_sets(monkeypatch, random_motion):
    """Dataset 1 as two random clips, dataset 2 missing; ZeroVelocity the only baseline."""
    clips = [clip(random_motion(frames=240, seed=1), "a"),
             clip(random_motion(frames=210, seed=2), "b", "sad")]

    def load(name, locomotion):
        if name == suites.TABLE1_SETS["dataset 1"]:
            return clips
        raise DataError(f"dataset {name} is not installed: run `emotive data fetch {name}`")

    monkeypatch.setattr(suites, "load_clips", load)
    monkeypatch.setattr(suites, "split_clips", lambda c: {"test": c})
    monkeypatch.setattr(suites, "table1_baselines", lambda p: [ZeroVelocity()])
    return clips


def test_the_suite_reports_what_is_installed_and_says_what_is_not(stand_in_sets):
    from emotive.core.ops import resample

    oracle = Oracle({c.info.name: resample(c.motion, 10.0) for c in stand_in_sets})
    out = suites.table1_suite(oracle, rates=(10.0,))
    assert list(out["results"]["10 fps"]) == ["dataset 1"]
    assert list(out["unavailable"]) == ["dataset 2"]
    assert "dataset 2 is not installed: dataset bandai-namco-2-locomotion" in out["markdown"]
    assert "| Oracle | 0.000 ± 0.000, 0.0° |" in out["markdown"]
    # The oracle is exact, so it beats holding the last frame at every one of the 42 frames.
    assert "Oracle beats zero velocity at 42 of the 42 horizons (frames ahead 1-42)." in (
        out["markdown"])
    horizon = out["horizon"]["dataset 1"]
    np.testing.assert_allclose(horizon["pose"]["Oracle"], 0.0, atol=1e-9)
    assert horizon["frames"] == [1, 5, 10, 15, 20, 25, 30, 42]


def test_no_data_set_is_a_data_error(monkeypatch):
    def load(name, locomotion):
        raise DataError(f"dataset {name} is missing")

    monkeypatch.setattr(suites, "load_clips", load)
    with pytest.raises(DataError, match="bandai-namco-1, bandai-namco-2-locomotion"):
        suites.table1_suite(ZeroVelocity())


def test_the_horizon_rate_must_be_one_of_the_rates(stand_in_sets):
    with pytest.raises(ValueError, match=r"horizon_fps=30\.0"):
        suites.table1_suite(ZeroVelocity(), rates=(10.0,), horizon_fps=30.0)


@pytest.mark.parametrize(("frames", "text"), [([1, 2, 3, 5], "1-3, 5"), ([7], "7"),
                                              ([2, 4, 5, 6, 9, 10], "2, 4-6, 9-10")])
def test_frame_ranges(frames, text):
    assert suites._frame_ranges(np.array(frames)) == text
