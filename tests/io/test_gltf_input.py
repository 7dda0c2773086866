"""glTF input: emotive's own files, hand-built documents, Blender's export, and bad files."""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import subprocess
import threading
import tracemalloc
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
    (_missing_node, ["channels[0].target.node", "nodes[999]", "not there"]),
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
    # In a folder of a long path, which the message must not cut before the buffer's name.
    deep = tmp_path / ("a-long-folder-name-" * 6) / "and-another"
    deep.mkdir(parents=True)
    path = _external_bin(standing_clip(frames=4), deep)
    (deep / "walk data.bin").unlink()
    with pytest.raises(MotionFileError, match=r"buffers\[0\]\.uri: .*'walk data\.bin'.*no such "
                       r"file.*keep the \.bin beside"):
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


# --- The input contract (emotive.io.input_limits): one test per refusal ---------------------


def walk_json(frames: int = 4) -> tuple[dict, bytes]:
    """The JSON object and buffer of a small walk, as emotive writes it (no mesh)."""
    doc, blob = gltf_document(standing_clip(frames=frames), mesh=False)
    return json.loads(doc.gltf_to_json(separators=(",", ":"))), blob


def refused(path: Path, *words: str) -> str:
    """The one-line message of reading ``path``, which must hold every one of ``words``."""
    with pytest.raises(MotionFileError) as exc:
        read_gltf(path)
    message = str(exc.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    assert all(w in message for w in words), message
    return message


@pytest.fixture
def sandbox(tmp_path) -> tuple[Path, Path, dict, bytes]:
    """``(case folder, folder beside it, JSON, buffer)``; beside the case folder lies
    ``outside.bin``, a valid buffer for the JSON: a reader that left its folder would read it."""
    root, blob = walk_json()
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "outside.bin").write_bytes(blob)
    case = tmp_path / "case"
    case.mkdir()
    return case, outside, root, blob


def _gltf(case: Path, root: dict, uri: str) -> Path:
    root = json.loads(json.dumps(root))
    root["buffers"][0]["uri"] = uri
    path = case / "walk.gltf"
    path.write_text(json.dumps(root))
    return path


@pytest.mark.parametrize(("uri", "words"), [
    ("../outside/outside.bin", "leads outside the document's folder"),
    ("sub/../../outside/outside.bin", "leads outside the document's folder"),
    ("%2E%2E/outside/outside.bin", "leads outside the document's folder"),
    ("..%2Foutside%2Foutside.bin", "leads outside the document's folder"),
    ("{outside}/outside.bin", "is an absolute path"),
    ("%2F{outside_rel}/outside.bin", "is an absolute path"),
    ("/etc/passwd", "is an absolute path"),
    ("file://{outside}/outside.bin", "is a URL"),
    ("http://127.0.0.1:9/outside.bin", "nothing is fetched"),
])
def test_a_buffer_uri_leading_out_of_the_folder_is_refused(sandbox, uri, words):
    case, outside, root, _ = sandbox
    uri = uri.format(outside=outside, outside_rel=str(outside).lstrip("/"))
    refused(_gltf(case, root, uri), "buffers[0].uri: ", words, "keep the file it names")


@pytest.mark.parametrize(("name", "target", "uri"), [
    ("link.bin", "../outside/outside.bin", "link.bin"),
    ("zero.bin", "/dev/zero", "zero.bin"),
    ("environ.bin", "/proc/self/environ", "environ.bin"),
    ("inner", "../outside", "inner/outside.bin"),
])
def test_a_symbolic_link_leading_out_of_the_folder_is_refused(sandbox, name, target, uri):
    case, _, root, _ = sandbox
    os.symlink(target, case / name)
    refused(_gltf(case, root, uri), "buffers[0].uri: ", "leads outside the document's folder")


def test_a_bin_in_a_folder_below_is_read_and_a_data_uri_too(sandbox, tmp_path):
    case, _, root, blob = sandbox
    (case / "data").mkdir()
    (case / "data" / "walk data.bin").write_bytes(blob)
    assert read_gltf(_gltf(case, root, "data/walk%20data.bin")).num_frames == 4
    uri = "data:application/gltf-buffer;base64," + base64.b64encode(blob).decode()
    assert read_gltf(_gltf(case, root, uri)).num_frames == 4


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes need POSIX")
@pytest.mark.parametrize("which", ["buffer", "document"])
def test_a_named_pipe_is_refused_at_once(sandbox, which):
    case, _, root, _ = sandbox
    os.mkfifo(case / "pipe.bin")
    path = _gltf(case, root, "pipe.bin")
    if which == "document":
        path.unlink()
        os.mkfifo(path)
    result: list[BaseException | None] = []

    def read() -> None:
        try:
            read_gltf(path)
        except BaseException as exc:
            result.append(exc)
        else:
            result.append(None)

    worker = threading.Thread(target=read, daemon=True)
    worker.start()
    worker.join(30.0)  # a hang detector, far above the milliseconds a refusal takes
    if worker.is_alive():
        for fifo in (case / "pipe.bin", path):  # unblock the reader, then fail
            with contextlib.suppress(OSError):
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail("read_gltf blocked on a named pipe")
    assert isinstance(result[0], MotionFileError), result
    assert "not a regular file" in str(result[0])
    if which == "buffer":
        assert "buffers[0].uri" in str(result[0])


@pytest.mark.parametrize(("path", "words"), [("/dev/zero", "not a regular file"),
                                             ("/proc/self/environ", "is a system file")])
