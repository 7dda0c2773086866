"""The novelty check: shapes compared up to rotation and translation over the trajectory's own
length, exact coverage and relative gaps on both sides of their thresholds, coinciding draws
drawn again, the data's absence stated, and, against the real data, the paper's trajectories
and the small recipe's short walks (3 s and 4 s) novel for seeds 0-30."""

from __future__ import annotations

import os

import numpy as np
import pytest

from emotive.paths import GroundPath, circle
from emotive.synth import novelty
from emotive.synth.recipe import Recipe, named_recipe
from emotive.synth.trajectories import Trajectory, trajectory


def _turned(points: np.ndarray, angle: float, shift) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return points @ np.array([[c, s], [-s, c]]) + np.asarray(shift)


def _data(monkeypatch, *paths: np.ndarray) -> None:
    names = [f"dataset-1_walk_x_{k:03d}" for k in range(len(paths))]
    monkeypatch.setattr(novelty, "data_root_paths", lambda: (names, list(paths)))


def _cut(t: Trajectory, metres: float) -> Trajectory:
    """``t``'s first ``metres`` of arc as a trajectory of its own."""
    steps = np.linalg.norm(np.diff(t.path.points, axis=0), axis=1)
    arc = np.concatenate(([0.0], np.cumsum(steps)))
    return Trajectory(t.index, GroundPath.from_polyline(t.path.points[arc <= metres]), (), 0.0)


def _line(points: int) -> np.ndarray:
    return np.stack((np.zeros(points), np.arange(points) * novelty.STEP), 1)


def test_a_moved_copy_fits_exactly_and_another_shape_does_not():
    mine = novelty.resample(circle(1.25).points)
    piece = mine[5:25]
    line = np.stack((np.zeros(20), np.arange(20) * novelty.STEP), 1)
    gaps = novelty.best_fits(np.stack([_turned(piece, 1.1, (3.0, -2.0)), line]), mine)
    assert gaps[0] < 1e-9
    assert gaps[1] > 0.3


def test_coverage_is_the_share_of_the_trajectory_spanned():
    # Points count steps from 0: 5 points span 4 steps of a trajectory of 8 steps.
    assert novelty.coverage(5, 9) == 0.5
    assert novelty.coverage(24, 30) == 23 / 29
    assert novelty.coverage(25, 30) == 24 / 29
    assert novelty.coverage(30, 30) == 1.0
    assert novelty.coverage(40, 30) == 1.0          # a longer clip spans all of it
    mine = novelty.resample(circle(1.25).points)[:9]
    longer = novelty.resample(circle(1.25).points)[:12]
    gap, relative, cover = novelty.fits(
        mine, [_turned(mine[:5], 0.3, (1.0, 2.0)), _turned(mine, -2.0, (0.0, 4.0)), longer])
    assert cover.tolist() == [0.5, 1.0, 1.0]
    assert np.allclose(gap, 0.0, atol=1e-9) and np.allclose(relative, 0.0, atol=1e-8)


def test_a_clip_spanning_four_fifths_of_the_trajectory_coincides_and_less_does_not(monkeypatch):
    t = _cut(trajectory(0, 0, 3.0), 7.3)
    mine = novelty.resample(t.path.points)
    assert len(mine) == 30                          # 29 steps of 0.25 m
    below, above = _turned(mine[3:27], 0.7, (2, 1)), _turned(mine[2:27], -0.4, (0, 5))
    _data(monkeypatch, below)                       # 24 points: 23/29 = 0.793 of it
    check = novelty.check_trajectories([t]).paths[0]
    assert (check.coverage, check.coincides) == (0.793, False)
    _data(monkeypatch, above)                       # 25 points: 24/29 = 0.828 of it
    check = novelty.check_trajectories([t]).paths[0]
    assert (check.coverage, check.coincides) == (0.828, True)


