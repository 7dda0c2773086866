"""``emotive transfer`` on a real walk: its line gives the output's foot skate beside the
input's, the output skates no more than the input and stands on its floor (needs dataset 1)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from cli_helpers import invoke_command
from emotive.commands.transfer import transfer
from emotive.core import ops
from emotive.core.roles import resolve_roles
from emotive.eval.feet import foot_skating
from emotive.ik.floor import FLOOR_TOLERANCE, clip_floor, depth_below_floor
from emotive.io.bvh import read_bvh, write_bvh

pytestmark = pytest.mark.data

CLIP = "dataset-1_walk_normal_001"
#: Three seconds of it.
FRAMES = 90
LINE = re.compile(r"; foot skate (\d+\.\d{3}) m/s \(input (\d+\.\d{3}) m/s\)$")


@pytest.fixture(scope="module")
def real_index(bandai1_dir, tmp_path_factory) -> Path:
    """An index of dataset 1's walks, one take per style, the clip left out."""
    from emotive.data.clips import load_clips
    from emotive.models.mar.build import build_database
    from emotive.models.mar.config import MARConfig
    from emotive.models.mar.database import Example

    examples = [Example(c.motion, "bandai-namco-1", c.content, c.info.emotion, c.name)
                for c in load_clips("bandai-namco-1", contents=["walk"]) if c.name != CLIP]
    config = MARConfig(datasets=("bandai-namco-1",), actions=("walk",), max_takes=1)
    return build_database(examples, config).save(tmp_path_factory.mktemp("index") / "i.npz")


@pytest.fixture(scope="module")
def real_walk(bandai1_dir, tmp_path_factory) -> Path:
    """The clip's first three seconds as a BVH file (in a temporary folder only)."""
    clip = ops.crop(read_bvh(bandai1_dir / "data" / f"{CLIP}.bvh"), 0, FRAMES)
    return write_bvh(clip, tmp_path_factory.mktemp("walk") / "walk.bvh", unit="cm")


def _skate(motion) -> float:
    points = motion.positions_with_end_sites()
    return float(foot_skating(points, resolve_roles(motion.skeleton), motion.fps).mean_speed)


def test_a_real_walk_skates_no_more_than_its_input_and_stands_on_its_floor(
        real_walk, real_index, tmp_path):
    out = tmp_path / "sad.bvh"
    result = invoke_command("transfer", transfer, real_walk, "--style", "sad", "--out", out,
                            "--index", real_index)
    assert result.exit_code == 0, result.output
    lines = [ln for ln in result.stdout.splitlines() if ln.strip()]
    assert len(lines) == 1
    found = LINE.search(lines[0])
    assert found, lines[0]
    printed, printed_input = float(found[1]), float(found[2])
    inp, got = read_bvh(real_walk), read_bvh(out)
    # The numbers are the suite's measure of the input and of what was written (the file
    # rounds the angles, so the output's may move in its last printed digit).
    assert printed_input == pytest.approx(_skate(inp), abs=6e-4)
    assert printed == pytest.approx(_skate(got), abs=2e-3)
    assert printed <= printed_input
    assert _skate(got) <= _skate(inp) + 1e-6
    roles = resolve_roles(inp.skeleton)
    floor = clip_floor(inp.positions_with_end_sites(), roles)
    assert depth_below_floor(got.positions_with_end_sites(), roles, floor).max() <= (
        FLOOR_TOLERANCE)
