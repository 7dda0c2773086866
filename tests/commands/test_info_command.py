"""Tests of ``emotive info`` and ``emotive features`` on synthetic BVH files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import emotive
from cli_helpers import run_main
from emotive.core import Motion, Skeleton
from emotive.data.clips import parse_clip_name
from emotive.io.bvh import write_bvh
from emotive.transforms.np_rotations import euler_to_quaternion
from rigs import RIG

FRAMES = 60


def make_walk(rename: dict[str, str] | None = None) -> Motion:
    """Two seconds at 30 fps: the root glides forward at 1.2 m/s while the legs swing."""
    rename = rename or {}
    names = tuple(rename.get(r[0], r[0]) for r in RIG)
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    sk = Skeleton(
        names, np.array([r[1] for r in RIG]), np.array([r[2] for r in RIG], dtype=float),
        end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends],
    )
    t = np.arange(FRAMES) / 30.0
    euler = np.zeros((FRAMES, len(RIG), 3))
    swing = 0.4 * np.sin(2 * np.pi * t)
    euler[:, names.index(rename.get("UpperLeg_L", "UpperLeg_L")), 1] = swing  # ZXY: X middle
    euler[:, names.index(rename.get("UpperLeg_R", "UpperLeg_R")), 1] = -swing
    rotations = euler_to_quaternion(euler, "ZXY")
    positions = np.broadcast_to(sk.offsets, (FRAMES, len(RIG), 3)).copy()
    positions[:, 0, 2] = 1.2 * t
    return Motion(sk, rotations, positions, 30.0)


@pytest.fixture
def walk_file(tmp_path: Path) -> Path:
    return write_bvh(make_walk(), tmp_path / "dataset-1_walk_happy_001.bvh", unit="cm")


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if not p.suffix == ".bvh")


class TestLabels:
    @pytest.mark.parametrize(("name", "labels"), [
        ("dataset-1_walk_happy_001.bvh", ("1", "walk", "happy", "001")),
        ("/x/dataset-2_walk-turn-left_not-confident_012.bvh",
         ("2", "walk-turn-left", "not-confident", "012")),
    ])
    def test_pattern(self, name, labels):
        got = parse_clip_name(name)
        assert got is not None
        assert (got["dataset"], got["content"], got["style"], got["take"]) == labels

    @pytest.mark.parametrize("name", ["walk.bvh", "dataset-1_walk_happy.bvh",
                                      "dataset-1_walk_happy_001_extra.bvh"])
    def test_other_names(self, name):
        assert parse_clip_name(name) is None


class TestInfo:
    def test_labelled_clip(self, monkeypatch, capsys, walk_file):
        code, out, _ = run_main(monkeypatch, capsys, "info", walk_file)
        assert code == 0
        assert "frames: 60" in out and "fps: 30" in out and "duration: 2.00 s" in out
        assert "content walk" in out and "style happy" in out and "take 001" in out
        assert "emotion label happy" in out
        assert "19 joints, 5 end sites" in out
        assert "map: bandai" in out and "Toes_L/end" in out and "missing" not in out

    def test_unlabelled_clip_with_missing_roles(self, monkeypatch, capsys, tmp_path):
        # Without --roles the rig's shape would name the head; the Bandai names lack it.
        path = write_bvh(make_walk({"Head": "Kopf"}), tmp_path / "walk.bvh")
        code, out, _ = run_main(monkeypatch, capsys, "info", path, "--roles", "bandai")
        assert code == 0
        assert "labels: none" in out
        assert "missing" in out and "roles not resolved" in out and "head" in out

    def test_bad_file(self, monkeypatch, capsys, tmp_path):
        code, out, err = run_main(monkeypatch, capsys, "info", tmp_path / "absent.bvh")
        assert code == 2 and out == ""
        assert err.startswith("error: ") and "absent.bvh" in err and err.count("\n") == 1


class TestFeatures:
    def test_csv(self, monkeypatch, capsys, walk_file, tmp_path):
        from emotive.core.roles import resolve_roles
        from emotive.features.affective import AFFECTIVE_FEATURE_NAMES, affective_features_np
        from emotive.io.bvh import read_bvh

        out = tmp_path / "features.csv"
        code, _, err = run_main(monkeypatch, capsys, "features", walk_file, "--out", out)
        assert code == 0, err
        header = out.read_text().splitlines()[0].split(",")
        assert header[0] == "time" and header[1:19] == list(AFFECTIVE_FEATURE_NAMES)
        assert header[-2:] == ["contact_left", "contact_right"] and len(header) == 28
        table = np.loadtxt(out, delimiter=",", skiprows=1)
        assert table.shape == (FRAMES, 28) and np.isfinite(table).all()
        np.testing.assert_allclose(table[:, 0], np.arange(FRAMES) / 30.0, atol=1e-9)
        motion = read_bvh(walk_file)
        expected = affective_features_np(
            motion.positions_with_end_sites(), resolve_roles(motion.skeleton)
        )
        np.testing.assert_allclose(table[:, 1:19], expected, rtol=1e-7, atol=1e-9)
        assert set(np.unique(table[:, -2:])) <= {0.0, 1.0}
        assert leftovers(tmp_path) == ["features.csv"]

    def test_plot(self, monkeypatch, capsys, walk_file, tmp_path):
        out, png = tmp_path / "f.csv", tmp_path / "f.png"
        code, _, err = run_main(
            monkeypatch, capsys, "features", walk_file, "--out", out, "--plot", png
        )
        assert code == 0, err
        assert png.read_bytes().startswith(b"\x89PNG")
        assert leftovers(tmp_path) == ["f.csv", "f.png"]

    def test_roles_file(self, monkeypatch, capsys, tmp_path):
        path = write_bvh(make_walk({"Head": "Kopf"}), tmp_path / "walk.bvh")
        out = tmp_path / "f.csv"
        code, _, err = run_main(
            monkeypatch, capsys, "features", path, "--out", out, "--roles", "bandai"
        )
        assert code == 2 and "head" in err and "--roles" in err and not out.exists()
        roles = tmp_path / "roles.json"
        from emotive.core.roles import BANDAI

        roles.write_text(json.dumps({**BANDAI, "head": "Kopf"}))
        code, _, err = run_main(
            monkeypatch, capsys, "features", path, "--out", out, "--roles", roles
        )
        assert code == 0, err
        assert out.is_file()

    def test_bad_bvh_leaves_no_output(self, monkeypatch, capsys, tmp_path):
        bad = tmp_path / "bad.bvh"
        bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")
        out, png = tmp_path / "f.csv", tmp_path / "f.png"
        code, stdout, err = run_main(
            monkeypatch, capsys, "features", bad, "--out", out, "--plot", png
        )
        assert code == 2 and stdout == ""
        assert err.startswith("error: ") and "bad.bvh" in err and err.count("\n") == 1
        assert leftovers(tmp_path) == []

    def test_failure_keeps_an_existing_output(self, monkeypatch, capsys, tmp_path):
        out = tmp_path / "f.csv"
        out.write_text("old")
        (tmp_path / "empty.bvh").write_text("")
        code, _, _ = run_main(monkeypatch, capsys, "features", tmp_path / "empty.bvh", "--out", out)
        assert code == 2 and out.read_text() == "old" and leftovers(tmp_path) == ["f.csv"]

    @pytest.mark.parametrize("option", [("--out", "missing/f.csv"), ("--plot", "f.gif")])
    def test_bad_output_paths(self, monkeypatch, capsys, walk_file, tmp_path, option):
        args = ["features", walk_file, "--out", tmp_path / "f.csv"]
        flag, value = option
        if flag == "--out":
            args[-1] = tmp_path / value
        else:
            args += [flag, tmp_path / value]
        code, _, err = run_main(monkeypatch, capsys, *args)
        assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
        assert leftovers(tmp_path) == []


def test_console_entry_point_one_line_error(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_bytes(b"\x00\x01binary")
    out = tmp_path / "f.csv"
    proc = subprocess.run(
        [sys.executable, "-c", "from emotive.cli import main; main()", "features", str(bad),
         "--out", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: ") and proc.stderr.count("\n") == 1
    assert "bad.bvh" in proc.stderr and not out.exists()


def test_version_and_help_list_every_command(monkeypatch, capsys):
    code, out, _ = run_main(monkeypatch, capsys, "--version")
    assert code == 0 and out.strip() == f"emotive {emotive.__version__}"
    code, out, _ = run_main(monkeypatch, capsys, "--help")
    assert code == 0
    for command in ("info", "features", "data"):
        assert command in out


def test_info_names_the_emotion_label_of_a_style(monkeypatch, capsys, tmp_path):
    for style, label in (("normal", "neutral"), ("not-confident", "not-confident"),
                         ("unheard-of", "none known")):
        path = write_bvh(make_walk(), tmp_path / f"dataset-1_walk_{style}_001.bvh", unit="cm")
        code, out, _ = run_main(monkeypatch, capsys, "info", path)
        assert code == 0 and f"emotion label {label}" in out
