from __future__ import annotations

import numpy as np
import pytest
from retarget_helpers import root_speed, speed_per_leg, walk

from cli_helpers import assert_failed_cleanly, invoke_command
from emotive.commands.generate import generate
from emotive.commands.retarget import retarget
from emotive.core import Skeleton
from emotive.core.rig_layouts import to_layout
from emotive.core.roles import resolve_roles
from emotive.errors import RigError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.retarget import foot_skate, rest_clip, rest_template
from layout_clips import synthetic_clip


def _rig_file(path, layout, unit, **template):
    skeleton = rest_template(to_layout(synthetic_clip(), layout).skeleton, **template)
    return write_bvh(rest_clip(skeleton, unit=unit), path)


@pytest.fixture(scope="module")
def cmu_rig(tmp_path_factory):
    return _rig_file(tmp_path_factory.mktemp("rigs") / "cmu.bvh", "cmu", "cmu",
                     proportions={"legs": 1.1, "arms": 0.95})


def test_walk_onto_a_mixamo_rig_keeps_its_speed_per_leg_length(tmp_path, bandai1_dir):
    source = write_bvh(walk(bandai1_dir), tmp_path / "walk.bvh")
    rig = _rig_file(tmp_path / "mixamo.bvh", "mixamo", "in", pose="t",
                    proportions={"legs": 1.15, "arms": 0.9, "spine": 1.05},
                    rotation_order="XZY")
    out = tmp_path / "out.bvh"
    result = invoke_command("retarget", retarget, source, "--to", rig, "--out", out)
    assert result.exit_code == 0, result.output
    assert "leg-length scale" in result.output and "foot skate" in result.output
    clip, moved, target = read_bvh(source), read_bvh(out), read_bvh(rig)
    assert moved.metadata["file_unit"] == "in"
    assert moved.skeleton.names == target.skeleton.names
    assert moved.skeleton.channels == target.skeleton.channels
    assert np.allclose(moved.skeleton.offsets[1:], target.skeleton.offsets[1:], atol=1e-6)
    assert speed_per_leg(moved) == pytest.approx(speed_per_leg(clip), rel=0.05)
    scale = root_speed(moved) / root_speed(clip)
    assert foot_skate(moved) <= 1.2 * scale * foot_skate(clip)


def _footless_rig(path):
    sk = synthetic_clip().skeleton
    keep = [j for j, n in enumerate(sk.names) if not n.startswith(("Foot_", "Toes_"))]
    parents = [keep.index(p) if p >= 0 else -1 for p in sk.parents[keep]]
    footless = Skeleton(tuple(sk.names[j] for j in keep), parents, sk.offsets[keep],
                        end_site_parents=[keep.index(sk.index("Head"))],
                        end_site_offsets=[[0.0, 0.1, 0.0]])
    return write_bvh(rest_clip(footless), path)


def test_a_rig_without_feet_fails_in_one_line_and_writes_nothing(tmp_path):
    clip = synthetic_clip()
    source = write_bvh(clip.replace(metadata={"file_unit": "cm"}), tmp_path / "in.bvh")
    rig = _footless_rig(tmp_path / "footless.bvh")
    before = sorted(tmp_path.iterdir())
    result = invoke_command("retarget", retarget, source, "--to", rig, "--out",
                            tmp_path / "out.bvh")
    assert_failed_cleanly(result, RigError, ["footless.bvh", "target rig", "l_ankle", "r_toe",
                                             "--to-roles"], tmp_path, before)


def test_generate_refuses_a_rig_or_primer_without_roles_before_writing(tmp_path):
    rig = _footless_rig(tmp_path / "footless.bvh")
    before = sorted(tmp_path.iterdir())
    result = invoke_command("generate", generate, "--seconds", 1, "--rig", rig, "--out",
                            tmp_path / "w.bvh", "--npz", tmp_path / "w.npz")
    assert_failed_cleanly(result, RigError, ["--rig", "footless.bvh", "l_ankle", "r_toe",
                                             "--rig-roles"], tmp_path, before)
    result = invoke_command("generate", generate, "--seconds", 1, "--primer", rig, "--out",
                            tmp_path / "w.bvh")
    assert_failed_cleanly(result, RigError, ["--primer", "another rig", "l_ankle",
                                             "--primer-roles"], tmp_path, before)


def _generated(tmp_path, emotion, rig):
    out = tmp_path / f"{emotion}.bvh"
    result = invoke_command("generate", generate, "--emotion", emotion, "--seconds", 3,
                            "--path", "line", "--rig", rig, "--out", out,
                            "--npz", tmp_path / f"{emotion}.npz")
    assert result.exit_code == 0, result.output
    return read_bvh(out)


def test_generate_sad_on_a_cmu_rig(tmp_path, cmu_rig):
    sad, happy = _generated(tmp_path, "sad", cmu_rig), _generated(tmp_path, "happy", cmu_rig)
    rig = read_bvh(cmu_rig)
    assert sad.skeleton.names == rig.skeleton.names and sad.metadata["file_unit"] == "cmu"
    assert np.allclose(sad.skeleton.offsets[1:], rig.skeleton.offsets[1:], atol=1e-6)
    points = sad.positions_with_end_sites()
    assert abs(points[..., 1].min()) < 0.03
    assert root_speed(sad) < 0.6 * root_speed(happy)
    npz = np.load(tmp_path / "sad.npz")
    assert npz["positions"].shape == points.shape and npz["names"][0] == "Hips"
    assert np.allclose(npz["positions"], points, atol=1e-4)


def test_generate_from_a_primer_on_another_rig(tmp_path, bandai1_dir):
    primer = write_bvh(to_layout(walk(bandai1_dir, "normal", 2.0), "mixamo"),
                       tmp_path / "primer.bvh")
    out = tmp_path / "primed.bvh"
    result = invoke_command("generate", generate, "--emotion", "angry", "--seconds", 2,
                            "--primer", primer, "--out", out)
    assert result.exit_code == 0, result.output
    primed = read_bvh(out)
    assert resolve_roles(primed.skeleton).map_name == "bandai"
    assert 0.3 < root_speed(primed) < 3.0
