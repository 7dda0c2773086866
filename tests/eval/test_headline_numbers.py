"""The README's Table 1 numbers for the gait network are what ``emotive evaluate`` computes.

The numbers are read from the README's numbers table ("A few measured numbers"), not copied
here, and recomputed with :mod:`emotive.eval.suites`, which the ``table1`` suite of
``emotive evaluate --model gait --suite table1`` runs, at 10 fps (the rate the README quotes;
the command adds 30 fps). Editing a number in the README without rerunning the command fails
here.

Two checks: the quick one recomputes the dataset-1 column alone (15 windows, seconds); the
full one runs :func:`~emotive.eval.suites.table1_suite` on both data sets (108 windows, about
two minutes on a busy 2-core machine), checks every column and the horizon counts, and is
marked ``slow``: it runs with the rest of the data tests in CI (``.ci/run``), and
``pytest -m "not slow"`` leaves it out.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"

#: The README rounds to three decimals: a stated figure is within half a unit of the last
#: digit, 0.0005, of the mean it states. The means are over 15 to 108 windows, computed in
#: float64 from float32 network outputs; between CPUs and kernels the models' outputs move by at
#: most about 1.5e-4 relative (docs/development.md), under 3e-5 on these errors (0.03-0.2):
#: 5e-5 covers that, and a README figure off by one in the last digit (0.001) still fails.
TOLERANCE = 0.0005 + 5e-5

#: README name -> (suite predictor name); the column order of the README's "a / b / c".
PREDICTORS = {"network": "Ours", "zero velocity": "Zero velocity", "QuaterNet": "QuaterNet"}
SETS = ("both", "dataset 1", "dataset 2")


def readme_table1() -> tuple[dict[str, int], dict[str, dict[str, float]]]:
    """Windows per set and pose error per predictor and set, from the README's gait row."""
    text = README.read_text(encoding="utf-8")
    row = next((line for line in text.splitlines() if line.startswith("| gait network |")),
               None)
    assert row is not None, "README.md's numbers table has no '| gait network |' row"
    windows = re.search(r"on the (\d+) / (\d+) / (\d+) test windows of both data sets / "
                        r"dataset 1 / dataset 2", row)
    assert windows, f"no 'on the A / B / C test windows of both data sets / ...' in: {row}"
    errors = {}
    for name in PREDICTORS:
        found = re.search(rf"{name} (\d\.\d+) / (\d\.\d+) / (\d\.\d+)", row)
        assert found, f"no '{name} A / B / C' pose errors in README's gait row: {row}"
        errors[name] = dict(zip(SETS, map(float, found.groups()), strict=True))
    return dict(zip(SETS, map(int, windows.groups()), strict=True)), errors


def readme_horizons() -> tuple[int, int, int]:
    """Horizons at which zero velocity beats the network on dataset 1, at which the network wins
    on dataset 2, and the horizons counted, from the README's gait row."""
    row = next(line for line in README.read_text(encoding="utf-8").splitlines()
               if line.startswith("| gait network |"))
    found = re.search(r"at (\d+) of the (\d+) horizons, while on dataset 2 it wins at (\d+) of "
                      r"(\d+)", row)
    assert found, f"no 'at A of the N horizons, while on dataset 2 it wins at B of N' in: {row}"
    lost, total, won, total2 = map(int, found.groups())
    assert total == total2
    return lost, won, total


def wins_over_zero_velocity(markdown: str, set_name: str) -> tuple[int, int]:
    """``(horizons won, horizons)`` of the suite's verdict sentence for ``set_name``."""
    part = markdown.split(f"Pose error by horizon, {set_name},")[1]
    found = re.search(r"Ours beats zero velocity at (\d+) of the (\d+) horizons", part)
    assert found, part
    return int(found.group(1)), int(found.group(2))


def test_the_readme_row_parses():
    windows, errors = readme_table1()
    assert set(errors) == set(PREDICTORS) and all(len(v) == 3 for v in errors.values())
    assert windows["both"] == windows["dataset 1"] + windows["dataset 2"]


@pytest.fixture(scope="module")
def gait():
    from emotive.models.registry import get_model

    return get_model("gait").load("predictor")


@pytest.mark.data
def test_readme_dataset1_numbers_quick(bandai1_dir, gait):
    from emotive.data.clips import load_clips
    from emotive.data.splits import split_clips
    from emotive.eval.suites import TABLE1_SETS, table1_baselines, table1_runs

    windows, stated = readme_table1()
    clips = split_clips(load_clips(TABLE1_SETS["dataset 1"], locomotion=True))["test"]
    run = table1_runs([gait, *table1_baselines(gait)], {"dataset 1": clips}, 10.0)["dataset 1"]
    assert run.windows == windows["dataset 1"]
    for readme_name, name in PREDICTORS.items():
        got = run[name].overall.pose
        assert abs(got - stated[readme_name]["dataset 1"]) <= TOLERANCE, (readme_name, got)


@pytest.fixture(scope="module")
def suite(bandai1_dir, bandai2_dir, gait) -> dict:
    from emotive.eval.suites import table1_suite

    return table1_suite(gait, rates=(10.0,))


@pytest.mark.data
@pytest.mark.slow
def test_readme_table1_numbers_are_what_the_command_computes(suite):
    windows, stated = readme_table1()
    at10 = suite["results"]["10 fps"]
    assert suite["unavailable"] == {}
    for set_name in SETS:
        assert at10[set_name]["windows"] == windows[set_name], set_name
        for readme_name, name in PREDICTORS.items():
            got = at10[set_name]["predictors"][name]["overall"]["pose"]
            assert abs(got - stated[readme_name][set_name]) <= TOLERANCE, (
                f"README says {readme_name} {stated[readme_name][set_name]} on {set_name}; "
                f"`emotive evaluate --model gait --suite table1` computes {got:.4f}"
            )


@pytest.mark.data
@pytest.mark.slow
def test_the_gait_network_clears_table1_and_beats_quaternet(suite):
    both = suite["results"]["10 fps"]["both"]["predictors"]
    ours, quaternet = both["Ours"]["overall"], both["QuaterNet"]["overall"]
    # Issue 3's targets: pose error at most 0.12 of the bounding-box diagonal, and better than
    # the QuaterNet baseline in pose and rotation error, on every set.
    assert ours["pose"] <= 0.12
    for set_name in SETS:
        scores = suite["results"]["10 fps"][set_name]["predictors"]
        assert scores["Ours"]["overall"]["pose"] < scores["QuaterNet"]["overall"]["pose"]
        assert scores["Ours"]["overall"]["rotation"] < scores["QuaterNet"]["overall"]["rotation"]
    assert ours["rotation"] < quaternet["rotation"]


@pytest.mark.data
@pytest.mark.slow
def test_readme_horizon_counts_are_the_suites(suite):
    # Counts of frames where one mean is below another: stable across CPUs because the two
    # curves never come closer than 5e-4 (dataset 2, frame 11), against kernel differences
    # of a few 1e-5.
    lost, won, total = readme_horizons()
    d1_won, d1_total = wins_over_zero_velocity(suite["markdown"], "dataset 1")
    d2_won, d2_total = wins_over_zero_velocity(suite["markdown"], "dataset 2")
    assert total == d1_total == d2_total
    assert (lost, won) == (d1_total - d1_won, d2_won)
