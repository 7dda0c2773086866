"""The novelty check: shapes compared up to rotation and translation, coinciding paths refused,
the data's absence stated, and the paper's trajectories novel against the real data."""

from __future__ import annotations

import os

import numpy as np
import pytest

from emotive.paths import circle
from emotive.synth import novelty
from emotive.synth.recipe import Recipe
from emotive.synth.trajectories import trajectory


def _turned(points: np.ndarray, angle: float, shift) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, s], [-s, c]]) + np.asarray(shift)


def test_a_moved_copy_fits_exactly_and_another_shape_does_not():
    mine = novelty.resample(circle(1.25).points)
    piece = mine[5:25]
    line = np.stack((np.zeros(20), np.arange(20) * novelty.STEP), 1)
    gaps = novelty.best_fits(np.stack([_turned(piece, 1.1, (3.0, -2.0)), line]), mine)
    assert gaps[0] < 1e-9
    assert gaps[1] > 0.3


def test_a_trajectory_that_is_a_data_path_is_refused(monkeypatch):
    t = trajectory(0, 2, 4.0)
    copy = novelty.resample(_turned(t.path.points, 0.4, (1.0, 5.0)))
    monkeypatch.setattr(novelty, "data_root_paths", lambda: (["dataset-1_walk_x_001"], [copy]))
    report = novelty.check_trajectories([trajectory(0, 1, 4.0), t])
    assert report.checked and report.clips == 1
    assert [c.coincides for c in report.paths] == [False, True]
    with pytest.raises(novelty.NoveltyError, match="trajectory 2 follows the data's clip "
                                                   "dataset-1_walk_x_001"):
        novelty.raise_if_coinciding(report)
    assert novelty.NoveltyReport.from_dict(report.to_dict()) == report


def test_without_the_data_the_check_is_skipped_and_says_why(monkeypatch):
    monkeypatch.setattr(novelty, "data_root_paths", lambda: "the data set x is not available")
    report = novelty.check_trajectories([trajectory(0, 0, 4.0)])
    assert not report.checked and "not available" in report.reason
    novelty.raise_if_coinciding(report)


@pytest.mark.data
def test_the_papers_trajectories_are_not_in_the_data():
    found = novelty.data_root_paths()
    if isinstance(found, str):
        if os.environ.get("EMOTIVE_REQUIRE_DATA") == "1":
            pytest.fail(f"EMOTIVE_REQUIRE_DATA=1 but the data is missing: {found}")
        pytest.skip(found)
    recipe = Recipe()
    report = novelty.check_trajectories(
        [trajectory(recipe.seed, p, recipe.seconds) for p in range(recipe.paths)])
    assert report.checked and report.clips > 500
    assert not any(c.coincides for c in report.paths)
    # No data clip covers even half of a trajectory of the paper's recipe.
    assert max(c.coverage for c in report.paths) < 0.5
