"""FBX input through Blender: a generated walk made into FBX by Blender reads back."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from test_gltf_input import MM, joint_error

from cli_helpers import invoke_command
from emotive.commands.generate import generate
from emotive.errors import MotionFileError
from emotive.io import fbx, input_limits
from emotive.io.bvh import read_bvh, write_bvh
from emotive.io.motion_files import read_motion
from tools import bvh_to_fbx, require_tool


@pytest.fixture(scope="module")
def blender() -> str:
    exe = shutil.which("blender")
    require_tool(exe is not None, "Blender is not installed (apt-get install blender)")
    return exe


@pytest.fixture(scope="module")
def made(blender, tmp_path_factory):
    """``(generated walk, its FBX made by Blender, the FBX read by emotive)``."""
    folder = tmp_path_factory.mktemp("fbx")
    result = invoke_command("generate", generate, "--seconds", 2, "--out", folder / "gen.bvh")
    assert result.exit_code == 0, result.output
    walk = read_bvh(folder / "gen.bvh")
    bvh = write_bvh(walk, folder / "walk.bvh", unit="m")
    out = folder / "walk.fbx"
    bvh_to_fbx(blender, bvh, out)
    return walk, out, read_motion(out)


def test_a_generated_walk_through_blenders_fbx_keeps_its_joints_within_a_millimetre(made):
    walk, _, back = made
    assert set(walk.skeleton.names) <= set(back.skeleton.names)
    assert back.fps == walk.fps and back.num_frames == walk.num_frames
    assert joint_error(back, walk) < MM


def test_fbx_leaf_bones_come_through_as_extra_joints(made):
    walk, path, back = made
    extra = set(back.skeleton.names) - set(walk.skeleton.names)
    assert extra and all(n.endswith("_end") for n in extra)
    assert back.metadata["source"] == str(path) and back.metadata["name"] == "walk"


def test_a_corrupt_fbx_gives_a_typed_error(blender, tmp_path):
    path = tmp_path / "broken.fbx"
    path.write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00" + b"\xff" * 64)
    with pytest.raises(MotionFileError, match=r"broken\.fbx: Blender could not read a skeleton"):
        read_motion(path)
    path.write_text("; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n}\n")
    with pytest.raises(MotionFileError, match=r"ASCII FBX files are not supported.*binary FBX"):
        read_motion(path)


def test_without_blender_the_error_says_how_to_install_it(tmp_path, monkeypatch):
    path = tmp_path / "walk.fbx"
    path.write_bytes(b"Kaydara FBX Binary  \x00")
    monkeypatch.setattr(fbx.shutil, "which", lambda name: None)
    with pytest.raises(MotionFileError) as exc:
        read_motion(path)
    assert str(exc.value).startswith(str(path))
    assert "apt-get install blender" in str(exc.value) and ".glb" in str(exc.value)


def test_a_missing_fbx_is_named(tmp_path: Path):
    with pytest.raises(MotionFileError, match=r"absent\.fbx: no such file"):
        read_motion(tmp_path / "absent.fbx")


def _no_blender(*args, **kwargs):
    raise AssertionError("Blender was started")


@pytest.mark.parametrize(("make", "words"), [
    (lambda p: os.mkfifo(p), "not a regular file"),
    (lambda p: p.mkdir(), "is a folder"),
    (lambda p: p.write_bytes(b""), "is empty"),
    (lambda p: os.symlink("/dev/zero", p), "not a regular file"),
    (lambda p: os.symlink("/proc/self/environ", p), "is a system file"),
    (lambda p: _sparse(p, input_limits.MAX_FILE_BYTES + 1), "at most 1,073,741,824 are read"),
])
def test_what_is_not_a_regular_small_file_is_refused_before_blender_starts(
        tmp_path, monkeypatch, make, words):
    path = tmp_path / "walk.fbx"
    make(path)
    monkeypatch.setattr(fbx.subprocess, "run", _no_blender)
    with pytest.raises(MotionFileError) as exc:
        read_motion(path)
    assert str(exc.value).startswith(f"{path}: ") and words in str(exc.value)


def _sparse(path: Path, size: int) -> None:
    with open(path, "wb") as fh:
        fh.truncate(size)


def test_blender_reads_a_private_copy_of_the_checked_bytes(tmp_path, monkeypatch):
    path = tmp_path / "walk.fbx"
    path.write_bytes(b"Kaydara FBX Binary  \x00" + bytes(range(256)))
    seen = {}

    def fake_blender(argv, **kwargs):
        copy = Path(argv[argv.index("--") + 1])
        seen.update(folder=copy.parent.name, data=copy.read_bytes(), cwd=kwargs["cwd"])
        kwargs["stdout"].write(b"noise\n" * 50_000 + b"EMOTIVE_FBX_ERROR no armature\n")
        return subprocess.CompletedProcess(argv, 3)

    monkeypatch.setattr(fbx.shutil, "which", lambda name: "/usr/bin/blender")
    monkeypatch.setattr(fbx.subprocess, "run", fake_blender)
    with pytest.raises(MotionFileError, match=r"walk\.fbx: Blender could not read a skeleton "
                       r"from it \(no armature\)"):
        read_motion(path)
    assert seen["folder"].startswith("emotive-fbx-") and seen["data"] == path.read_bytes()
    assert Path(seen["cwd"]).name == seen["folder"]
