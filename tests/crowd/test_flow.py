"""``emotive.crowd.flow``: PedPy's flow through a line and speed-density in an area, on
trajectories with a known answer, its one-line errors, and one short real run."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

pytest.importorskip("pedpy", reason="the crowd extra is not installed")

from emotive.crowd.errors import CrowdError
from emotive.crowd.flow import (
    WEIDMANN,
    main,
    measure_flow,
    parse_area,
    parse_line,
    weidmann_speed,
)
from emotive.crowd.trajectories import trajectory_text

RATE = 1.5          # persons per second through the line
FPS = 30


def write_run(folder, rows, fps, area=None):
    """A run folder as ``emotive crowd`` writes it: trajectories.csv and scene.json."""
    folder.mkdir(parents=True, exist_ok=True)
    table = np.asarray(rows, dtype=np.float64)
    table = table[np.lexsort((table[:, 0], table[:, 1]))]
    (folder / "trajectories.csv").write_text(trajectory_text(table, fps), encoding="utf-8")
    if area is not None:
        scene = {"name": "synthetic", "area": {"polygon": area, "obstacles": []}, "groups": []}
        (folder / "scene.json").write_text(json.dumps(scene), encoding="utf-8")
    return folder


def door_run(folder, count=30):
    """``count`` agents walking +x at 1 m/s along y = 0, one every 1/RATE s, crossing x = 0
    (between frames, never on a frame), and one agent walking beside the line, never across."""
    gap = round(FPS / RATE)
    rows = []
    for a in range(count):
        start = a * gap
        for k in range(6 * FPS):
            rows.append((a, start + k, -3.01 + k / FPS, 0.0))
    for k in range(count * gap + 6 * FPS):
        rows.append((count, k, -3.0 + k / FPS * 0.2, 3.0))
    return write_run(folder, rows, FPS, [[-4, -4], [4, -4], [4, 4], [-4, 4]])


class TestLineFlow:
    def test_a_known_rate_comes_back_as_the_specific_flow(self, tmp_path):
        count = 30
        run = door_run(tmp_path / "run", count)
        result = measure_flow(run, line="0,-0.5,0,0.5", window=2.0)["line"]
        assert result["length"] == pytest.approx(1.0)
        assert result["crossed"] == count
        assert sorted(a for a, _ in result["crossings"]) == list(range(count))
        assert result["n_t"][-1][1] == count
        # the windows after the first measure whole gaps between crossings: exact up to a frame
        assert result["steady_windows"] >= 5
        assert result["steady_specific_flow"] == pytest.approx(RATE, abs=0.02)
        # PedPy's flow over the whole passage counts N persons over N - 1 gaps (plus a frame)
        overall = result["specific_flow"]
        assert RATE <= overall <= RATE * count / (count - 1) + 0.01
        assert result["flow"] == pytest.approx(overall)

    def test_the_specific_flow_divides_by_the_line_length(self, tmp_path):
        run = door_run(tmp_path / "run")
        short = measure_flow(run, line="0,-0.5,0,0.5", window=2.0)["line"]
        wide = measure_flow(run, line="0,-1,0,1", window=2.0)["line"]
        assert wide["crossed"] == short["crossed"]
        assert wide["steady_flow"] == pytest.approx(short["steady_flow"])
        assert wide["steady_specific_flow"] == pytest.approx(short["steady_specific_flow"] / 2)

    def test_a_single_crossing_gives_no_flow(self, tmp_path):
        run = door_run(tmp_path / "run", count=1)
        result = measure_flow(run, line="0,-0.5,0,0.5")["line"]
        assert result["crossed"] == 1
        assert result["flow"] is None and result["steady_flow"] is None


def lattice_run(folder, sx, sy, fps=10, seconds=5.0, speed=0.8):
    """A lattice ``sx`` x ``sy`` m (one agent per cell) across a 4 m wide corridor, moving +x
    at ``speed``; with the areas below, no agent ever stands on an area's border."""
    rows, a = [], 0
    for x0 in np.arange(sx / 2, 24.0, sx):
        for y in np.arange(sy / 2, 4.0, sy):
            rows.extend((a, k, x0 + speed * k / fps, y) for k in range(round(seconds * fps)))
            a += 1
    return write_run(folder, rows, fps, [[-1, 0], [41, 0], [41, 4], [-1, 4]])


