"""FBX input through Blender: the file is converted to a temporary GLB and read as glTF.

FBX is a closed format without a well-kept Python reader; Blender's importer is the reference
free one. :func:`read_fbx` runs Blender headless (``blender -b``) once per file: it imports the
FBX into an empty scene (Blender's FBX importer applies the file's axes and unit scale, and
sets the scene's frame rate from the file), exports the scene as a GLB with its armature and
every animation frame sampled (Y up, metres), and :func:`emotive.io.gltf_read.read_gltf` reads
that. Leaf bones that FBX exporters add at the end of each chain (``Head_end``) come through
as joints.

The input contract of :mod:`emotive.io.input_limits` holds on both sides of Blender. Before
Blender starts, the file must be a regular, non-empty file of at most ``MAX_FILE_BYTES``
(:func:`~emotive.io.input_limits.open_regular`: a pipe, device or folder is refused at once)
and is copied, from the descriptor that was checked, into a private folder that Blender reads
from, so what Blender imports is what was checked and a reference the FBX makes to a file
beside it finds nothing. Inside Blender no image file the FBX names is opened (a texture
makes no skeleton; ``/etc/passwd`` as a texture's ``FileName`` is never read), and images
are not searched for. What comes back is a GLB that
:func:`~emotive.io.gltf_read.read_gltf` reads within the same limits as any glTF file; its
refusals name the FBX file. Blender's output is kept in a file and only its last lines read.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import tempfile
from pathlib import Path

from emotive.core.motion import Motion
from emotive.errors import MotionFileError
from emotive.io.gltf_read import read_gltf
from emotive.io.input_limits import InputFile, open_regular

#: Suffixes of the FBX files :func:`read_fbx` reads.
FBX_SUFFIXES = (".fbx",)

#: Longest a conversion may take, seconds (Blender starts in seconds; a huge scene takes more).
TIMEOUT_S = 600

#: Address space Blender may take, bytes: it starts in under 2 GiB, and a damaged FBX whose
#: counts Blender's importer believes took 23 GB of memory without this limit.
MEMORY_LIMIT_BYTES = 4 << 30

#: Most bytes of Blender's output read for its last message.
LOG_TAIL_BYTES = 1 << 16

#: Bytes copied at a time into the private folder.
_COPY_BYTES = 1 << 24

#: The conversion, run inside Blender: ``-- INPUT.fbx OUTPUT.glb``.
CONVERT = """
import sys
import bpy
import numpy
# Blender 3.4's glTF add-on uses np.bool, which NumPy 1.24-1.26 do not have.
if not hasattr(numpy, "bool"):
    numpy.bool = numpy.bool_
from bpy_extras import image_utils
src, dst = sys.argv[sys.argv.index("--") + 1:][:2]


def no_image_file(imagepath, *args, **kwargs):
    # A texture makes no skeleton: no image file the FBX names is opened or searched for.
    return bpy.data.images.new("texture", 1, 1)


image_utils.load_image = no_image_file
try:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=src, use_image_search=False)
    if not any(o.type == "ARMATURE" for o in bpy.context.scene.objects):
        raise ValueError("the file has no armature (skeleton) to read")
    bpy.ops.export_scene.gltf(filepath=dst, export_format="GLB", export_animations=True,
                              export_force_sampling=True, export_yup=True, export_skins=True,
                              export_materials="NONE")
except Exception as exc:
    lines = [ln for ln in str(exc).splitlines() if ln.strip()] or [type(exc).__name__]
    print("EMOTIVE_FBX_ERROR " + lines[-1].removeprefix("Error: ").strip())
    sys.exit(3)
