"""``emotive crowd`` writes a BVH per agent, trajectories.csv that PedPy reads, a preview."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")
pedpy = pytest.importorskip("pedpy", reason="the crowd extra is not installed")

from tests.cli_helpers import run_main  # noqa: E402
from tests.crowd.conftest import CORRIDOR, write_scene  # noqa: E402

from emotive.crowd.measure import FREE_WAY, _free_stands, measure_run  # noqa: E402


def test_the_command_writes_bvh_trajectories_and_a_preview(tmp_path, monkeypatch, capsys):
    scene = write_scene(tmp_path, CORRIDOR.format(count=1))
    out = tmp_path / "out"
    code, _, err = run_main(monkeypatch, capsys, "crowd", scene, "--seconds", "2", "--out", out,
                            "--seed", "3")
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["agent-0000.bvh", "agent-0001.bvh", "agents.csv", "navigation.csv",
                     "preview.mp4", "scene.json", "trajectories.csv"]
    traj = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.csv")
    assert traj.frame_rate == 30
    assert list(traj.data.columns[:4]) == ["id", "frame", "x", "y"]
    assert sorted(traj.data["id"].unique()) == [0, 1] and traj.data["frame"].max() == 59
    measured = measure_run(out)
    assert measured["agents"] == 2 and measured["hips_in_obstacles"] == 0
    assert measured["min_hip_distance"] > 0.3 and measured["tie_p99"] < 0.1
    assert measured["stood_free"] == 0
    skates = [row["foot_skate"] for row in measured["per_emotion"].values()]
    assert skates and all(0 < s < 0.5 for s in skates)


def test_a_stand_counts_only_while_the_way_is_free_and_before_the_goal():
    fps = 10.0
    still = np.zeros((120, 2))
    walk = np.stack((np.arange(120) * 0.1, np.zeros(120)), axis=1)
    tracks = {0: (0, still), 1: (0, walk), 2: (0, still.copy()), 3: (0, still.copy())}
    free = {0: np.ones(120, bool), 1: np.ones(120, bool), 2: np.zeros(120, bool),
            3: np.ones(120, bool)}
    stands = _free_stands(tracks, fps, free, ends={3: 30})
    assert stands[0] == pytest.approx(12.0)
    assert stands[1] == 0.0 and stands[2] == 0.0
    assert stands[3] == pytest.approx(3.0)
    assert FREE_WAY > 0.3