class TestAreaSpeedDensity:
    @pytest.mark.parametrize("method", ["classic", "voronoi"])
    def test_a_moving_lattice_gives_its_density_and_speed(self, tmp_path, method):
        # 0.6 m x 0.8 m cells: 1/0.48 = 2.083 agents per m^2, inside the 2.00-2.25 bin; the
        # area is 7 columns long, so the count inside never changes
        run = lattice_run(tmp_path / "run", 0.6, 0.8)
        result = measure_flow(run, area="8,0,12.2,0,12.2,4,8,4", density=method)["area"]
        assert result["size"] == pytest.approx(16.8)
        assert result["frames"] == 50
        assert result["mean_density"] == pytest.approx(1 / 0.48, abs=1e-6)
        assert result["mean_speed"] == pytest.approx(0.8, abs=2e-3)
        (row,) = result["bins"]
        assert (row["from"], row["to"], row["frames"]) == (2.0, 2.25, 50)
        assert row["specific_flow"] == pytest.approx(0.8 / 0.48, abs=5e-3)
        assert row["weidmann_speed"] == pytest.approx(float(weidmann_speed(1 / 0.48)))

    def test_densities_fall_into_bins_a_quarter_wide(self, tmp_path):
        run = lattice_run(tmp_path / "run", 1.2, 0.8)   # 1.04 agents per m^2
        (row,) = measure_flow(run, area="8,0,11.6,0,11.6,4,8,4")["area"]["bins"]
        assert (row["from"], row["to"]) == (1.0, 1.25)
        assert row["density"] == pytest.approx(1 / 0.96)


class TestWeidmann:
    def test_free_speed_at_no_density_and_none_at_the_jam_density(self):
        v = weidmann_speed(np.array([0.0, 1e-3, 1.0, 2.0, 4.0, WEIDMANN["rho_max"], 7.0]))
        assert v[0] == WEIDMANN["v0"] and v[1] == pytest.approx(WEIDMANN["v0"])
        assert np.all(np.diff(v) <= 0) and v[-2] == 0 and v[-1] == 0
        expected = 1.34 * (1 - math.exp(-1.913 * (1 / 1.0 - 1 / 5.4)))
        assert v[2] == pytest.approx(expected)


