"""Not-a-replay measure and guard of resampled motion (issue 7, section 3).

Resampled motion must differ from every captured sequence. It is compared window by window:
a *window* is :data:`WINDOW_SECONDS` of the end-effector points :data:`EFFECTORS` (head, both
wrists, both ankles, each in its chain's frame, so independent of where the character is),
flattened; the distance of two windows is the RMS over frames and points of the point
distances (metres). A generated window's *novelty* is its distance to the nearest window of any
captured clip of the emotion (every captured frame starts one).

The threshold (:class:`NoveltyReference`): how close two *distinct* captured clips of the
emotion come, the :data:`THRESHOLD_PERCENTILE`-th percentile over every captured window of the
distance to the nearest window of another clip. A new take of the emotion would therefore have
5 % of its windows at or below it; replaying a captured passage through the IK gives about
0.1 mm. The guard (:meth:`emotive.models.lgb.resampler.EmotionResampler.sample_features`)
redraws every stretch whose window is not above the threshold.

Legend: ``T`` frames, ``P`` effector points, ``L`` frames of a window, ``K`` windows, ``M``
captured windows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Feature blocks compared (one 3D point each).
EFFECTORS = ("head_torso:head", "left_arm:l_wrist", "right_arm:r_wrist", "left_leg:l_ankle",
             "right_leg:r_ankle")
#: Length of a compared window.
WINDOW_SECONDS = 1.0
#: Percentile of the distinct-clip distances used as the threshold.
THRESHOLD_PERCENTILE = 5.0
#: Query windows per block of the brute-force search (bounds its memory).
_BLOCK = 512


def windows(points: np.ndarray, length: int, hop: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Every ``hop``-th window of ``length`` frames.

    Args:
        points: ``(T, 3P)`` effector points per frame.
        length: frames per window, ``L``.
        hop: frames between window starts.

    Returns:
        Start frames ``(K,)`` and windows ``(K, L * 3P)`` (none if ``T < L``).
    """
    starts = np.arange(0, len(points) - length + 1, hop)
    if not len(starts):
        return starts, np.zeros((0, length * points.shape[1]))
    view = np.lib.stride_tricks.sliding_window_view(points, length, axis=0)[starts]
    return starts, view.transpose(0, 2, 1).reshape(len(starts), -1)


def nearest_distance(queries: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """RMS point distance from each query window to the nearest of ``pool``.

    RMS point distance (metres) from each window of ``queries`` ``(K, L*3P)`` to the nearest
    of ``pool`` ``(M, L*3P)``; ``(K,)``, infinite where the pool is empty.
    """
    best = np.full(len(queries), np.inf)
    if not len(pool):
        return best
    points = queries.shape[1] / 3
    pool_sq = (pool**2).sum(1)
    for a in range(0, len(queries), _BLOCK):
        q = queries[a : a + _BLOCK]
        d2 = (q**2).sum(1)[:, None] + pool_sq[None] - 2.0 * q @ pool.T
        best[a : a + _BLOCK] = np.sqrt(np.maximum(d2.min(1), 0.0))
    return best / np.sqrt(points)


@dataclass(frozen=True, eq=False)
class NoveltyReference:
    """The captured windows of one emotion and its not-a-replay threshold.

    Attributes:
        pool: ``(M, L*3P)`` every captured window.
        threshold: metres; a generated window must be farther than this from the pool.
        distinct: ``(M',)`` each captured window's distance to the nearest window of another
            clip (the threshold's sample; empty with a single clip).
        length: ``L``, frames of a window.
    """

    pool: np.ndarray
    threshold: float
    distinct: np.ndarray
    length: int

    @classmethod
    def fit(cls, clips: Sequence[np.ndarray], length: int) -> NoveltyReference:
        """Windows and threshold of captured clips.

        Args:
            clips: one ``(T_i, 3P)`` array of effector points per clip.
            length: ``L``, frames of a window.

        Returns:
            The reference; with one clip (no distinct pair) the threshold is 0.
        """
        per_clip = [windows(c, length)[1] for c in clips]
        pool = np.concatenate(per_clip) if per_clip else np.zeros((0, 0))
        distinct = [
            nearest_distance(w, np.concatenate([v for j, v in enumerate(per_clip) if j != i]))
            for i, w in enumerate(per_clip)
            if len(w) and sum(len(v) for j, v in enumerate(per_clip) if j != i)
        ]
        between = np.concatenate(distinct) if distinct else np.zeros(0)
        threshold = float(np.percentile(between, THRESHOLD_PERCENTILE)) if len(between) else 0.0
        return cls(pool, threshold, between, length)

    def novelty(self, points: np.ndarray, hop: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Start frames and nearest captured-window distances of every ``hop``-th window.

        Start frames ``(K,)`` and nearest captured-window distances ``(K,)`` of every
        ``hop``-th window of ``points`` ``(T, 3P)``.
        """
        starts, w = windows(points, self.length, hop)
        return starts, nearest_distance(w, self.pool)


@dataclass(frozen=True)
class NoveltyReport:
    """What the not-a-replay guard did to one resampled sequence.

    Attributes:
        threshold: metres (see :class:`NoveltyReference`).
        windows: windows checked (every :data:`~emotive.models.lgb.resampler.GUARD_HOP`-th frame).
        redrawn: stretches redrawn.
        rounds: check-and-redraw rounds run.
        closest: metres, the smallest novelty of a checked window after the guard.
        below: windows still not above the threshold when the guard gave up (0: every
            checked window is new).
    """

    threshold: float
    windows: int
    redrawn: int
    rounds: int
    closest: float
    below: int
