"""FBX input through Blender: the file is converted to a temporary GLB and read as glTF.

FBX is a closed format without a well-kept Python reader; Blender's importer is the reference
free one. :func:`read_fbx` runs Blender headless (``blender -b``) once per file: it imports the
FBX into an empty scene (Blender's FBX importer applies the file's axes and unit scale, and
sets the scene's frame rate from the file), exports the scene as a GLB with its armature and
every animation frame sampled (Y up, metres), and :func:`emotive.io.gltf_read.read_gltf` reads
that. Leaf bones that FBX exporters add at the end of each chain (``Head_end``) come through
as joints.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from emotive.core.motion import Motion
from emotive.errors import MotionFileError
from emotive.io.gltf_read import read_gltf

#: Suffixes of the FBX files :func:`read_fbx` reads.
FBX_SUFFIXES = (".fbx",)

#: Longest a conversion may take, seconds (Blender starts in seconds; a huge scene takes more).
TIMEOUT_S = 600

#: The conversion, run inside Blender: ``-- INPUT.fbx OUTPUT.glb``.
CONVERT = """
import sys
import bpy
import numpy
# Blender 3.4's glTF add-on uses np.bool, which NumPy 1.24-1.26 do not have.
if not hasattr(numpy, "bool"):
    numpy.bool = numpy.bool_
src, dst = sys.argv[sys.argv.index("--") + 1:][:2]
try:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=src)
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
        MotionFileError: Blender is not installed, the file is missing or Blender cannot
            import it, it has no armature, or the converted file cannot be read.
    """
    path = Path(path)
    if not path.is_file():
        raise MotionFileError(path, "no such file; check the path")
    exe = shutil.which("blender")
    if exe is None:
        raise MotionFileError(path, "reading FBX needs Blender, which is not on PATH; install "
                              "Blender (apt-get install blender, or blender.org), or export the "
                              "file as .glb")
    with tempfile.TemporaryDirectory(prefix="emotive-fbx-") as tmp:
        out = Path(tmp) / f"{path.stem}.glb"
        try:
            run = subprocess.run(
                [exe, "-b", "--factory-startup", "--python-exit-code", "2",
                 "--python-expr", CONVERT, "--", str(path.resolve()), str(out)],
                capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
        except subprocess.TimeoutExpired:
            raise MotionFileError(path, f"Blender did not convert it within {TIMEOUT_S} s; "
                                  "export it as .glb from your tool instead") from None
        if run.returncode != 0 or not out.is_file():
            raise MotionFileError(path, f"Blender could not read a skeleton from it "
                                  f"({_reason(run)}); export it from your tool as binary FBX "
                                  "with its armature, or as .glb")
        motion = read_gltf(out, unit=unit, fps=fps)
    return motion.replace(metadata={**motion.metadata, "source": str(path)})


def _reason(run: subprocess.CompletedProcess) -> str:
    """The last meaningful line Blender printed."""
    lines = [ln.strip() for ln in (run.stdout + run.stderr).splitlines() if ln.strip()]
    marked = [ln.removeprefix("EMOTIVE_FBX_ERROR ") for ln in lines
              if ln.startswith("EMOTIVE_FBX_ERROR ")]
    return (marked or lines or [f"exit code {run.returncode}"])[-1][:300]
