"""Stick-figure previews of motion as MP4 or GIF (matplotlib Agg frames, ffmpeg encoding).

The camera is orthographic, looking down at the ground from :data:`ELEVATION_DEG` above it,
from the front-left of the clip's main direction of travel (:data:`VIEW_ANGLE_DEG` off it;
:data:`AZIMUTH_DEG` around the vertical axis for a clip that stays in place), and follows the
character (its ground position smoothed over :data:`FOLLOW_SECONDS`) with a view
:data:`VIEW_WIDTH` metres wide. The ground shows a 1 m grid, the path to follow and the root's
trail; left limbs are blue, right limbs red; a caption gives the time and, per frame, any text
the caller passes (the current emotion, say).

Encoding goes through the ffmpeg binary that the ``imageio-ffmpeg`` wheel ships, streaming
frames, so memory does not grow with the clip length (:mod:`emotive.render.video`, which
checks the encoder's result and the finished file). GIFs get a palette computed over the
whole clip.

Legend: ``T`` frames, ``J + E`` joints then end sites, ``N`` bones.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.progress import track
from scipy.ndimage import uniform_filter1d

from emotive.core.motion import Motion
from emotive.errors import EmotiveError
from emotive.io.atomic import atomic_output
from emotive.io.outputs import missing_folder
from emotive.render.video import VideoEncoder

#: Output formats by file suffix.
PREVIEW_SUFFIXES = (".mp4", ".gif")
#: Highest default frame rate per format: GIF frame delays are whole hundredths of a second,
#: so 25 fps (4/100 s) is the fastest common rate it shows exactly.
MAX_DEFAULT_FPS = {".mp4": 30.0, ".gif": 25.0}
#: Camera angle around the vertical axis for clips without a direction of travel, degrees
#: (0 looks along +Z).
AZIMUTH_DEG = -140.0
#: Angle between the camera's view and the main direction of travel, degrees (180 would look
#: the walker in the face).
VIEW_ANGLE_DEG = 140.0
#: Camera angle above the ground, degrees.
ELEVATION_DEG = 25.0
#: Width of the view in metres.
VIEW_WIDTH = 5.0
#: The camera follows a moving average of the character's position over this many seconds.
FOLLOW_SECONDS = 1.0
#: Bones whose length changes more than this over the clip (metres) are translations, not bones
#: (e.g. a static top node joined to the hips that carry the world position): not drawn.
MAX_BONE_STRETCH = 0.05
_LEFT = re.compile(r"(^|[_.\- ])(L|Left|left)([_.\- ]|$)|^Left|^L(?=[A-Z])|_L$")
_RIGHT = re.compile(r"(^|[_.\- ])(R|Right|right)([_.\- ]|$)|^Right|^R(?=[A-Z])|_R$")
_COLOURS = {"left": "#1f5fbf", "right": "#c8352b", "centre": "#333333"}


class PreviewError(EmotiveError):
    """A preview that cannot be written (bad output name, nothing to draw)."""


def _azimuth(ground: np.ndarray) -> float:
    """Camera azimuth in degrees for a ``(T, 2)`` ``(x, z)`` ground track.

    A 3/4 front view of its principal direction, oriented by the net displacement.
    """
    centred = ground - ground.mean(0)
    if len(ground) < 2 or np.ptp(ground, axis=0).max() < 0.5:
        return AZIMUTH_DEG
    axis = np.linalg.svd(centred, full_matrices=False)[2][0]
    if np.dot(axis, ground[-1] - ground[0]) < 0:
        axis = -axis
    return float(np.degrees(np.arctan2(axis[0], axis[1]))) - VIEW_ANGLE_DEG


def _camera(azimuth_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Screen right and up vectors ``(3,)`` of the orthographic camera."""
    az, el = np.radians(azimuth_deg), np.radians(ELEVATION_DEG)
    forward = np.array([np.sin(az) * np.cos(el), -np.sin(el), np.cos(az) * np.cos(el)])
    right = np.array([-forward[2], 0.0, forward[0]])
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward)


