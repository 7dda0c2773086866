"""``reconstruct``, ``transfer``, ``preview`` and ``features`` on CMU-style and Mixamo rigs.

The rigs are built from a real Bandai Namco walk by the project's own code
(:func:`emotive.core.rig_layouts.to_layout`): a CMU-style rig (``LHipJoint``, ``LowerBack``,
``Neck1``, fingers) at 120 fps with its joint frames aligned with the world in its rest pose,
as a CMU file has them (:func:`aligned_frames.world_aligned`), and a Mixamo rig (the
``mixamorig:`` prefix, XYZ rotations, inches). No command gets ``--roles``.
"""

from __future__ import annotations

import csv
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from emotive.commands.info import features
from emotive.commands.reconstruct import reconstruct
from emotive.commands.render import preview
from emotive.commands.transfer import transfer
from emotive.core.ops import resample
from emotive.core.rig_layouts import to_layout
from emotive.core.roles import resolve_roles
from emotive.io.bvh import read_bvh, write_bvh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "ik"))
from aligned_frames import world_aligned

from cli_helpers import invoke_command

#: The real walk the rigs are made of, and how many of its frames (30 fps).
INPUT, FRAMES = "dataset-1_walk_normal_001", 45
#: Styles of the small index the transfers use.
STYLES = ("happy", "angry")
#: Feature columns that depend on the pose only, not on where a rig ends its hands and feet.
POSE_COLUMNS = ("time", "shoulders_angle_at_spine", "l_elbow_angle", "r_elbow_angle",
                "head_neck_l_shoulder_angle", "head_neck_r_shoulder_angle", "l_knee_angle",
                "r_knee_angle", "root_height")


def _rigs(clip) -> dict:
    return {"cmu": resample(world_aligned(to_layout(clip, "cmu")), 120.0),
            "mixamo": to_layout(clip, "mixamo")}


@pytest.fixture(scope="module")
def walk(bandai1_dir):
    """The first :data:`FRAMES` frames of :data:`INPUT` on the Bandai rig."""
    clip = read_bvh(bandai1_dir / "data" / f"{INPUT}.bvh")
    return clip.replace(rotations=clip.rotations[:FRAMES], positions=clip.positions[:FRAMES])


@pytest.fixture(scope="module")
def files(walk, tmp_path_factory) -> dict[str, Path]:
    """The walk written as ``bandai.bvh``, ``cmu.bvh`` and ``mixamo.bvh``."""
    folder = tmp_path_factory.mktemp("rigs")
    out = {"bandai": write_bvh(walk, folder / "bandai.bvh")}
    for name, motion in _rigs(walk).items():
        out[name] = write_bvh(motion, folder / f"{name}.bvh")
    return out


@pytest.fixture(scope="module")
def index(tmp_path_factory) -> Path:
    """A small MAR index of dataset 1's walks in :data:`STYLES` (one take each, not INPUT)."""
    from emotive.data.clips import load_clips
    from emotive.models.mar.build import build_database
    from emotive.models.mar.config import MARConfig
    from emotive.models.mar.database import Example

    walks = load_clips("bandai-namco-1", contents=["walk"])
    examples = [Example(c.motion, "bandai-namco-1", c.content, c.info.emotion, c.name)
                for c in walks if c.name != INPUT and c.info.emotion in STYLES]
    config = MARConfig(datasets=("bandai-namco-1",), actions=("walk",), max_takes=1)
    return build_database(examples, config).save(tmp_path_factory.mktemp("index") / "i.npz")


def _height(motion) -> float:
    """Standing height of the first frame: highest minus lowest point, metres."""
    return float(np.ptp(motion.positions_with_end_sites()[0, :, 1]))


def _top_speed(motion, height: float) -> float:
    """Fastest joint or end site over the clip, body heights per second."""
    pts = motion.positions_with_end_sites()
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=-1).max() * motion.fps / height)


def _legs_below_hips(motion) -> bool:
    roles = resolve_roles(motion.skeleton)
    pts = motion.positions_with_end_sites()
    hips = pts[:, roles.index["root"], 1]
    return all((pts[:, roles.index[r], 1] < hips).all()
               for r in ("l_knee", "r_knee", "l_ankle", "r_ankle"))


