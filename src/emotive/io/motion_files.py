"""One reader and one writer for motion files, choosing the format by the file's suffix.

Writing: ``.bvh`` goes to :func:`emotive.io.bvh.write_bvh`; ``.glb`` and ``.gltf`` to
:func:`emotive.io.gltf.write_gltf` (a skinned mannequin included). Every command that writes a
motion calls :func:`write_motion`, and checks its ``--out`` against :data:`MOTION_SUFFIXES`.

Reading: :func:`read_motion` reads ``.glb`` and ``.gltf`` (:func:`emotive.io.gltf_read.read_gltf`),
``.fbx`` through Blender (:func:`emotive.io.fbx.read_fbx`) and any other file as BVH
(:func:`emotive.io.bvh.read_bvh`, whose errors name the line): :data:`READ_SUFFIXES`.
"""

from __future__ import annotations

import os
from pathlib import Path

from emotive.core.motion import Motion
from emotive.errors import OutputError
from emotive.io.bvh import read_bvh, write_bvh
from emotive.io.fbx import FBX_SUFFIXES, read_fbx
from emotive.io.gltf import GLTF_SUFFIXES, write_gltf
from emotive.io.gltf_read import GLTF_READ_SUFFIXES, read_gltf

#: Suffixes :func:`write_motion` writes, BVH first.
MOTION_SUFFIXES = (".bvh", *GLTF_SUFFIXES)

#: Suffixes :func:`read_motion` reads, BVH first.
READ_SUFFIXES = (".bvh", *GLTF_READ_SUFFIXES, *FBX_SUFFIXES)


def read_motion(path: str | os.PathLike, unit: str = "auto") -> Motion:
    """Read a motion from a BVH, glTF or FBX file, by ``path``'s suffix.

    Args:
        path: a ``.glb``, ``.gltf`` or ``.fbx`` file; any other is read as BVH.
        unit: length unit of the file (see :func:`emotive.io.bvh.read_bvh`); ``"auto"`` detects
            a BVH file's unit from the figure's height and takes glTF's and FBX's metres.

    Returns:
        The clip, metres, Y up.

    Raises:
        BVHError: a BVH file (or one of another suffix) that cannot be read.
        MotionFileError: a glTF or FBX file that cannot be read (an FBX file without Blender
            installed included).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in GLTF_READ_SUFFIXES:
        return read_gltf(path, unit=unit)
    if suffix in FBX_SUFFIXES:
        return read_fbx(path, unit=unit)
    return read_bvh(path, unit=unit)


def write_motion(motion: Motion, path: str | os.PathLike, unit: str | None = None) -> Path:
    """Write a motion as BVH or glTF, by ``path``'s suffix, atomically.

    Args:
        motion: the clip (metres, Y up).
        path: a ``.bvh``, ``.glb`` or ``.gltf`` file.
        unit: length unit of a BVH file (see :func:`emotive.io.bvh.write_bvh`); glTF files are
            in metres by the format's definition, so it does not apply to them.

    Returns:
        ``path``.

    Raises:
        OutputError: an unknown suffix, or a file that could not be written whole.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return write_bvh(motion, path, unit=unit)
    if suffix in GLTF_SUFFIXES:
        return write_gltf(motion, path)
    raise OutputError(f"{path}: cannot write a motion as {suffix or 'a file without suffix'}; "
                      f"use a file ending in {' or '.join(MOTION_SUFFIXES)}")
