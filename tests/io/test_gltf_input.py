"""glTF input: emotive's own files, hand-built documents, Blender's export, and bad files."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pygltflib as gl
import pytest
from test_gltf_writer import standing_clip

from cli_helpers import invoke_command
from emotive.commands.generate import generate
from emotive.errors import MotionFileError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.io.gltf import encode_gltf, gltf_document, write_gltf
from emotive.io.gltf_read import read_gltf
from emotive.io.motion_files import read_motion
from tools import require_tool

#: Largest joint position difference allowed on any frame, metres.
MM = 1e-3

#: Run inside Blender: import a BVH (metres) and export it as GLB (``-- IN.bvh OUT.glb``).
BVH_TO_GLB = """
import builtins, sys, bpy, numpy
if not hasattr(numpy, "bool"):
    numpy.bool = numpy.bool_
_open = builtins.open
# Blender 3.4's BVH importer opens files with mode "rU", which Python 3.11 removed.
builtins.open = lambda f, mode="r", *a, **k: _open(f, mode.replace("U", ""), *a, **k)
src, dst = sys.argv[sys.argv.index("--") + 1:][:2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=src, update_scene_fps=True, update_scene_duration=True)
bpy.ops.export_scene.gltf(filepath=dst, export_format="GLB", export_animations=True,
                          export_force_sampling=True, export_materials="NONE")
