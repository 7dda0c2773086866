"""Files written by emotive load in Blender's BVH importer and three.js's BVHLoader.

Both tools are optional on a developer's machine (the test skips, naming what to install);
CI sets ``EMOTIVE_REQUIRE_TOOLS=1`` and installs them, which turns a skip into a failure.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from emotive.io.bvh import read_bvh, write_bvh
from tools import require_tool

HERE = Path(__file__).resolve().parent
THREEJS = HERE / "threejs"


def _blender(path: Path, frame: int) -> dict:
    exe = shutil.which("blender")
    require_tool(exe is not None, "Blender is not installed (apt-get install blender)")
    out = subprocess.run(
        [exe, "-b", "--factory-startup", "--python-exit-code", "1",
         "--python", str(HERE / "blender_check.py"), "--", str(path), str(frame)],
        capture_output=True, text=True, timeout=300, check=False,
    )
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("EMOTIVE_CHECK ")]
    assert out.returncode == 0 and lines, out.stdout[-2000:] + out.stderr[-2000:]
    return json.loads(lines[0].removeprefix("EMOTIVE_CHECK "))


def _threejs(path: Path) -> dict:
    node = shutil.which("node")
    require_tool(
        node is not None and (THREEJS / "node_modules" / "three").is_dir(),
        f"node or three.js is missing (run: npm ci --prefix {THREEJS})",
    )
    out = subprocess.run(
        [node, str(THREEJS / "check_bvh.mjs"), str(path)],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout)


@pytest.fixture
def written(tmp_path, request) -> tuple[Path, object]:
    motion = request.getfixturevalue(request.param)
    return write_bvh(motion, tmp_path / "written.bvh"), motion


@pytest.fixture
def synthetic_motion(random_motion):
    return random_motion(frames=12, seed=1)


@pytest.fixture
def real_motion(bandai1_dir):
    return read_bvh(bandai1_dir / "data" / "dataset-1_walk_happy_001.bvh")


@pytest.mark.parametrize("written", ["synthetic_motion", "real_motion"], indirect=True)
class TestImporters:
    def test_blender_hierarchy_frames_and_pose(self, written):
        path, motion = written
        frame = motion.num_frames // 2
        got = _blender(path, frame)
        sk = motion.skeleton
        assert got["bones"] == list(sk.names)
        assert got["parents"] == [sk.names[p] if p >= 0 else None for p in sk.parents]
        assert got["frames"] == motion.num_frames
        assert got["fps"] == pytest.approx(motion.fps)
        # Blender's world joint positions agree with our forward kinematics (file units).
        ours = motion.global_positions()[frame] / 0.01
        np.testing.assert_allclose(np.array(got["heads"]), ours, atol=1e-3)

    def test_threejs_hierarchy_and_frames(self, written):
        path, motion = written
        got = _threejs(path)
        sk = motion.skeleton
        pairs = zip(got["bones"], got["parents"], strict=True)
        joints = [(b, p) for b, p in pairs if b != "ENDSITE"]
        assert [b for b, _ in joints] == list(sk.names)
        assert [p for _, p in joints] == [sk.names[p] if p >= 0 else None for p in sk.parents]
        assert got["bones"].count("ENDSITE") == len(sk.end_site_parents)
        assert got["frames"] == motion.num_frames