@pytest.mark.parametrize("points", [32, 64])
def test_the_gap_threshold_is_a_share_of_the_length_at_any_length(monkeypatch, points):
    length = (points - 1) * novelty.STEP
    straight = Trajectory(0, GroundPath.from_polyline(_line(points)), (), 0.0)
    # Offsets +a, -a, -a, +a along a line: the best fit leaves every point a from it.
    signs = np.tile([1.0, -1.0, -1.0, 1.0], points // 4)
    for share, coincides in ((0.029, True), (0.031, False)):
        wiggle = _line(points) + np.stack((signs * share * length, np.zeros(points)), 1)
        _data(monkeypatch, _turned(wiggle, 0.5, (3.0, 1.0)))
        check = novelty.check_trajectories([straight]).paths[0]
        assert check.distance_m == pytest.approx(share * length, abs=1e-4)
        assert check.relative_gap == pytest.approx(share, abs=1e-4)
        assert (check.coverage, check.coincides) == (1.0, coincides)


def test_a_trajectory_that_is_a_data_path_is_refused(monkeypatch):
    t = trajectory(0, 2, 4.0)
    _data(monkeypatch, novelty.resample(_turned(t.path.points, 0.4, (1.0, 5.0))))
    report = novelty.check_trajectories([trajectory(0, 1, 4.0), t])
    assert report.checked and report.clips == 1
    assert [c.coincides for c in report.paths] == [False, True]
    with pytest.raises(novelty.NoveltyError, match=r"trajectory 2 follows the data's clip "
                                                   r"dataset-1_walk_x_000 .* give a new --out"):
        novelty.raise_if_coinciding(report)
    assert novelty.NoveltyReport.from_dict(report.to_dict()) == report


def test_a_coinciding_draw_is_drawn_again_from_the_seed(monkeypatch):
    first = trajectory(0, 1, 4.0)
    _data(monkeypatch, novelty.resample(_turned(first.path.points, 0.4, (1.0, 5.0))))
    paths, report = novelty.novel_trajectories(0, 3, 4.0)
    assert [c.draw for c in report.paths] == [0, 1, 0] == list(report.draws(3))
    assert [t.draw for t in paths] == [0, 1, 0]
    assert np.array_equal(paths[1].path.points, trajectory(0, 1, 4.0, 1).path.points)
    assert np.array_equal(paths[0].path.points, trajectory(0, 0, 4.0).path.points)
    assert not any(c.coincides for c in report.paths)
    again = novelty.NoveltyReport.from_dict(report.to_dict())
    assert again == report and again.draws(3) == (0, 1, 0)
    monkeypatch.setattr(novelty, "MAX_DRAWS", 1)
    with pytest.raises(novelty.NoveltyError, match=r"--seconds 4: all 1 draws of trajectory 1 "
                                                   r"\(seed 0\) follow a clip .* longer "
                                                   "--seconds"):
        novelty.novel_trajectories(0, 3, 4.0)


def test_without_the_data_the_check_is_skipped_and_says_why(monkeypatch):
    monkeypatch.setattr(novelty, "data_root_paths", lambda: "the data set x is not available")
    report = novelty.check_trajectories([trajectory(0, 0, 4.0)])
    assert not report.checked and "not available" in report.reason
    novelty.raise_if_coinciding(report)
    paths, report = novelty.novel_trajectories(0, 2, 3.0)
    assert not report.checked and report.draws(2) == (0, 0)
    assert [t.draw for t in paths] == [0, 0]


def _real_data() -> tuple[list[str], list[np.ndarray]]:
    found = novelty.data_root_paths()
    if isinstance(found, str):
        if os.environ.get("EMOTIVE_REQUIRE_DATA") == "1":
            pytest.fail(f"EMOTIVE_REQUIRE_DATA=1 but the data is missing: {found}")
        pytest.skip(found)
    return found


@pytest.mark.data
def test_the_papers_trajectories_are_not_in_the_data():
    _real_data()
    recipe = Recipe()
    report = novelty.check_trajectories(
        [trajectory(recipe.seed, p, recipe.seconds) for p in range(recipe.paths)])
    assert report.checked and report.clips > 500
    assert not any(c.coincides for c in report.paths)
    # No data clip covers even half of a trajectory of the paper's recipe.
    assert max(c.coverage for c in report.paths) < 0.5
    # So none is drawn again: the paper's data set keeps its first draws.
    _, drawn = novelty.novel_trajectories(recipe.seed, recipe.paths, recipe.seconds)
    assert drawn.draws(recipe.paths) == (0,) * recipe.paths


@pytest.mark.data
@pytest.mark.slow
@pytest.mark.parametrize("seconds", [3.0, 4.0])
def test_short_walks_of_the_small_recipe_are_novel_for_every_seed(seconds):
    """The small recipe at 3 s and 4 s, seeds 0-30: drawn until novel, within the draws."""
    _, data = _real_data()
    small = named_recipe("small", seconds=seconds)
    redrawn = 0
    for seed in range(31):
        paths, report = novelty.novel_trajectories(seed, small.paths, seconds)
        assert report.checked and not any(c.coincides for c in report.paths)
        for t, check in zip(paths, report.paths, strict=True):
            assert check.draw == t.draw < novelty.MAX_DRAWS
            # Every clip spanning most of it is a different shape.
            _, relative, cover = novelty.fits(novelty.resample(t.path.points), data)
            assert relative[cover >= novelty.MIN_COVERAGE].min() >= novelty.MATCH_FRACTION
            redrawn += t.draw > 0
    # Some first draws coincide with a clip at either length: the draws are needed.
    assert redrawn > 0