def test_a_device_or_kernel_file_is_refused_before_it_is_read(path, words):
    if not Path(path).exists():
        pytest.skip(f"no {path}")
    refused(Path(path), words)


def test_a_folder_in_place_of_a_buffer_is_refused(sandbox):
    case, _, root, _ = sandbox
    (case / "folder.bin").mkdir()
    refused(_gltf(case, root, "folder.bin"), "buffers[0].uri", "is a folder")


def glb_file(tmp_path: Path, root: dict, blob: bytes, name: str = "walk.glb") -> Path:
    from gltf_mutants import glb_bytes

    path = tmp_path / name
    path.write_bytes(glb_bytes(root, blob))
    return path


def test_a_huge_count_is_refused_before_any_array_is_made(tmp_path):
    root, blob = walk_json()
    translation = root["animations"][0]["samplers"][-1]["output"]
    del root["accessors"][translation]["bufferView"]  # read as zeros: nothing bounds count
    root["accessors"][translation]["count"] = 10**9
    path = glb_file(tmp_path, root, blob)
    tracemalloc.start()
    try:
        refused(path, f"accessors[{translation}].count", "at most 20,000,000")
        assert tracemalloc.get_traced_memory()[1] < 20 * 2**20
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize(("array", "key", "value", "element"), [
    ("accessors", "byteOffset", 2**40, "accessors[0].byteOffset"),
    ("accessors", "byteOffset", 1000, "accessors[0]: reads past the end of bufferViews[0]"),
    ("accessors", "count", -1, "accessors[0].count"),
    ("accessors", "count", "5", "accessors[0].count"),
    ("bufferViews", "byteOffset", 10**6, "bufferViews[0]: reads past the end of buffers[0]"),
    ("bufferViews", "byteLength", 2**62, "bufferViews[0].byteLength"),
    ("bufferViews", "byteStride", 2, "bufferViews[0].byteStride"),
    ("bufferViews", "byteStride", 256, "bufferViews[0].byteStride"),
    ("buffers", "byteLength", 10**8, "buffers[0].byteLength"),
])
def test_every_size_is_checked_against_the_data_there(tmp_path, array, key, value, element):
    root, blob = walk_json()
    root[array][0][key] = value
    refused(glb_file(tmp_path, root, blob), element)


@pytest.mark.parametrize(("key", "value", "words"), [
    ("matrix", [float("nan")] * 16, "nodes[1].matrix: holds a number that is not finite"),
    ("matrix", [1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
     "nodes[1].matrix: is not an affine transform"),
    ("translation", [float("inf"), 0, 0], "nodes[1].translation: holds a number that is not"),
    ("translation", [3e38, 0, 0], "nodes[1]: joint offsets reach 3e+38 m: at most 1000 m"),
    ("rotation", [0, 0, 0, 0], "nodes[1].rotation: is a zero quaternion"),
])
def test_node_transforms_must_be_finite_and_plausible(tmp_path, key, value, words):
    root, blob = walk_json()
    node = root["nodes"][1]  # the spine: the hips' rest offset carries the walk's start
    for other in ("translation", "rotation", "scale", "matrix"):
        node.pop(other, None)
    node[key] = value
    # json.dumps writes NaN and Infinity as the bare words other writers use too.
    path = tmp_path / "walk.gltf"
    root["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                 + base64.b64encode(blob).decode())
    path.write_text(json.dumps(root))
    refused(path, words)


@pytest.mark.parametrize(("value", "words"), [
    (3e38, "nodes[0]: joint translations reach 3e+38 m: at most 1000 m"),
    (float("nan"), "holds values that are not finite"),
])
def test_an_animation_sample_must_be_finite_and_plausible(tmp_path, value, words):
    root, blob = walk_json()
    output = root["accessors"][root["animations"][0]["samplers"][-1]["output"]]
    assert output["type"] == "VEC3"  # the hips' translation track
    at = root["bufferViews"][output["bufferView"]]["byteOffset"] + 12 * 2
    data = bytearray(blob)
    data[at:at + 4] = np.array([value], dtype="<f4").tobytes()
    refused(glb_file(tmp_path, root, bytes(data)), words)


def test_the_moving_nodes_and_their_values_are_bounded(tmp_path, monkeypatch):
    from emotive.io import input_limits as limits

    doc, blob = gltf_document(standing_clip(frames=4), mesh=True)
    root = json.loads(doc.gltf_to_json())
    # An armature node above the skin's joints that turns too: 20 moving nodes, 19 joints.
    root["nodes"].append({"name": "Armature", "children": [0]})
    root["scenes"][0]["nodes"] = [len(root["nodes"]) - 1, 19]
    root["animations"][0]["channels"].append(
        {"sampler": 0, "target": {"node": len(root["nodes"]) - 1, "path": "rotation"}})
    path = glb_file(tmp_path, root, blob)
    monkeypatch.setattr(limits, "MAX_MOVING_NODES", 3)
    refused(path, "animations[0]: moves 20 nodes that place the joints: at most 3 are read")
    monkeypatch.setattr(limits, "MAX_MOVING_NODES", 20)
    monkeypatch.setattr(limits, "MAX_VALUES", 4 * 19 * 6)  # the joints' values fit
    refused(path, "4 frames x 20 moving nodes x 6 = 480 values: at most 456")
    monkeypatch.setattr(limits, "MAX_VALUES", 4 * 20 * 6)
    assert read_gltf(path).num_frames == 4
