"""Pose error by prediction horizon: how far ahead each predictor stays close to the recording.

Table 1 of Emotive Gaits (section 5.5) averages the pose error over all 42 predicted frames
(4.2 s at 10 fps). Averaged that way, a predictor that is better far ahead and worse near the
primer can lose to holding the last frame (:class:`~emotive.eval.table1.ZeroVelocity`), which
is hard to beat over the first few frames. :func:`by_horizon` splits the same windows' error by
frame: the error ``h`` frames after the primer, for each predictor, as the mean over windows of
:attr:`~emotive.eval.table1.PredictorScores.pose_by_frame` at frame ``h``.

Each frame's error is relative to the bounding-box diagonal of the window's whole predicted
span (as in :func:`~emotive.eval.pose_errors.pose_error`), so the mean of a predictor's errors
over every horizon is its Table 1 pose error.

Shapes: ``B`` windows, ``T'`` predicted frames, ``H`` horizons.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.eval.table1 import Table1Result

__all__ = ["HORIZON_FRAMES", "HorizonErrors", "by_horizon"]

#: Horizons reported by default, frames after the primer (at 10 fps: 0.1 to 3 s); the
#: protocol's last frame is added by :func:`by_horizon`.
HORIZON_FRAMES: tuple[int, ...] = (1, 5, 10, 15, 20, 25, 30)


@dataclass(frozen=True, eq=False)
class HorizonErrors:
    """Mean pose error of each predictor at each horizon.

    Attributes:
        frames: ``(H,)`` horizons, frames after the primer (1 is the first predicted frame).
        fps: the frame rate of the run.
        names: the predictors, in the run's order.
        pose: ``(P, H)`` mean pose error over windows, a fraction of the bounding-box diagonal.
        windows: number of windows ``B`` averaged.
    """

    frames: np.ndarray
    fps: float
    names: tuple[str, ...]
    pose: np.ndarray
    windows: int

    def __getitem__(self, name: str) -> np.ndarray:
        """The ``(H,)`` errors of the predictor called ``name``."""
        if name not in self.names:
            raise KeyError(f"no predictor {name!r}; predictors: {list(self.names)}")
        return self.pose[self.names.index(name)]

    def beats(self, name: str, baseline: str) -> np.ndarray:
        """The horizons (frames) at which ``name``'s mean error is below ``baseline``'s."""
        return self.frames[self[name] < self[baseline]]

    def to_dict(self) -> dict:
        """JSON-ready: horizons in frames and seconds, and each predictor's errors."""
        return {
            "fps": self.fps, "windows": self.windows, "frames": self.frames.tolist(),
            "seconds": (self.frames / self.fps).tolist(),
            "pose": {n: self.pose[k].tolist() for k, n in enumerate(self.names)},
        }

    def to_markdown(self, digits: int = 3) -> str:
        """One row per horizon, one column per predictor; the smallest error of a row in bold."""
        header = ["frames ahead", "seconds", *self.names]
        lines = ["| " + " | ".join(header) + " |", "|" + "---:|" * len(header)]
        for h, frame in enumerate(self.frames):
            column = self.pose[:, h]
            cells = [f"**{v:.{digits}f}**" if v == column.min() else f"{v:.{digits}f}"
                     for v in column]
            lines.append(f"| {frame} | {frame / self.fps:.1f} | " + " | ".join(cells) + " |")
        return "\n".join(lines)


def by_horizon(result: Table1Result, frames: Sequence[int] = HORIZON_FRAMES) -> HorizonErrors:
    """Each predictor's mean pose error ``h`` frames after the primer, for each ``h``.

    Args:
        result: a :func:`~emotive.eval.table1.table1` run (or
            :func:`~emotive.eval.table1.merge_results` of several).
        frames: horizons in frames, each in ``1 .. result.predicted_frames``; the protocol's
            last frame is appended when missing.

    Returns:
        The ``(P, H)`` errors (:class:`HorizonErrors`), horizons sorted.

    Raises:
        ValueError: a horizon outside ``1 .. result.predicted_frames``.
    """
    last = result.predicted_frames
    wanted = sorted({int(f) for f in frames} | {last})
    if wanted[0] < 1 or wanted[-1] > last:
        raise ValueError(f"horizons must lie in 1..{last} frames (the predicted frames of this "
                         f"run at {result.fps:g} fps), got {list(frames)}")
    index = np.asarray(wanted) - 1
    pose = np.stack([s.pose_by_frame[:, index].mean(0) for s in result.scores])
    return HorizonErrors(np.asarray(wanted), result.fps, tuple(s.name for s in result.scores),
                         pose, result.windows)