class TestErrors:
    def test_a_missing_folder_or_file(self, tmp_path):
        with pytest.raises(CrowdError, match="no such folder"):
            measure_flow(tmp_path / "nowhere", line="0,0,0,1")
        (tmp_path / "empty").mkdir()
        with pytest.raises(CrowdError, match=r"trajectories\.csv: not found"):
            measure_flow(tmp_path / "empty", line="0,0,0,1")

    def test_a_line_no_one_crosses(self, tmp_path):
        run = door_run(tmp_path / "run", count=3)
        with pytest.raises(CrowdError, match="no one crosses it") as err:
            measure_flow(run, line="2,3.5,2,3.9")
        assert "--line 2,3.5,2,3.9" in str(err.value)

    def test_a_line_or_area_outside_the_scene(self, tmp_path):
        run = door_run(tmp_path / "run", count=3)
        with pytest.raises(CrowdError, match="outside the scene's walkable area"):
            measure_flow(run, line="0,-0.5,0,9")
        with pytest.raises(CrowdError, match="outside the scene's walkable area"):
            measure_flow(run, area="10,10,12,10,12,12")

    def test_an_area_no_one_enters(self, tmp_path):
        run = door_run(tmp_path / "run", count=3)
        with pytest.raises(CrowdError, match="no agent is ever inside it"):
            measure_flow(run, area="-1,-3,1,-3,1,-2,-1,-2")

    @pytest.mark.parametrize(("line", "area", "words"), [
        (None, None, "say where to measure"),
        ("0,0,1", None, "needs 4 numbers"),
        ("0,0,0,0", None, "both ends are the same point"),
        ("a,b,c,d", None, "not a list of numbers"),
        (None, "0,0,1,1", "at least 3 corners"),
        (None, "0,0,4,0,4,4,2,1,0,4", "not convex"),
        (None, "0,0,1,1,0,1,1,0", "cross"),
    ])
    def test_bad_options(self, tmp_path, line, area, words):
        run = door_run(tmp_path / "run", count=3)
        with pytest.raises(CrowdError, match=words):
            measure_flow(run, line=line, area=area)

    def test_voronoi_needs_the_scene(self, tmp_path):
        run = door_run(tmp_path / "run", count=3)
        (run / "scene.json").unlink()
        with pytest.raises(CrowdError, match=r"needs the run.s scene\.json"):
            measure_flow(run, area="-1,-1,1,-1,1,1,-1,1", density="voronoi")

    def test_the_command_prints_one_line_and_writes_nothing(self, tmp_path, capsys):
        run = door_run(tmp_path / "run", count=3)
        assert main([str(run), "--line", "2,3.5,2,3.9"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: --line") and "\n" not in err
        assert not (run / "flow.json").exists()


def test_the_command_prints_the_table_and_writes_flow_json(tmp_path, capsys):
    run = door_run(tmp_path / "run", count=10)
    # a first number below zero needs the = form, or argparse reads it as an option
    assert main([str(run), "--line", "0,-0.5,0,0.5", "--area=-1,-1,1,-1,1,1,-1,1"]) == 0
    printed = capsys.readouterr().out
    written = json.loads((run / "flow.json").read_text(encoding="utf-8"))
    assert written == json.loads(json.dumps(measure_flow(run, "0,-0.5,0,0.5",
                                                         "-1,-1,1,-1,1,1,-1,1")))
    assert "10 crossed" in printed and "Weidmann: v0 1.34 m/s" in printed
    assert list(run.glob(".flow.json*")) == []


def test_parsers_read_metres():
    assert parse_line("10,4.5, 10,5.5") == ((10.0, 4.5), (10.0, 5.5))
    assert parse_area("8,0,12,0,12,4,8,4") == ((8.0, 0.0), (12.0, 0.0), (12.0, 4.0), (8.0, 4.0))


ROOM = """
[area]
polygon = [[0, 0], [5, 0], [5, 2.1], [7, 2.1], [7, 2.9], [5, 2.9], [5, 5], [0, 5]]

[[groups]]
name = "leavers"
spawn = [[0.5, 0.5], [4, 0.5], [4, 4.5], [0.5, 4.5]]
count = 12
goal = [[6.5, 2.1], [7, 2.1], [7, 2.9], [6.5, 2.9]]
emotion = "neutral"
"""


@pytest.mark.slow
def test_a_room_emptying_through_a_door(tmp_path, monkeypatch, capsys):
    pytest.importorskip("jupedsim", reason="the crowd extra is not installed")
    from tests.cli_helpers import run_main
    from tests.crowd.conftest import write_scene

    scene = write_scene(tmp_path, ROOM)
    out = tmp_path / "out"
    code, _, err = run_main(monkeypatch, capsys, "crowd", scene, "--seconds", "30", "--out",
                            out, "--seed", "1", "--no-preview")
    assert code == 0, err
    assert main([str(out), "--line", "5,2.1,5,2.9", "--window", "2"]) == 0
    printed = capsys.readouterr().out
    flow = json.loads((out / "flow.json").read_text(encoding="utf-8"))["line"]
    with open(out / "agents.csv", encoding="utf-8", newline="") as f:
        reached = {int(r["id"]) for r in csv.DictReader(f) if r["reached"] == "1"}
    assert reached, "no agent reached the exit in 30 s"
    assert {a for a, _ in flow["crossings"]} == reached
    for key in ("specific_flow", "steady_specific_flow"):
        assert flow[key] is not None and math.isfinite(flow[key]) and flow[key] > 0
    assert f"{flow['crossed']} crossed" in printed
