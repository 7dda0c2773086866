"""glTF files written by emotive load in Blender's glTF importer and three.js's GLTFLoader,
and pass the Khronos glTF validator.

The tools are optional on a developer's machine (the tests skip, naming what to install); CI
sets ``EMOTIVE_REQUIRE_TOOLS=1`` and installs them, which turns a skip into a failure. The
node packages (pinned in ``gltf_js/package-lock.json``) are installed here with ``npm ci``
when they are missing and npm is there.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_gltf_writer import Read, standing_clip

from emotive.io.bvh import read_bvh
from emotive.io.gltf import write_gltf
from tools import require_tool

HERE = Path(__file__).resolve().parent
GLTF_JS = HERE / "gltf_js"


@pytest.fixture(scope="session")
def node() -> str:
    """The node executable, with the packages of ``gltf_js`` installed."""
    exe, npm = shutil.which("node"), shutil.which("npm")
    installed = all((GLTF_JS / "node_modules" / p).is_dir() for p in ("three", "gltf-validator"))
    if exe is not None and npm is not None and not installed:
        subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--silent"], cwd=GLTF_JS,
                       capture_output=True, timeout=300, check=False)
        installed = all((GLTF_JS / "node_modules" / p).is_dir()
                        for p in ("three", "gltf-validator"))
    require_tool(exe is not None and installed,
             f"node or the glTF node packages are missing (run: npm ci --prefix {GLTF_JS})")
    return exe


def _node_json(node: str, script: str, *args: object) -> dict:
    out = subprocess.run([node, str(GLTF_JS / script), *map(str, args)], capture_output=True,
                         text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout)


def _blender(path: Path, fps: float, frame: int) -> dict:
    exe = shutil.which("blender")
    require_tool(exe is not None,
                 "Blender is not installed (apt-get install blender python3-numpy)")
    out = subprocess.run(
        [exe, "-b", "--factory-startup", "--python-exit-code", "1",
         "--python", str(HERE / "blender_gltf_check.py"), "--", str(path), str(fps), str(frame)],
        capture_output=True, text=True, timeout=300, check=False,
    )
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("EMOTIVE_CHECK ")]
    assert out.returncode == 0 and lines, out.stdout[-2000:] + out.stderr[-2000:]
    return json.loads(lines[0].removeprefix("EMOTIVE_CHECK "))


@pytest.fixture(scope="module")
def written(request, tmp_path_factory):
    """``(path, motion)`` of each file checked: a small rig (binary and JSON), a real walk."""
    folder = tmp_path_factory.mktemp("gltf")
    if request.param == "real":
        data = request.getfixturevalue("bandai1_dir")
        motion = read_bvh(data / "data" / "dataset-1_walk_happy_001.bvh")
        motion = motion.replace(rotations=motion.rotations[:90], positions=motion.positions[:90])
        return write_gltf(motion, folder / "walk.glb"), motion
    motion = standing_clip(frames=24)
    return write_gltf(motion, folder / f"small{request.param}"), motion


FILES = pytest.mark.parametrize("written", [".glb", ".gltf", "real"], indirect=True)


@FILES
def test_the_khronos_validator_finds_no_issue(written, node):
    path, _ = written
    report = _node_json(node, "validate.mjs", path)
    assert report["errors"] == 0 and report["warnings"] == 0, report["messages"]
    assert report["info"]["hasSkins"] and report["info"]["animationCount"] == 1


@FILES
def test_threejs_builds_the_skinned_character_and_poses_it(written, node):
    path, motion = written
    frame = motion.num_frames // 2
    got = _node_json(node, "load_three.mjs", path, frame / motion.fps)
    sk = motion.skeleton
    assert got["skinned_meshes"] == 1 and got["clips"] == 1
    assert got["bones"] == list(sk.names)
    assert got["duration"] == pytest.approx((motion.num_frames - 1) / motion.fps, abs=1e-5)
    # three.js's posed bones and its skinned bounding box agree with ours within 1 cm.
    np.testing.assert_allclose(got["positions"], motion.global_positions()[frame], atol=0.01)
    verts = Read(path).skinned(frame)
    np.testing.assert_allclose(got["box_min"], verts.min(0), atol=0.01)
    np.testing.assert_allclose(got["box_max"], verts.max(0), atol=0.01)


@pytest.mark.parametrize("written", [".glb", "real"], indirect=True)
def test_blender_imports_the_armature_its_frames_and_its_pose(written):
    path, motion = written
    frame = motion.num_frames // 3
    got = _blender(path, motion.fps, frame)
    sk = motion.skeleton
    assert got["bones"] == list(sk.names)
    assert got["parents"] == [sk.names[p] if p >= 0 else None for p in sk.parents]
    assert got["frame_end"] - got["frame_start"] + 1 == pytest.approx(motion.num_frames)
    assert got["skinned_meshes"] == 1
    np.testing.assert_allclose(got["heads"], motion.global_positions()[frame], atol=0.01)
    verts = Read(path).skinned(frame)
    np.testing.assert_allclose(got["mesh_min"], verts.min(0), atol=0.01)
    np.testing.assert_allclose(got["mesh_max"], verts.max(0), atol=0.01)


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> Path:
    """``emotive generate --out walk.glb``, run as a user runs it."""
    out = tmp_path_factory.mktemp("generate") / "walk.glb"
    done = subprocess.run([sys.executable, "-c", "from emotive.cli import main; main()",
                           "generate", "--emotion", "happy", "--seconds", "3", "--out", str(out)],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return out


@pytest.mark.slow
def test_generate_writes_a_walk_that_three_and_the_validator_load(generated, node):
    read = Read(generated)
    frames = read.doc.accessors[read.doc.animations[0].samplers[0].input].count
    fps = (frames - 1) / read.doc.accessors[read.doc.animations[0].samplers[0].input].max[0]
    assert frames >= 3 * 30 and fps == pytest.approx(30.0)
    got = _node_json(node, "load_three.mjs", generated, 1.0)
    animated = {track.split(".")[0] for track in got["tracks"]}
    assert got["skinned_meshes"] == 1 and len(animated) >= 15
    assert got["duration"] == pytest.approx((frames - 1) / fps, abs=1e-5)
    assert 1.4 < got["box_max"][1] - got["box_min"][1] < 1.9
    report = _node_json(node, "validate.mjs", generated)
    assert report["errors"] == 0, report["messages"]
