"""Files of a generated walk: BVH on the training rig, NPZ, and a stick-figure preview.

Every file is written at :data:`OUTPUT_FPS` whatever rate the network runs at (the motion is
resampled with :func:`emotive.core.ops.resample`, the emotion interpolated linearly), and
atomically (:func:`emotive.io.atomic.atomic_output`), so an error never leaves a half-written
file.

NPZ keys: ``positions`` ``(T, J + E, 3)`` world positions of joints then end sites (metres, Y
up), ``names`` ``(J + E,)`` joint names then ``<parent>_end`` for end sites, ``parents``
``(J + E,)`` parent index of each point, ``emotion`` ``(T, C)`` weights, ``labels`` ``(C,)``,
``fps`` and ``path`` ``(P, 2)`` the ground path ``(x, z)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.errors import OutputError
from emotive.models.gait.generate import GeneratedWalk

#: Frame rate of every file written, frames per second (the data's).
OUTPUT_FPS = 30.0


def check_output(path: Path, suffixes: tuple[str, ...], option: str) -> None:
    """Fail early on an output of the wrong kind or in a missing folder.

    Raises:
        OutputError: naming the option, the file and the fix.
    """
    if path.suffix.lower() not in suffixes:
        raise OutputError(f"{option} {path}: use a file ending in {' or '.join(suffixes)}")
    if not path.parent.is_dir():
        raise OutputError(f"{option} {path}: folder {path.parent} does not exist; create it first")


def at_output_rate(walk: GeneratedWalk) -> tuple[Motion, np.ndarray]:
    """The walk's motion and ``(T, C)`` emotion at :data:`OUTPUT_FPS`."""
    from emotive.core.ops import resample

    motion = walk.motion
    if abs(motion.fps - OUTPUT_FPS) < 1e-9:
        return motion, walk.emotion
    out = resample(motion, OUTPUT_FPS)
    src = np.arange(motion.num_frames) / motion.fps
    dst = np.arange(out.num_frames) / OUTPUT_FPS
    emotion = np.stack([np.interp(dst, src, walk.emotion[:, c])
                        for c in range(walk.emotion.shape[1])], 1)
    return out, emotion / emotion.sum(1, keepdims=True)


def captions(emotion: np.ndarray, labels: tuple[str, ...], top: int = 2) -> list[str]:
    """Per frame, the ``top`` heaviest labels with their weights, e.g. ``"angry 0.62 happy
    0.38"`` (labels under 0.05 left out)."""
    out = []
    for row in emotion:
        order = np.argsort(-row)[:top]
        out.append(" ".join(f"{labels[k]} {row[k]:.2f}" for k in order if row[k] >= 0.05))
    return out


def write_npz(motion: Motion, emotion: np.ndarray, labels: tuple[str, ...], path_xz: np.ndarray,
              out: Path) -> Path:
    """Write the NPZ described in the module docstring; returns ``out``."""
    from emotive.io.atomic import atomic_output

    sk = motion.skeleton
    names = [*sk.names, *(f"{sk.names[p]}_end" for p in sk.end_site_parents)]
    parents = np.concatenate((sk.parents, sk.end_site_parents))
    with atomic_output(out) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(
                fh, positions=motion.positions_with_end_sites().astype(np.float32),
                names=np.array(names), parents=parents, emotion=emotion.astype(np.float32),
                labels=np.array(labels), fps=np.float64(motion.fps),
                path=np.asarray(path_xz, dtype=np.float32),
            )
    return out


def write_walk(walk: GeneratedWalk, out: Path, npz: Path | None = None,
               preview: Path | None = None, progress: bool = False) -> list[Path]:
    """Write a walk to ``out`` (``.bvh`` or ``.npz``), and optionally an NPZ and a preview.

    Returns:
        The files written.

    Raises:
        OutputError: an output of the wrong kind or in a missing folder (checked before any
            file is written).
    """
    from emotive.io.bvh import write_bvh
    from emotive.render.preview import render_preview

    check_output(out, (".bvh", ".npz"), "out")
    if npz is not None:
        check_output(npz, (".npz",), "npz")
    if preview is not None:
        check_output(preview, (".mp4", ".gif"), "preview")
    motion, emotion = at_output_rate(walk)
    written = []
    if out.suffix.lower() == ".bvh":
        written.append(write_bvh(motion, out))
    else:
        written.append(write_npz(motion, emotion, walk.labels, walk.path.points, out))
    if npz is not None:
        written.append(write_npz(motion, emotion, walk.labels, walk.path.points, npz))
    if preview is not None:
        written.append(render_preview(
            motion, preview, path_xz=walk.path.points, captions=captions(emotion, walk.labels),
            title=f"{out.name}: {walk.path.name}", progress=progress,
        ))
    return [Path(p) for p in written]
