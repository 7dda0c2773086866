"""Files of any generated motion: BVH or glTF, NPZ and a stick-figure preview.

Files of any generated motion (:class:`~emotive.models.api.Generated`): BVH or glTF (``.glb``,
``.gltf``: a skinned mannequin on the model's rig, :mod:`emotive.io.gltf`), NPZ, and a
stick-figure preview captioned with the current emotion.

Every file is written at the motion's own frame rate and atomically
(:func:`emotive.io.atomic.atomic_output`), so an error never leaves a half-written file, and
the files of one command go through :func:`write_all`: when one of them fails (a full disk
while encoding the preview, say), the new files already written by the same command are
removed too, so a failed command leaves no output it made.

NPZ keys: ``positions`` ``(T, J + E, 3)`` world positions of joints then end sites (metres, Y
up), ``names`` ``(J + E,)`` joint names then ``<parent>_end`` for end sites, ``parents``
``(J + E,)`` parent index of each point, ``emotion`` ``(T, C)`` weights, ``labels`` ``(C,)``,
``fps`` and ``path`` ``(P, 2)`` the ground path ``(x, z)`` (``(0, 2)`` for a motion that
followed none).

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``C`` labels, ``P`` path points.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from emotive.io.atomic import atomic_output
from emotive.io.motion_files import MOTION_SUFFIXES, write_motion
from emotive.io.outputs import PREVIEW_SUFFIXES, check_output
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


def write_all(writers: Sequence[tuple[Path, Callable[[], object]]]) -> list[Path]:
    """Run each ``(path, write)`` in turn; if one fails, remove the new files of the others.

    A file that existed before is replaced by the new, complete version as soon as its writer
    is done, and kept; only files this call created are removed after a later failure.

    Args:
        writers: the output paths and the calls that write them (each atomically).

    Returns:
        The paths written, in order.

    Raises:
        OutputError: a file could not be written (the first writer's error, as it is).
    """
    existed = [Path(path).exists() for path, _ in writers]
    done: list[Path] = []
    try:
        for path, write in writers:
            write()
            done.append(Path(path))
    except BaseException:
        for path, old in zip(done, existed, strict=False):
            if not old:
                path.unlink(missing_ok=True)
        raise
    return done


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
        OutputError: an output of the wrong kind, a folder's name or in a missing or
            unwritable folder (checked before any file is written), or a file that could not
            be written whole (then none of the new files is left).
    """
    check_output(out, OUT_SUFFIXES, "--out")
    if npz is not None:
        check_output(npz, (".npz",), "--npz")
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview")
    if out.suffix.lower() in MOTION_SUFFIXES:
        writers = [(out, lambda: write_motion(generated.motion, out))]
    else:
        writers = [(out, lambda: write_npz(generated, out))]
    if npz is not None:
        writers.append((npz, lambda: write_npz(generated, npz)))
    if preview is not None:
        path = generated.path
        writers.append((preview, lambda: render_preview(
            generated.motion, preview, path_xz=path.points if path is not None else None,
            captions=captions(np.asarray(generated.emotion), generated.labels),
            title=f"{out.name}: {path.name}" if path is not None else out.name,
            progress=progress,
        )))
    return write_all(writers)
