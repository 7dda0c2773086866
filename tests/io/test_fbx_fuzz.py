"""The FBX path under hostile input: non-regular, empty and oversize files are refused before
Blender starts; Blender never opens a texture the FBX names (a FIFO beside the case folder
would hang it); what Blender makes is held to the glTF reader's limits; every case is read
plausibly or refused with a one-line MotionFileError naming the FBX file."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from bvh_mutants import base_motion

from emotive.errors import MotionFileError
from emotive.io import fbx
from emotive.io import input_limits as limits
from emotive.io.bvh import write_bvh
from emotive.io.fbx import read_fbx
from tools import bvh_to_fbx, require_tool

#: A conversion still running after this many seconds has hung (each takes a few seconds of
#: processor time; a heavily loaded machine stretches Blender's start-up to a minute or more).
HANG_S = 600

#: Run inside Blender: import a BVH, add a plane whose material shows an image texture saved
#: at a given path, export FBX naming the image by a path relative to the FBX and an absolute
#: one (``-- IN.bvh OUT.fbx IMAGE.png``).
TEXTURED = """
import builtins, sys, bpy
_open = builtins.open
builtins.open = lambda f, mode="r", *a, **k: _open(f, mode.replace("U", ""), *a, **k)
src, dst, png = sys.argv[sys.argv.index("--") + 1:][:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=src, update_scene_fps=True, update_scene_duration=True)
image = bpy.data.images.new("skin", 4, 4)
image.filepath_raw, image.file_format = png, "PNG"
image.save()
bpy.ops.mesh.primitive_plane_add()
material = bpy.data.materials.new("skin")
material.use_nodes = True
texture = material.node_tree.nodes.new("ShaderNodeTexImage")
texture.image = image
material.node_tree.links.new(texture.outputs["Color"],
                             material.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
bpy.context.active_object.data.materials.append(material)
bpy.ops.export_scene.fbx(filepath=dst, bake_anim=True, path_mode="RELATIVE",
                         embed_textures=False)
"""


class FifoWatch:
    """Whether anything opens a FIFO for reading: a thread waits to open it for writing,
    which returns only once a reader has opened it (then the reader gets end-of-file)."""

    def __init__(self, fifo: Path) -> None:
        self.fifo, self.opened, self._stop = fifo, 0, False
        self._thread = threading.Thread(target=self._wait, daemon=True)
        self._thread.start()

    def _wait(self) -> None:
        while True:
            with open(self.fifo, "wb"):
                if self._stop:
                    return
                self.opened += 1

    def stop(self) -> None:
        self._stop = True
        # Our own reader releases the waiting writer.
        fd = os.open(self.fifo, os.O_RDONLY | os.O_NONBLOCK)
        self._thread.join(10)
        os.close(fd)


@pytest.fixture(scope="module")
def blender() -> str:
    exe = shutil.which("blender")
    require_tool(exe is not None, "Blender is not installed (apt-get install blender)")
    return exe


def _files(blender: str, root: Path) -> dict[str, Path]:
    """The base FBX, one naming a texture beside its folder, one whose root is 1,000 km out."""
    made = root / "made"
    made.mkdir()
    motion = base_motion()
    base = made / "walk.fbx"
    bvh_to_fbx(blender, write_bvh(motion, made / "walk.bvh", unit="m"), base)
    far = motion.replace(positions=motion.positions + np.array([1e6, 0.0, 0.0]))
    bvh_to_fbx(blender, write_bvh(far, made / "far.bvh", unit="m"), made / "far.fbx")
    (root / "outside").mkdir()
    (root / "case").mkdir()
    png = root / "outside" / "skin.png"
    textured = root / "case" / "textured.fbx"
    run = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1",
                          "--python-expr", TEXTURED, "--", str(made / "walk.bvh"),
                          str(textured), str(png)],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0 and textured.is_file(), run.stdout[-2000:] + run.stderr[-2000:]
    assert b"../outside/skin.png" in textured.read_bytes()
    png.unlink()
    os.mkfifo(png)  # what the texture names now hangs whoever opens it
    return {"base": base, "far": made / "far.fbx", "textured": textured}


def _flip(data: bytes, rng: np.random.Generator, count: int) -> bytes:
    out = bytearray(data)
    for at in rng.integers(27, len(out), count):
        out[at] = int(rng.integers(0, 256))
    return bytes(out)


def _cases(files: dict[str, Path], folder: Path) -> list[tuple[str, Path, str]]:
    """``(name, path, expectation)``.

    The expectation is ``"read"``, ``"any"``, ``"refused"``, ``"refused: words"`` (a refusal
    holding those words) or ``"before: words"`` (one before Blender starts).
    """
    folder.mkdir()
    good = files["base"].read_bytes()
    rng = np.random.default_rng(2406)
    out: list[tuple[str, Path, str]] = [
        ("base", files["base"], "read"), ("textured", files["textured"], "read"),
        ("far", files["far"], "refused: reach 1e+06 m")]

    def put(name: str, data: bytes, expect: str) -> None:
        (folder / f"{name}.fbx").write_bytes(data)
        out.append((name, folder / f"{name}.fbx", expect))

    for k in range(4):
        put(f"flip_{k}", _flip(good, rng, 1 + 3 * k), "any")
    for k, keep in enumerate((len(good) // 3, len(good) - 100)):
        put(f"cut_{k}", good[:keep], "refused")
    put("ascii", b"; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n}\n", "refused")
    put("old_version", good[:23] + (7000).to_bytes(4, "little") + good[27:], "refused")
    put("magic_then_junk", good[:27] + bytes(rng.integers(0, 256, 4000, dtype=np.uint8)),
        "refused")
    links = {"dev_zero": "/dev/zero", "environ": "/proc/self/environ", "dangling": "absent",
             "outside_fifo": str(files["textured"].parent.parent / "outside" / "skin.png")}
    for name, target in links.items():
        os.symlink(target, folder / f"{name}.fbx")
        words = {"dangling": "no such file", "environ": "system file"}.get(
            name, "not a regular file")
        out.append((name, folder / f"{name}.fbx", f"before: {words}"))
    os.mkfifo(folder / "fifo.fbx")
    (folder / "folder.fbx").mkdir()
    (folder / "empty.fbx").write_bytes(b"")
    with open(folder / "huge.fbx", "wb") as fh:  # sparse: nothing is written
        fh.write(good[:64])
        fh.truncate(limits.MAX_FILE_BYTES + 1)
    out += [("fifo", folder / "fifo.fbx", "before: not a regular file"),
            ("folder", folder / "folder.fbx", "before: is a folder"),
            ("empty", folder / "empty.fbx", "before: is empty"),
            ("huge", folder / "huge.fbx", "before: at most 1,073,741,824 are read")]
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(folder / "socket.fbx"))
    sock.close()
    out.append(("socket", folder / "socket.fbx", "before: not a regular file"))
    return out


@pytest.fixture(scope="module")
def fuzz(blender, tmp_path_factory):
    """``(cases, result by name, Blender runs by name, opens of the outside FIFO)``."""
    root = tmp_path_factory.mktemp("fbx_fuzz")
    files = _files(blender, root)
    cases = _cases(files, root / "cases")
    watch = FifoWatch(root / "outside" / "skin.png")
    launches: list[str] = []
    results, runs = {}, {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(fbx, "TIMEOUT_S", HANG_S)
        mp.setattr(fbx.subprocess, "run",
                   lambda *a, **k: launches.append(1) or measured_run(*a, **k))
        for name, path, _ in cases:
            before = len(launches)
            try:
                motion = read_fbx(path)
            except MotionFileError as exc:
                results[name] = ("refused", str(exc), None)
            except Exception as exc:  # what the fuzz counts: never another type
                results[name] = ("crash", f"{type(exc).__name__}: {exc}", None)
            else:
                results[name] = ("read", "", motion)
            runs[name] = len(launches) - before
    watch.stop()
    return cases, results, runs, watch.opened


#: Peak resident bytes of each Blender run of the fuzz, from its own rusage.
BLENDER_PEAKS: list[int] = []


def measured_run(cmd: list[str], *, timeout: float | None = None, check: bool = False,
                 **kwargs) -> subprocess.CompletedProcess:
    """``subprocess.run`` for the fuzz's Blender runs that also keeps each run's peak memory.

    The child is reaped with ``os.wait4``, which gives that child's own rusage: the test
    process's ``RUSAGE_CHILDREN`` mixes in every process it ever waited for (other tests'
    commands and browsers run in the same worker). A timer kills it at ``timeout``.
    """
    proc = subprocess.Popen(cmd, **kwargs)
    killed = threading.Event()

    def kill() -> None:
        killed.set()
        proc.kill()

    timer = threading.Timer(timeout, kill) if timeout else None
    if timer is not None:
        timer.start()
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        if timer is not None:
            timer.cancel()
    proc.returncode = os.waitstatus_to_exitcode(status)
    BLENDER_PEAKS.append(usage.ru_maxrss * 1024)
    if killed.is_set():
        raise subprocess.TimeoutExpired(cmd, timeout)
    if check and proc.returncode:
        raise subprocess.CalledProcessError(proc.returncode, cmd)
    return subprocess.CompletedProcess(cmd, proc.returncode)


def test_every_case_is_read_or_refused_in_one_typed_line(fuzz):
    cases, results, _, _ = fuzz
    assert len(cases) >= 20
    assert [f"{n}: {m}" for n, (o, m, _) in results.items() if o == "crash"] == []
    for name, path, expect in cases:
        outcome, message, motion = results[name]
        assert "did not convert it within" not in message, (name, "hung")
        if outcome == "refused":
            assert message.startswith(f"{path}: ") and "\n" not in message, (name, message)
            assert "emotive-fbx-" not in message, (name, message)
        if expect == "read" or outcome == "read":
            assert outcome == "read", (name, message)
            assert motion.num_frames == 5 and motion.metadata["source"] == str(path)
            assert np.abs(motion.positions).max() <= limits.MAX_LENGTH_M
        elif expect != "any":
            assert outcome == "refused", (name, outcome)
            words = expect.partition(": ")[2]
            assert words in message, (name, message)


def test_files_that_are_not_regular_small_files_never_reach_blender(fuzz):
    cases, _, runs, _ = fuzz
    before = [n for n, _, e in cases if e.startswith("before: ")]
    assert len(before) >= 9
    assert {n: runs[n] for n in before} == dict.fromkeys(before, 0)
    assert all(runs[n] == 1 for n, _, e in cases if not e.startswith("before: "))


def test_blender_opens_no_texture_the_fbx_names(fuzz):
    _, results, _, opened = fuzz
    assert results["textured"][0] == "read"
    assert opened == 0


def test_what_blender_makes_is_held_to_the_gltf_limits(fuzz):
    _, results, _, _ = fuzz
    outcome, message, _ = results["far"]
    assert outcome == "refused" and "Blender's conversion of it is refused" in message
    assert "at most 1000 m" in message


def test_blender_stays_within_its_memory_limit(fuzz):
    # Each of Blender's runs on the damaged files, measured on its own (one took 23 GB
    # before Blender had a limit).
    assert len(BLENDER_PEAKS) >= 10
    peak = max(BLENDER_PEAKS)
    assert 0 < peak <= fbx.MEMORY_LIMIT_BYTES, f"{peak / 2**30:.1f} GiB"