"""


def read_fbx(path: str | os.PathLike, unit: str = "auto", fps: float | None = None) -> Motion:
    """Read the skeleton and first animation of an FBX file, through Blender.

    Args:
        path: a binary ``.fbx`` file (Blender imports FBX 7.1 and later, not ASCII FBX).
        unit: as in :func:`emotive.io.gltf_read.read_gltf` (Blender already converts the
            file's own unit to metres; ``"auto"`` keeps that).
        fps: frame rate to resample at; ``None`` keeps the file's.

    Returns:
        The motion (metres, Y up), ``metadata`` naming the FBX file as ``source``.

    Raises:
        MotionFileError: the file is missing, not a regular file, empty or over
            ``MAX_FILE_BYTES`` (all refused before Blender starts), Blender is not
            installed, cannot import it or finds no armature, or the converted file is
            refused by the glTF reader's limits.
    """
    path = Path(path)

    def fail(problem: str) -> MotionFileError:
        return MotionFileError(path, problem)

    with open_regular(path, fail) as source:
        if source.size == 0:
            raise fail("is empty; export the FBX file again")
        exe = shutil.which("blender")
        if exe is None:
            raise fail("reading FBX needs Blender, which is not on PATH; install Blender "
                       "(apt-get install blender, or blender.org), or export the file as .glb")
        with tempfile.TemporaryDirectory(prefix="emotive-fbx-") as tmp:
            copy = Path(tmp) / f"input{path.suffix.lower() or '.fbx'}"
            _copy(source, copy)
            motion = _convert(path, exe, copy, Path(tmp), unit, fps)
    return motion.replace(metadata={**motion.metadata, "source": str(path), "name": path.stem})


def _copy(source: InputFile, copy: Path) -> None:
    """Write the checked file's bytes (as long as it was when opened) to ``copy``."""
    with open(copy, "wb") as out:
        for start in range(0, source.size, _COPY_BYTES):
            out.write(source.read_at(start, min(_COPY_BYTES, source.size - start)))


def _convert(path: Path, exe: str, copy: Path, folder: Path, unit: str,
             fps: float | None) -> Motion:
    """Run Blender on ``copy`` and read the GLB it writes into ``folder``."""
    out = folder / "converted.glb"
    log = folder / "blender.log"
    with open(log, "wb") as sink:
        try:
            run = subprocess.run(
                [exe, "-b", "--factory-startup", "--python-exit-code", "2",
                 "--python-expr", CONVERT, "--", str(copy), str(out)],
                stdin=subprocess.DEVNULL, stdout=sink, stderr=subprocess.STDOUT,
                timeout=TIMEOUT_S, check=False, cwd=folder, preexec_fn=_limit_memory)
        except subprocess.TimeoutExpired:
            raise MotionFileError(path, f"Blender did not convert it within {TIMEOUT_S} s; "
                                  "export it as .glb from your tool instead") from None
    if run.returncode != 0 or not out.is_file():
        raise MotionFileError(path, f"Blender could not read a skeleton from it "
                              f"({_reason(log, run.returncode, copy, path)}); export it from your "
                              "tool as binary FBX with its armature, or as .glb")
    try:
        return read_gltf(out, unit=unit, fps=fps)
    except MotionFileError as exc:
        raise MotionFileError(path, f"Blender's conversion of it is refused: {exc.problem}") \
            from None


def _limit_memory() -> None:
    """In Blender's process, before it starts: at most :data:`MEMORY_LIMIT_BYTES`."""
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT_BYTES, MEMORY_LIMIT_BYTES))


def _reason(log: Path, code: int, copy: Path, path: Path) -> str:
    """The last meaningful line Blender printed (its output's last ``LOG_TAIL_BYTES``).

    The private copy's path in it is replaced by the file's own.
    """
    with open(log, "rb") as fh:
        fh.seek(max(0, os.fstat(fh.fileno()).st_size - LOG_TAIL_BYTES))
        text = fh.read().decode("utf-8", errors="replace")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    marked = [ln.removeprefix("EMOTIVE_FBX_ERROR ") for ln in lines
              if ln.startswith("EMOTIVE_FBX_ERROR ")]
    return (marked or lines or [f"exit code {code}"])[-1].replace(str(copy), str(path))[:300]
