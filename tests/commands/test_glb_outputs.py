"""Every command that writes a clip on a rig also writes glTF: ``--out x.glb`` / ``.gltf``."""

from __future__ import annotations

import numpy as np
import pygltflib
import pytest

from cli_helpers import invoke_command
from emotive.commands.reconstruct import reconstruct
from emotive.commands.retarget import retarget
from emotive.core.rig_layouts import to_layout
from emotive.io.bvh import write_bvh
from emotive.io.outputs import OutputError
from layout_clips import synthetic_clip


def _duration(path) -> tuple[float, int]:
    gltf = pygltflib.GLTF2().load(str(path))
    times = gltf.accessors[gltf.animations[0].samplers[0].input]
    return float(times.max[0]), len(gltf.skins[0].joints)


@pytest.fixture
def clip_file(tmp_path):
    return write_bvh(synthetic_clip(frames=20), tmp_path / "clip.bvh", unit="m")


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_reconstruct_writes_gltf(tmp_path, clip_file, suffix):
    out = tmp_path / f"rebuilt{suffix}"
    result = invoke_command("reconstruct", reconstruct, clip_file, "--out", out)
    assert result.exit_code == 0, result.output
    seconds, joints = _duration(out)
    assert seconds == pytest.approx(19 / 30.0) and joints >= 15


def test_retarget_writes_gltf_on_the_target_rig(tmp_path, clip_file):
    rig = write_bvh(to_layout(synthetic_clip(frames=2), "mixamo"), tmp_path / "rig.bvh")
    out = tmp_path / "on_mixamo.glb"
    result = invoke_command("retarget", retarget, clip_file, "--to", rig, "--out", out)
    assert result.exit_code == 0, result.output
    gltf = pygltflib.GLTF2().load(str(out))
    names = {gltf.nodes[j].name for j in gltf.skins[0].joints}
    assert "mixamorig:LeftUpLeg" in names
    assert np.isclose(_duration(out)[0], 19 / 30.0)


def test_an_unknown_output_type_is_refused_before_any_work(tmp_path, clip_file):
    result = invoke_command("reconstruct", reconstruct, clip_file, "--out", tmp_path / "x.fbx")
    assert isinstance(result.exception, OutputError)
    assert ".glb" in str(result.exception)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip.bvh"]
