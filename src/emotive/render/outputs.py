"""Files of any generated motion: BVH or glTF, NPZ and a stick-figure preview.

Files of any generated motion (:class:`~emotive.models.api.Generated`): BVH or glTF (``.glb``,
``.gltf``: a skinned mannequin on the model's rig, :mod:`emotive.io.gltf`), NPZ, and a
stick-figure preview captioned with the current emotion.

Every file is written at the motion's own frame rate, and the files of one call are all or
none (:func:`emotive.io.atomic.output_transaction`): each is written under a temporary name
and all are renamed into place only when the last is done, so when one of them fails (a full
disk while encoding the preview, say) every file that existed before is left as it was and no
new or temporary file is left.

NPZ keys: ``positions`` ``(T, J + E, 3)`` world positions of joints then end sites (metres, Y
up), ``names`` ``(J + E,)`` joint names then ``<parent>_end`` for end sites, ``parents``
``(J + E,)`` parent index of each point, ``emotion`` ``(T, C)`` weights, ``labels`` ``(C,)``,
``fps`` and ``path`` ``(P, 2)`` the ground path ``(x, z)`` (``(0, 2)`` for a motion that
followed none).

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``C`` labels, ``P`` path points.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from emotive.io.atomic import atomic_output, output_transaction
from emotive.io.motion_files import MOTION_SUFFIXES, write_motion
from emotive.io.outputs import PREVIEW_SUFFIXES, check_distinct, check_output
from emotive.render.preview import render_preview

if TYPE_CHECKING:
    from emotive.models.api import Generated

#: Suffixes of the main output: a motion file (BVH, glTF) or the NPZ.
OUT_SUFFIXES = (*MOTION_SUFFIXES, ".npz")


def captions(emotion: np.ndarray, labels: tuple[str, ...], top: int = 2) -> list[str]:
    """Per frame, the ``top`` heaviest labels with their weights.

    E.g. ``"angry 0.62 happy 0.38"`` (labels under 0.05 left out).

    Args:
        emotion: ``(T, C)`` weights.
        labels: the ``C`` labels.
        top: labels shown per frame.
    """
    out = []
    for row in emotion:
        order = np.argsort(-row)[:top]
        out.append(" ".join(f"{labels[k]} {row[k]:.2f}" for k in order if row[k] >= 0.05))
    return out


def write_npz(generated: Generated, out: Path) -> Path:
    """Write the NPZ described in the module docstring; returns ``out``."""
    motion = generated.motion
    sk = motion.skeleton
    names = [*sk.names, *(f"{sk.names[p]}_end" for p in sk.end_site_parents)]
    parents = np.concatenate((sk.parents, sk.end_site_parents))
    path = (generated.path.points if generated.path is not None else np.zeros((0, 2)))
    with atomic_output(out) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(
                fh, positions=motion.positions_with_end_sites().astype(np.float32),
                names=np.array(names), parents=parents,
                emotion=np.asarray(generated.emotion).astype(np.float32),
                labels=np.array(generated.labels), fps=np.float64(motion.fps),
                path=np.asarray(path, dtype=np.float32),
            )
    return out


def write_generated(generated: Generated, out: Path, npz: Path | None = None,
                    preview: Path | None = None, progress: bool = False) -> list[Path]:
    """Write a generated motion to ``out``, and optionally an NPZ and a preview.

    Write a generated motion to ``out`` (``.bvh``, ``.glb``, ``.gltf`` or ``.npz``), and
    optionally an NPZ and a preview.

    Args:
        generated: the model's output.
        out: the main file.
        npz: also write the NPZ here.
        preview: also write a stick-figure video here (``.mp4`` or ``.gif``).
        progress: show the preview's progress bar on stderr.

    Returns:
        The files written.

    Raises:
        OutputError: an output of the wrong kind, a folder's name, in a missing or unwritable
            folder or named twice (checked before any file is written), or a file that could
            not be written whole (then no file is changed).
    """
    check_output(out, OUT_SUFFIXES, "--out")
    if npz is not None:
        check_output(npz, (".npz",), "--npz")
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview")
    check_distinct([("--out", out), ("--npz", npz), ("--preview", preview)])
    with output_transaction() as outputs:
        if out.suffix.lower() in MOTION_SUFFIXES:
            write_motion(generated.motion, out)
        else:
            write_npz(generated, out)
        if npz is not None:
            write_npz(generated, npz)
        if preview is not None:
            path = generated.path
            render_preview(
                generated.motion, preview, path_xz=path.points if path is not None else None,
                captions=captions(np.asarray(generated.emotion), generated.labels),
                title=f"{out.name}: {path.name}" if path is not None else out.name,
                progress=progress,
            )
    return outputs.written
