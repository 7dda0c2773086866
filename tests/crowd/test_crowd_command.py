"""``emotive crowd`` writes a BVH per agent, trajectories.csv that PedPy reads, a preview."""

from __future__ import annotations

import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")
pedpy = pytest.importorskip("pedpy", reason="the crowd extra is not installed")

from tests.cli_helpers import run_main  # noqa: E402
from tests.crowd.conftest import CORRIDOR, write_scene  # noqa: E402

from emotive.crowd.measure import measure_run  # noqa: E402


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
