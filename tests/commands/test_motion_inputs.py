"""Every command that reads a motion or a rig takes glTF too, and refuses a bad one in a line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from cli_helpers import run_main
from emotive.io.bvh import read_bvh, write_bvh
from emotive.io.gltf import write_gltf
from emotive.io.motion_files import read_motion

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "models" / "mar"))
from mar_helpers import CONFIG, examples, styled
from test_info_command import make_walk


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    """A walk as GLB, a rig to retarget onto as glTF, a MAR index and a style clip as GLB."""
    from emotive.models.mar.build import build_database

    folder = tmp_path_factory.mktemp("inputs")
    walk = make_walk()
    rig = walk.replace(skeleton=walk.skeleton.scaled(1.1), positions=walk.positions[:1] * 1.1,
                       rotations=walk.rotations[:1])
    held = tuple(f"synthetic_walk_{s}_2" for s in ("neutral", "proud", "sad"))
    index = build_database(examples(3, skip=held), CONFIG).save(folder / "index.npz")
    return {"walk": write_gltf(walk, folder / "walk.glb"),
            "rig": write_gltf(rig, folder / "tall.gltf"),
            "styled": write_gltf(styled("walk", "neutral", take=2), folder / "styled.glb"),
            "index": index}


def test_info_describes_a_glb(files, monkeypatch, capsys):
    code, out, err = run_main(monkeypatch, capsys, "info", files["walk"])
    assert code == 0, err
    assert "frames: 60" in out and "fps: 30" in out and "file unit: m" in out


def test_retarget_reads_a_glb_clip_onto_a_gltf_rig(files, tmp_path, monkeypatch, capsys):
    out = tmp_path / "tall.bvh"
    code, stdout, err = run_main(monkeypatch, capsys, "retarget", files["walk"], "--to",
                                 files["rig"], "--out", out)
    assert code == 0, err
    moved, rig = read_bvh(out), read_motion(files["rig"])
    assert moved.skeleton.names == rig.skeleton.names and moved.num_frames == 60
    assert np.allclose(moved.skeleton.offsets[1:], rig.skeleton.offsets[1:], atol=1e-5)
    assert "leg-length scale 1.100" in stdout


def test_classify_reads_a_glb_as_it_reads_the_same_walk_in_bvh(files, tmp_path, monkeypatch,
                                                                capsys):
    bvh = write_bvh(read_motion(files["walk"]), tmp_path / "walk.bvh", unit="cm")
    results = []
    for path in (files["walk"], bvh):
        code, out, err = run_main(monkeypatch, capsys, "classify", path, "--json")
        assert code == 0, err
        results.append(json.loads(out))
    glb, text = results
    assert [w["perceived"] for w in glb["windows"]] == [w["perceived"] for w in text["windows"]]
    for a, b in zip(glb["windows"], text["windows"], strict=True):
        assert list(a["emotion"].values()) == pytest.approx(list(b["emotion"].values()),
                                                            abs=1e-3)


def test_transfer_reads_a_glb_and_writes_one(files, tmp_path, monkeypatch, capsys):
    out = tmp_path / "proud.glb"
    code, _, err = run_main(monkeypatch, capsys, "transfer", files["styled"], "--style", "proud",
                            "--out", out, "--index", files["index"], "--action", "walk")
    assert code == 0, err
    before, after = read_motion(files["styled"]), read_motion(out)
    assert after.skeleton.names == before.skeleton.names and after.num_frames > 0


def test_generate_takes_a_gltf_rig(files, tmp_path, monkeypatch, capsys):
    out = tmp_path / "onto.bvh"
    code, _, err = run_main(monkeypatch, capsys, "generate", "--seconds", 1, "--rig",
                            files["rig"], "--out", out)
    assert code == 0, err
    assert read_bvh(out).skeleton.names == read_motion(files["rig"]).skeleton.names


@pytest.mark.parametrize("command", [["info"], ["classify"], ["retarget", "--to", "RIG", "--out",
                                                                "OUT.bvh"]])
def test_a_corrupt_glb_fails_in_one_line_naming_the_file(files, tmp_path, monkeypatch, capsys,
                                                         command):
    bad = tmp_path / "broken.glb"
    bad.write_bytes(b"glTF\x02\x00\x00\x00\x10")
    args = [str(files["rig"]) if a == "RIG" else str(tmp_path / a) if a == "OUT.bvh" else a
            for a in command]
    code, _, err = run_main(monkeypatch, capsys, command[0], bad, *args[1:])
    assert code != 0 and not (tmp_path / "OUT.bvh").exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "glTF" in lines[0], err


def test_an_evaluation_folder_takes_glb_files(files, tmp_path):
    from emotive.eval.sources import read_folder

    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "walk.glb").write_bytes(files["walk"].read_bytes())
    (folder / "labels.json").write_text(json.dumps({"walk.glb": {"emotion": "happy"}}))
    (clip,) = read_folder(folder)
    assert clip.name == "walk.glb" and clip.motion.num_frames == 60
