"""One writer for motion files, choosing the format by the file's suffix.

``.bvh`` goes to :func:`emotive.io.bvh.write_bvh`; ``.glb`` and ``.gltf`` to
:func:`emotive.io.gltf.write_gltf` (a skinned mannequin included). Every command that writes a
motion calls :func:`write_motion`, and checks its ``--out`` against :data:`MOTION_SUFFIXES`.
"""

from __future__ import annotations

import os
from pathlib import Path

from emotive.core.motion import Motion
from emotive.errors import OutputError
from emotive.io.bvh import write_bvh
from emotive.io.gltf import GLTF_SUFFIXES, write_gltf

#: Suffixes :func:`write_motion` writes, BVH first.
MOTION_SUFFIXES = (".bvh", *GLTF_SUFFIXES)


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
