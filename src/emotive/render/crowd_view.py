"""Top-view MP4 of a crowd run: the area, its obstacles, every agent coloured by emotion.

Legend: ``T`` frames of an agent, ``C`` emotion labels.

Each agent is a disc at its body's root on the ground (the scene's ``x, y``; ``y`` is the
world ``z``), its colour the blend of the four emotions' colours (:data:`COLOURS`) by its
emotion's place in the valence/arousal circumplex, with a trail of its last
:data:`TRAIL_SECONDS`. Frames are drawn with matplotlib's Agg canvas and encoded by
:class:`~emotive.render.video.VideoEncoder`, written atomically.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from emotive.data.emotion import DEFAULT_LABELS, valence_arousal, weights_from_valence_arousal
from emotive.io.atomic import atomic_output
from emotive.render.video import VideoEncoder

__all__ = ["COLOURS", "emotion_colours", "render_crowd"]

#: RGB of the four emotions (the order of ``DEFAULT_LABELS``: happy, sad, angry, neutral).
COLOURS = np.array([[0.98, 0.75, 0.10], [0.20, 0.40, 0.85], [0.85, 0.15, 0.15],
                    [0.55, 0.55, 0.55]])
#: Seconds of trail behind each agent.
TRAIL_SECONDS = 2.0
#: Largest frame rate of the video: longer runs skip frames.
MAX_VIDEO_FPS = 15.0


def emotion_colours(weights: np.ndarray, labels: Sequence[str]) -> np.ndarray:
    """``(..., 3)`` RGB of emotions ``(..., C)`` over ``labels``."""
    mix = weights_from_valence_arousal(valence_arousal(weights, labels), DEFAULT_LABELS)
    return mix @ COLOURS


def render_crowd(out: Path, area: Sequence[Sequence[float]],
                 obstacles: Sequence[Sequence[Sequence[float]]],
                 tracks: Mapping[int, tuple[int, np.ndarray, np.ndarray]], frames: int,
                 fps: float, labels: Sequence[str], progress: bool = False) -> Path:
    """Write the top view of a crowd run as MP4.

    Args:
        out: the ``.mp4`` file.
        area: the area's ring ``[[x, y], ...]``.
        obstacles: the obstacles' rings.
        tracks: per agent ``(first frame, root (T, 2), emotion (T, C))``.
        frames: frames of the run.
        fps: frame rate of the run.
        labels: the ``C`` labels.
        progress: print the frame count on stderr now and then.

    Returns:
        ``out``.
    """
    import sys  # noqa: PLC0415 (progress lines only)

    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy)
    from matplotlib.patches import Polygon as Patch  # noqa: PLC0415 (heavy)

    ring = np.asarray(area, dtype=np.float64)
    lo, hi = ring.min(0) - 0.5, ring.max(0) + 0.5
    span = hi - lo
    width = 8.0
    height = float(np.clip(width * span[1] / span[0], 2.0, 10.0))
    fig = Figure(figsize=(width, height), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.axis("off")
    ax.add_patch(Patch(ring, closed=True, facecolor="#f4f1ea", edgecolor="#333", lw=1.5))
    for o in obstacles:
        ax.add_patch(Patch(np.asarray(o), closed=True, facecolor="#555", edgecolor="#222"))
    colours = {a: emotion_colours(e, labels) for a, (_, _, e) in tracks.items()}
    dots = ax.scatter([], [], s=20, zorder=3)
    trails = ax.scatter([], [], s=1, zorder=2, alpha=0.35)
    label = ax.text(lo[0] + 0.2, hi[1] - 0.3, "", fontsize=9, va="top")
    stride = max(1, int(np.ceil(fps / MAX_VIDEO_FPS)))
    trail = int(TRAIL_SECONDS * fps)
    size = canvas.get_width_height()
    with atomic_output(out) as tmp, VideoEncoder(tmp, size, fps / stride, gif=False,
                                                 name=out) as video:
        for f in range(0, max(frames, 1), stride):
            xy, rgb, txy, trgb = [], [], [], []
            for a, (first, root, _) in tracks.items():
                k = f - first
                if 0 <= k < len(root):
                    xy.append(root[k])
                    rgb.append(colours[a][k])
                    seg = root[max(0, k - trail):k + 1:stride]
                    txy.append(seg)
                    trgb.append(np.repeat(colours[a][k][None], len(seg), 0))
            dots.set_offsets(np.asarray(xy).reshape(-1, 2))
            dots.set_facecolors(np.asarray(rgb).reshape(-1, 3))
            trails.set_offsets(np.vstack(txy) if txy else np.zeros((0, 2)))
            trails.set_facecolors(np.vstack(trgb) if trgb else np.zeros((0, 3)))
            label.set_text(f"{f / fps:5.1f} s   {len(xy)} agents")
            canvas.draw()
            video.send(np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[..., :3]).tobytes())
            if progress and f % (stride * 150) == 0:
                print(f"preview: frame {f}/{frames}", file=sys.stderr, flush=True)
    return out