def _same_rig(out: Path, source: Path):
    before, after = read_bvh(source), read_bvh(out)
    assert after.skeleton.names == before.skeleton.names
    assert after.skeleton.channels == before.skeleton.channels
    assert after.fps == before.fps
    assert np.isfinite(after.rotations).all() and np.isfinite(after.positions).all()
    return before, after


def _residuals(line: str) -> dict[str, float]:
    """Chain -> max target residual in mm from a ``reconstruct`` summary line."""
    return {m[0]: float(m[2]) for m in re.findall(r"(\w+) ([\d.]+)/([\d.]+)", line)}


def test_reconstruct_rebuilds_each_rig_as_closely_as_the_bandai_rig(files, tmp_path):
    lines = {}
    for name in ("bandai", "cmu", "mixamo"):
        out = tmp_path / f"{name}.bvh"
        result = invoke_command("reconstruct", reconstruct, files[name], "--out", out)
        assert result.exit_code == 0, result.output
        lines[name] = result.stdout
        before, after = _same_rig(out, files[name])
        assert _height(after) == pytest.approx(_height(before), rel=0.02)
        assert _top_speed(after, _height(before)) < 1.5 * _top_speed(before, _height(before))
    bandai = _residuals(lines["bandai"])
    assert set(bandai) == {"head_torso", "left_arm", "right_arm", "left_leg", "right_leg"}
    for name in ("cmu", "mixamo"):
        other = _residuals(lines[name])
        # In mm of metres: a wrong unit would scale these (a 25 cm CMU figure, 7x smaller).
        for chain, mm in bandai.items():
            assert 0.3 * mm - 0.05 < other[chain] < 2.0 * mm + 0.2, (name, chain, other)


@pytest.mark.parametrize("style", STYLES)
def test_transfer_on_the_cmu_rig_keeps_its_legs_and_speeds(files, index, style, tmp_path):
    out = tmp_path / f"{style}.bvh"
    result = invoke_command("transfer", transfer, files["cmu"], "--style", style, "--out", out,
                            "--index", index)
    assert result.exit_code == 0, result.output
    before, after = _same_rig(out, files["cmu"])
    assert _legs_below_hips(after)
    height = _height(before)
    # Before the fix: legs above the hips and joints at 30-50 body heights per second.
    assert _top_speed(after, height) < 2.0 * _top_speed(before, height)


def test_transfer_and_preview_on_the_mixamo_rig(files, index, tmp_path):
    out, video = tmp_path / "angry.bvh", tmp_path / "angry.gif"
    result = invoke_command("transfer", transfer, files["mixamo"], "--style", "angry",
                            "--out", out, "--index", index)
    assert result.exit_code == 0, result.output
    before, after = _same_rig(out, files["mixamo"])
    assert _legs_below_hips(after)
    assert _top_speed(after, _height(before)) < 2.0 * _top_speed(before, _height(before))
    for name in ("cmu", "mixamo"):
        video = tmp_path / f"{name}.gif"
        result = invoke_command("preview", preview, files[name], "--out", video, "--fps", "10",
                                "--width", "96", "--height", "96")
        assert result.exit_code == 0, result.output
        assert video.stat().st_size > 0


def _table(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open() as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_features_on_each_rig_match_the_bandai_rigs_columns(files, tmp_path):
    tables = {}
    for name in ("bandai", "cmu", "mixamo"):
        out = tmp_path / f"{name}.csv"
        result = invoke_command("features", features, files[name], "--out", out)
        assert result.exit_code == 0, result.output
        tables[name] = _table(out)
    header, bandai = tables["bandai"]
    for name, step in (("cmu", 4), ("mixamo", 1)):
        other_header, other = tables[name]
        assert other_header == header and np.isfinite(other).all()
        assert len(other) == FRAMES * step
        # Pose features that do not depend on where a rig ends its hands and feet agree.
        for column in POSE_COLUMNS:
            i = header.index(column)
            np.testing.assert_allclose(other[::step, i], bandai[:, i], atol=0.02, rtol=0.02,
                                       err_msg=f"{name} {column}")
