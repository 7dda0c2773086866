"""``emotive info`` and ``emotive features`` on every rig family, without --roles."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli_helpers import invoke_command
from emotive.commands.info import features, info
from emotive.core import Skeleton
from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.errors import RigError
from emotive.io.bvh import write_bvh
from layout_clips import synthetic_clip

FAMILY = {layout: layout for layout in LAYOUTS} | {"cmu-plain": "cmu"}


@pytest.fixture(scope="module")
def clip():
    return synthetic_clip(frames=40)


def scrambled(motion):
    """The clip on the same rig with names no family knows."""
    sk = motion.skeleton
    rig = Skeleton(tuple(f"bone{k:03d}" for k in range(sk.num_joints)), sk.parents,
                   sk.offsets, sk.channels, sk.end_site_parents, sk.end_site_offsets)
    return motion.replace(skeleton=rig)


@pytest.mark.parametrize("layout", LAYOUTS)
def test_info_and_features_on_every_layout(clip, tmp_path, layout):
    path = write_bvh(to_layout(clip, layout), tmp_path / f"{layout}.bvh")
    result = invoke_command("info", info, path)
    assert result.exit_code == 0, result.output
    text = result.output
    assert f"rig family: {FAMILY[layout]}" in text and "missing" not in text
    assert "height: 1.8" in text or "height: 1.7" in text
    assert "extra joints: " in text and "extra joints: none" not in text
    unit = {"cmu": "cmu", "cmu-plain": "cmu", "mixamo": "in", "unreal": "cm"}.get(layout, "m")
    assert f"file unit: {unit}" in text
    out = tmp_path / "f.csv"
    result = invoke_command("features", features, path, "--out", out)
    assert result.exit_code == 0, result.output
    assert len(out.read_text().splitlines()) == clip.num_frames + 1


def test_many_extra_joints_are_shortened(clip, tmp_path):
    path = write_bvh(to_layout(clip, "smplx"), tmp_path / "smplx.bvh")
    text = invoke_command("info", info, path).output
    line = next(ln for ln in text.splitlines() if ln.startswith("extra joints"))
    assert "extra joints: 34 (" in line and "and 22 more" in line


def test_info_on_a_rig_known_by_its_shape(clip, tmp_path):
    path = write_bvh(scrambled(to_layout(clip, "mixamo", prefix="")), tmp_path / "odd.bvh")
    result = invoke_command("info", info, path)
    assert result.exit_code == 0 and "rig family: topology" in result.output


def test_roles_template_round_trip(clip, tmp_path):
    path = write_bvh(scrambled(to_layout(clip, "cmu")), tmp_path / "odd.bvh")
    result = invoke_command("info", info, path, "--roles-template")
    assert result.exit_code == 0, result.output
    template = json.loads(result.output)
    assert template["root"] == "bone000" and all(template.values())
    roles = tmp_path / "roles.json"
    roles.write_text(json.dumps(template))
    out = tmp_path / "f.csv"
    result = invoke_command("features", features, path, "--out", out, "--roles", roles)
    assert result.exit_code == 0, result.output
    assert out.is_file()


def test_template_of_a_rig_lacking_roles_names_them_null(clip, tmp_path):
    motion = to_layout(clip, "mixamo")
    sk = motion.skeleton
    names = tuple("Kopf" if n == "mixamorig:Head" else n for n in sk.names)
    rig = Skeleton(names, sk.parents, sk.offsets, sk.channels, sk.end_site_parents,
                   sk.end_site_offsets)
    path = write_bvh(motion.replace(skeleton=rig), tmp_path / "kopf.bvh")
    out = tmp_path / "f.csv"
    result = invoke_command("features", features, path, "--out", out, "--roles", "mixamo")
    assert isinstance(result.exception, RigError)
    message = str(result.exception)
    assert "\n" not in message and "head" in message
    assert "emotive info FILE --roles-template" in message and not out.exists()
    result = invoke_command("info", info, path, "--roles", "mixamo", "--roles-template")
    template = json.loads(result.output)
    assert template["head"] is None and template["neck"] == "mixamorig:Neck"
    roles = tmp_path / "roles.json"
    roles.write_text(json.dumps(template | {"head": "Kopf"}))
    result = invoke_command("features", features, path, "--out", out, "--roles", roles)
    assert result.exit_code == 0, result.output


def _mixamo_without_spine2(clip, prefix):
    """A Mixamo rig that stops at ``Spine1`` and has no fingers: only names CMU shares."""
    motion = to_layout(clip, "cmu-plain", prefix=prefix)
    sk = motion.skeleton
    drop = ("FingerBase", "HandIndex1", "Thumb")
    keep = [j for j, n in enumerate(sk.names) if not n.endswith(drop)]
    rig = Skeleton(tuple(sk.names[j] for j in keep),
                   [keep.index(p) if p >= 0 else -1 for p in sk.parents[keep]],
                   sk.offsets[keep], tuple(sk.channels[j] for j in keep),
                   [keep.index(p) for p in sk.end_site_parents if p in keep],
                   sk.end_site_offsets[np.isin(sk.end_site_parents, keep)])
    return motion.replace(skeleton=rig, rotations=motion.rotations[:, keep],
                          positions=motion.positions[:, keep])


@pytest.mark.parametrize("prefix", ["mixamorig:", "mixamorig1:", "Armature|mixamorig:",
                                    "mixamorig12:"])
def test_info_names_mixamo_rigs_without_spine2_by_their_namespace(clip, tmp_path, prefix):
    motion = _mixamo_without_spine2(clip, prefix)
    assert not any(n.endswith("Spine2") for n in motion.skeleton.names)
    path = write_bvh(motion, tmp_path / "mixamo.bvh")
    result = invoke_command("info", info, path)
    assert result.exit_code == 0, result.output
    assert "rig family: mixamo" in result.output and "missing" not in result.output


@pytest.mark.parametrize("prefix", ["mixamorig:", "mixamorig1:"])
def test_info_names_mixamo_rigs_with_spine2_under_any_namespace(clip, tmp_path, prefix):
    path = write_bvh(to_layout(clip, "mixamo", prefix=prefix), tmp_path / "mixamo.bvh")
    assert "rig family: mixamo" in invoke_command("info", info, path).output


def test_the_same_names_without_the_namespace_stay_cmu(clip, tmp_path):
    path = write_bvh(_mixamo_without_spine2(clip, ""), tmp_path / "plain.bvh")
    assert "rig family: cmu" in invoke_command("info", info, path).output