def _project(points: np.ndarray, azimuth_deg: float) -> np.ndarray:
    """``(..., 3)`` world points to ``(..., 2)`` screen coordinates in metres."""
    right, up = _camera(azimuth_deg)
    return np.stack((points @ right, points @ up), axis=-1)


def bones(motion: Motion, positions: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The segments to draw and their side.

    Args:
        motion: the clip (its skeleton gives the hierarchy).
        positions: ``(T, J + E, 3)`` world positions of joints then end sites.

    Returns:
        ``(N, 2)`` indices into the ``J + E`` points (parent, child) and ``N`` sides
        (``"left"``, ``"right"``, ``"centre"``, from the child's name).
    """
    sk = motion.skeleton
    n = sk.num_joints
    pairs = [(int(p), j) for j, p in enumerate(sk.parents) if p >= 0]
    pairs += [(int(p), n + e) for e, p in enumerate(sk.end_site_parents)]
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64), []
    idx = np.array(pairs, dtype=np.int64)
    length = np.linalg.norm(positions[:, idx[:, 0]] - positions[:, idx[:, 1]], axis=-1)
    keep = np.ptp(length, axis=0) <= MAX_BONE_STRETCH
    idx = idx[keep]
    names = [sk.names[c] if c < n else sk.names[p] for p, c in idx]
    sides = [
        "left" if _LEFT.search(name) else "right" if _RIGHT.search(name) else "centre"
        for name in names
    ]
    return idx, sides


def _grid(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(G, 2, 3)`` 1 m ground-grid segments covering ``[lo, hi]`` in ``(x, z)``."""
    xs = np.arange(np.floor(lo[0]), np.ceil(hi[0]) + 1.0)
    zs = np.arange(np.floor(lo[1]), np.ceil(hi[1]) + 1.0)
    along_z = [((x, 0.0, zs[0]), (x, 0.0, zs[-1])) for x in xs]
    along_x = [((xs[0], 0.0, z), (xs[-1], 0.0, z)) for z in zs]
    return np.array(along_z + along_x, dtype=np.float64)


def render_preview(
    motion: Motion,
    out: str | os.PathLike,
    *,
    path_xz: np.ndarray | None = None,
    captions: Sequence[str] | None = None,
    title: str = "",
    fps: float | None = None,
    size: tuple[int, int] = (640, 480),
    progress: bool = False,
) -> Path:
    """Write a stick-figure video of a clip.

    Args:
        motion: the clip, ``T`` frames, metres, Y up.
        out: ``.mp4`` or ``.gif`` file; its folder must exist. Written atomically.
        path_xz: optional ``(P, 2)`` ground path ``(x, z)`` to draw (e.g.
            ``GroundPath.points``).
        captions: optional ``T`` strings shown with the time, frame by frame.
        title: a line above the picture.
        fps: output frame rate; default the clip's rate, at most 30 for MP4 and 25 for GIF
            (frames are skipped to keep real time).
        size: ``(width, height)`` in pixels.
        progress: show a progress bar on stderr.

    Returns:
        The written path.

    Raises:
        PreviewError: unknown suffix, a folder's name, missing folder, empty clip, or captions
            of the wrong length.
        OutputError: the video cannot be written whole (full disk, read-only folder, the
            encoder failing); nothing is left behind.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib)
    from matplotlib.collections import LineCollection  # noqa: PLC0415 (heavy: matplotlib)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib)

    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in PREVIEW_SUFFIXES:
        raise PreviewError(
            f"preview {out}: unknown video type {out.suffix!r}; use one of {PREVIEW_SUFFIXES}"
        )
    if out.is_dir():
        raise PreviewError(f"preview {out}: that is a folder; name a file in it, e.g. "
                           f"{out / 'preview.gif'}")
    problem = missing_folder(out)
    if problem is not None:
        raise PreviewError(f"preview {out}: {problem}")
    if motion.num_frames == 0:
        raise PreviewError(f"preview {out}: the motion has no frames")
    if captions is not None and len(captions) != motion.num_frames:
        raise PreviewError(
            f"preview {out}: {len(captions)} captions for {motion.num_frames} frames"
        )
    rate = float(fps) if fps is not None else min(motion.fps, MAX_DEFAULT_FPS[suffix])
    if not rate > 0:
        raise PreviewError(f"preview {out}: fps must be positive, got {fps}")
    frames = np.unique(np.round(np.arange(0.0, motion.duration, 1.0 / rate) * motion.fps)
                       .astype(np.int64).clip(0, motion.num_frames - 1))

    positions = motion.positions_with_end_sites()
    idx, sides = bones(motion, positions)
    # The trail follows the top joint of the drawn figure (the hips when a static top node
    # carries them, as on the Bandai rig).
    root = positions[:, int(idx[:, 0].min()) if idx.size else 0]
    ground = [positions[..., [0, 2]].reshape(-1, 2)]
    if path_xz is not None:
        ground.append(np.asarray(path_xz, dtype=np.float64).reshape(-1, 2))
    lo, hi = np.min([g.min(0) for g in ground], 0), np.max([g.max(0) for g in ground], 0)
    azimuth = _azimuth(root[:, [0, 2]])
    grid = _project(_grid(lo - VIEW_WIDTH, hi + VIEW_WIDTH), azimuth)
    screen = _project(positions, azimuth)
    trail = _project(np.stack((root[:, 0], np.zeros(len(root)), root[:, 2]), 1), azimuth)
    # Camera target: the smoothed ground position of the trail joint, lifted to mid-body.
    window = max(1, round(FOLLOW_SECONDS * motion.fps))
    smooth = uniform_filter1d(root, window, axis=0, mode="nearest")
    smooth[:, 1] = 0.5 * np.median(root[:, 1])
    centre = _project(smooth, azimuth)

    width, height = size
    half_w = 0.5 * VIEW_WIDTH
    half_h = half_w * height / width
    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    # The axes fill the figure and the limits keep its aspect ratio: one metre is as long
    # across as it is up.
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.add_collection(LineCollection(grid, colors="#dddddd", linewidths=0.8))
    if path_xz is not None:
        p = np.asarray(path_xz, dtype=np.float64).reshape(-1, 2)
        ax.plot(*_project(np.stack((p[:, 0], np.zeros(len(p)), p[:, 1]), 1), azimuth).T,
                color="#2a9d4b", lw=1.5)
    (trail_line,) = ax.plot([], [], color="#999999", lw=1.0)
    figure = LineCollection([], colors=[_COLOURS[s] for s in sides], linewidths=2.5,
                            capstyle="round")
    ax.add_collection(figure)
    caption = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", family="monospace",
                      fontsize=11)
    if title:
        ax.text(0.98, 0.97, title, transform=ax.transAxes, va="top", ha="right", fontsize=10)

    with atomic_output(out) as tmp, VideoEncoder(tmp, size, rate, gif=suffix == ".gif",
                                                 name=out) as video:
        # No bar when stderr is no terminal: it would leave a blank line in logs.
        console = Console(stderr=True)
        for t in track(frames, description=f"rendering {out.name}", console=console,
                       disable=not (progress and console.is_terminal), transient=True):
            ax.set_xlim(centre[t, 0] - half_w, centre[t, 0] + half_w)
            ax.set_ylim(centre[t, 1] - half_h, centre[t, 1] + half_h)
            figure.set_segments(screen[t][idx])
            trail_line.set_data(trail[: t + 1, 0], trail[: t + 1, 1])
            text = f"{t / motion.fps:6.2f} s"
            caption.set_text(text + (f"  {captions[t]}" if captions is not None else ""))
            canvas.draw()
            rgb = np.asarray(canvas.buffer_rgba())[..., :3]
            video.send(np.ascontiguousarray(rgb).tobytes())
    return out