"""


def joint_error(a, b) -> float:
    """Largest distance (metres) between the joints two clips share by name, any frame."""
    names = [n for n in a.skeleton.names if n in b.skeleton.names]
    pa = a.global_positions()[:, [a.skeleton.index(n) for n in names]]
    pb = b.global_positions()[:, [b.skeleton.index(n) for n in names]]
    assert len(pa) == len(pb)
    return float(np.linalg.norm(pa - pb, axis=-1).max())


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """A 2 s walk written by ``emotive generate`` (BVH, centimetres) and read back."""
    out = tmp_path_factory.mktemp("generated") / "walk.bvh"
    result = invoke_command("generate", generate, "--seconds", 2, "--out", out)
    assert result.exit_code == 0, result.output
    return read_bvh(out)


@pytest.mark.parametrize(("suffix", "mesh"), [(".glb", True), (".gltf", True), (".glb", False)])
def test_a_generated_walk_survives_write_and_read_within_a_millimetre(generated, tmp_path,
                                                                     suffix, mesh):
    path = write_gltf(generated, tmp_path / f"walk{suffix}", mesh=mesh)
    back = read_motion(path)
    assert back.skeleton.names == generated.skeleton.names
    assert np.array_equal(back.skeleton.parents, generated.skeleton.parents)
    assert back.fps == generated.fps and back.num_frames == generated.num_frames
    assert joint_error(back, generated) < MM
    assert back.metadata["file_unit"] == "m"
    assert back.metadata["height_m"] == pytest.approx(generated.metadata["height_m"], rel=0.02)


def test_the_clip_written_again_as_bvh_keeps_its_joints(generated, tmp_path):
    back = read_gltf(write_gltf(generated, tmp_path / "walk.glb"))
    again = read_bvh(write_bvh(back, tmp_path / "again.bvh"))
    assert joint_error(again, generated) < MM


def _external_bin(motion, folder: Path) -> Path:
    doc, blob = gltf_document(motion)
    (folder / "walk data.bin").write_bytes(blob)
    doc.buffers[0].uri = "walk%20data.bin"
    path = folder / "walk.gltf"
    path.write_text(doc.gltf_to_json())
    return path


def test_a_gltf_with_its_buffer_in_a_bin_file_reads(tmp_path):
    motion = standing_clip(frames=12)
    back = read_gltf(_external_bin(motion, tmp_path))
    assert back.fps == 25.0 and back.num_frames == 12
    assert joint_error(back, motion) < MM


def _doc_with(motion, change) -> tuple[gl.GLTF2, bytes]:
    doc, blob = gltf_document(motion, mesh=False)
    blob = change(doc, blob) or blob
    doc.buffers[0].byteLength = len(blob)
    return doc, blob


def _write(doc, blob, path: Path) -> Path:
    path.write_bytes(encode_gltf(doc, blob, binary=path.suffix == ".glb"))
    return path


def test_step_keys_hold_and_uneven_keys_resample_at_30_fps(tmp_path):
    motion = standing_clip(frames=5)
    doc, blob = gltf_document(motion, mesh=False)
    times = np.array([0.0, 0.11, 0.25, 0.31, 0.5], dtype=np.float32)
    extra = times.tobytes()
    doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(extra)))
    doc.accessors.append(gl.Accessor(bufferView=len(doc.bufferViews) - 1, count=5, type="SCALAR",
                                     componentType=gl.FLOAT, min=[0.0], max=[0.5]))
    for sampler in doc.animations[0].samplers:
        sampler.input = len(doc.accessors) - 1
        sampler.interpolation = gl.ANIM_STEP
    blob += extra
    doc.buffers[0].byteLength = len(blob)
    back = read_gltf(_write(doc, blob, tmp_path / "step.glb"))
    assert back.fps == 30.0 and back.num_frames == 16
    # Frame k is at k / 30 s: keys 0, 1, 2, 3, 4 start at frames 0, 3.3, 7.5, 9.3, 15.
    held = [0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 3, 3, 3, 3, 3, 4]
    expected = motion.global_positions()[held]
    assert np.abs(back.global_positions() - expected).max() < 1e-5


def test_cubic_spline_keys_use_their_values(tmp_path):
    motion = standing_clip(frames=10)
    doc, blob = gltf_document(motion, mesh=False)
    chunks = [blob]
    size = len(blob)
    for sampler in doc.animations[0].samplers:
        acc = doc.accessors[sampler.output]
        view = doc.bufferViews[acc.bufferView]
        values = np.frombuffer(blob, np.float32, acc.count * (4 if acc.type == "VEC4" else 3),
                               view.byteOffset).reshape(acc.count, -1)
        tangents = np.full_like(values, 7.0)  # never read: the values alone are interpolated
        cubic = np.stack([tangents, values, tangents], axis=1).astype(np.float32).tobytes()
        doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=size, byteLength=len(cubic)))
        doc.accessors.append(gl.Accessor(bufferView=len(doc.bufferViews) - 1,
                                         count=3 * acc.count, type=acc.type,
                                         componentType=gl.FLOAT))
        sampler.output, sampler.interpolation = len(doc.accessors) - 1, gl.ANIM_CUBICSPLINE
        chunks.append(cubic)
        size += len(cubic)
    blob = b"".join(chunks)
    doc.buffers[0].byteLength = len(blob)
    back = read_gltf(_write(doc, blob, tmp_path / "cubic.gltf"))
    assert back.num_frames == 10 and joint_error(back, motion) < MM


def test_a_scaled_turned_parent_node_is_folded_into_the_joints(tmp_path):
    """A centimetre rig under a 0.01-scaled, Z-up-to-Y-up node (as FBX converters write)."""
    motion = standing_clip(frames=8)
    in_cm = motion.replace(skeleton=motion.skeleton.scaled(100.0),
                           positions=motion.positions * 100.0)
    doc, blob = gltf_document(in_cm, mesh=False)
    turn = [-np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]  # x, y, z, w: -90 degrees about X
    doc.nodes.append(gl.Node(name="Armature", children=[0], scale=[0.01] * 3, rotation=turn,
                             translation=[1.0, 0.0, 0.0]))
    doc.scenes[0].nodes = [len(doc.nodes) - 1]
    back = read_gltf(_write(doc, blob, tmp_path / "scaled.glb"))
    assert "Armature" not in back.skeleton.names
    p = motion.global_positions()
    expected = np.stack([p[..., 0] + 1.0, p[..., 2], -p[..., 1]], axis=-1)
    assert np.abs(back.global_positions() - expected).max() < 1e-5
    assert np.linalg.norm(back.skeleton.offsets[1:], axis=-1) == pytest.approx(
        np.linalg.norm(motion.skeleton.offsets[1:], axis=-1), abs=1e-6)


def test_a_rig_without_animation_reads_as_one_standing_frame(tmp_path):
    motion = standing_clip(frames=4)
    doc, blob = gltf_document(motion)
    doc.animations = []
    back = read_gltf(_write(doc, blob, tmp_path / "rig.glb"))
    assert back.num_frames == 1 and back.skeleton.names == motion.skeleton.names
    assert np.abs(back.global_positions()[0] - motion.global_positions()[0]).max() < 1e-6


def test_an_explicit_unit_rescales_the_file(tmp_path):
    motion = standing_clip(frames=4)
    back = read_gltf(write_gltf(motion, tmp_path / "w.glb"), unit="cm")
    assert np.allclose(back.global_positions(), motion.global_positions() * 0.01, atol=1e-8)
    assert back.metadata["file_unit"] == "cm"


def _sparse(doc, blob):
    doc.accessors[doc.animations[0].samplers[0].output].sparse = gl.Sparse(
        count=1, indices=gl.AccessorSparseIndices(bufferView=0, componentType=gl.UNSIGNED_SHORT),
        values=gl.AccessorSparseValues(bufferView=0))


def _integers(doc, blob):
    doc.accessors[doc.animations[0].samplers[0].output].componentType = gl.SHORT


def _no_skin_no_animation(doc, blob):
    doc.animations = []


def _truncated_view(doc, blob):
    return blob[:-64]


def _compressed(doc, blob):
    doc.extensionsRequired = ["EXT_meshopt_compression"]


def _missing_node(doc, blob):
    doc.animations[0].channels[0].target.node = 999


@pytest.mark.parametrize(("change", "words"), [
    (_sparse, ["sparse accessor", "re-export"]),
    (_integers, ["not normalized"]),
    (_no_skin_no_animation, ["no skin and no animation", "armature"]),
    (_truncated_view, ["past the end"]),
    (_missing_node, ["missing node"]),
    (_compressed, ["EXT_meshopt_compression", "without compression"]),
])
def test_a_file_it_cannot_read_gives_a_typed_one_line_error(tmp_path, change, words):
    doc, blob = _doc_with(standing_clip(frames=4), change)
    path = _write(doc, blob, tmp_path / "bad.glb")
    with pytest.raises(MotionFileError) as exc:
        read_motion(path)
    message = str(exc.value)
    assert message.startswith(str(path)) and "\n" not in message
    assert all(w in message for w in words), message


@pytest.mark.parametrize("content", [b"glTF\x02\x00\x00\x00garbage", b"", b'{"asset": ',
                                     b"not json at all"])
def test_corrupt_bytes_give_a_typed_error(tmp_path, content):
    for suffix in (".glb", ".gltf"):
        path = tmp_path / f"corrupt{suffix}"
        path.write_bytes(content)
        with pytest.raises(MotionFileError, match=r"corrupt|not a readable glTF"):
            read_gltf(path)


def test_missing_files_and_buffers_name_the_fix(tmp_path):
    with pytest.raises(MotionFileError, match="no such file"):
        read_gltf(tmp_path / "absent.glb")
    path = _external_bin(standing_clip(frames=4), tmp_path)
    (tmp_path / "walk data.bin").unlink()
    with pytest.raises(MotionFileError, match=r"walk data\.bin.*keep the \.bin beside"):
        read_gltf(path)
    doc, blob = gltf_document(standing_clip(frames=4))
    doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(
        blob).decode()[:-9] + "!!"
    path.write_text(doc.gltf_to_json())
    with pytest.raises(MotionFileError, match="invalid base64"):
        read_gltf(path)


@pytest.fixture(scope="module")
def blender_glb(generated, tmp_path_factory) -> Path:
    """The generated walk, as BVH in metres, imported by Blender and exported as GLB."""
    exe = shutil.which("blender")
    require_tool(exe is not None, "Blender is not installed (apt-get install blender)")
    folder = tmp_path_factory.mktemp("blender")
    bvh = write_bvh(generated, folder / "walk.bvh", unit="m")
    out = folder / "walk.glb"
    run = subprocess.run([exe, "-b", "--factory-startup", "--python-exit-code", "1",
                          "--python-expr", BVH_TO_GLB, "--", str(bvh), str(out)],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0 and out.is_file(), run.stdout[-2000:] + run.stderr[-2000:]
    return out


def test_blenders_glb_export_reads_back_within_a_millimetre(blender_glb, generated):
    back = read_motion(blender_glb)
    assert set(generated.skeleton.names) <= set(back.skeleton.names)
    assert back.fps == generated.fps and back.num_frames == generated.num_frames
    assert joint_error(back, generated) < MM


@pytest.mark.parametrize("change", [
    lambda d: d["nodes"][0].update(children=["Spine"]),
    lambda d: d["accessors"][0].update(count="many"),
    lambda d: d["nodes"][1].update(rotation=[0, 0, 1]),
    lambda d: d["animations"][0]["channels"][0].update(sampler=None),
    lambda d: d["nodes"][0].update(children=[1, 0]),
    lambda d: d["bufferViews"][0].update(byteOffset=-4),
])
def test_malformed_fields_give_a_typed_error(tmp_path, change):
    path = write_gltf(standing_clip(frames=4), tmp_path / "w.gltf")
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(MotionFileError, match=r"w\.gltf: .*(corrupt|not a readable glTF)"):
        read_gltf(path)
