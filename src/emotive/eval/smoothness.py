"""Smoothness metrics based on jerk.

Smoothness: :func:`jerk`, :func:`windowed_jerk` and :func:`transition_smoothness`
(jerk around emotion changes against real-data jerk).

Conventions (shapes, units) are those of :mod:`emotive.eval.metric_inputs`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints, ``K`` emotion
changes, ``W`` windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.eval.metric_inputs import check_points, check_positive, window_frames

__all__ = [
    "TransitionSmoothness",
    "jerk",
    "transition_smoothness",
    "windowed_jerk",
]


def jerk(positions: np.ndarray, fps: float, per_joint: bool = False) -> np.ndarray:
    """Magnitude of the jerk (third time derivative) of joint positions.

    ``j_i = | x_{i+3} - 3 x_{i+2} + 3 x_{i+1} - x_i | * fps^3``, the third finite difference,
    exact for cubic motion; sample ``i`` is centred between frames ``i + 1`` and ``i + 2``.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres, ``T >= 4``.
        fps: frames per second.
        per_joint: keep joints apart instead of averaging them.

    Returns:
        ``(..., T - 3)`` mean over joints (``(..., T - 3, J)`` with ``per_joint``), m/s^3.

    Raises:
        ValueError: fewer than 4 frames, bad shapes, or a non-positive ``fps``.
    """
    p = check_points(positions, "positions", min_frames=4)
    fps = check_positive(fps, "fps")
    magnitude = np.linalg.norm(np.diff(p, n=3, axis=-3), axis=-1) * fps**3
    return magnitude if per_joint else magnitude.mean(-1)


def windowed_jerk(positions: np.ndarray, fps: float, window_s: float = 0.5) -> np.ndarray:
    """Mean :func:`jerk` over every window of ``round(window_s * fps)`` consecutive samples.

    This is the statistic :func:`transition_smoothness` measures around emotion changes;
    computed on real clips it gives the reference distribution to compare against.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.
        fps: frames per second.
        window_s: window length in seconds.

    Returns:
        ``(..., T - 3 - n + 1)`` window means, m/s^3 (``n`` the window length in samples).

    Raises:
        ValueError: the clip is shorter than one window (plus the 3 frames a jerk needs).
    """
    j = jerk(positions, fps)
    n = window_frames(window_s, fps)
    if j.shape[-1] < n:
        raise ValueError(f"a clip of {j.shape[-1] + 3} frames is shorter than one window of "
                         f"{n} jerk samples ({window_s} s) plus 3 frames")
    return np.lib.stride_tricks.sliding_window_view(j, n, axis=-1).mean(-1)


@dataclass(frozen=True)
class TransitionSmoothness:
    """Jerk around emotion changes compared with a reference distribution.

    Attributes:
        jerk: ``(K,)`` mean jerk in the window around each change, m/s^3.
        percentile: ``(K,)`` share of reference values at or below it, in ``[0, 100]``.
        exceeds: ``(K,)`` bool, whether it is above the reference's ``level`` percentile.
        threshold: that percentile of the reference, m/s^3.
    """

    jerk: np.ndarray
    percentile: np.ndarray
    exceeds: np.ndarray
    threshold: float


def transition_smoothness(
    positions: np.ndarray,
    fps: float,
    change_frames: np.ndarray,
    reference: np.ndarray,
    window_s: float = 0.5,
    level: float = 99.0,
) -> TransitionSmoothness:
    """Whether the motion jerks where the emotion changes, judged against real data.

    For a change at frame ``c`` (the first frame of the new emotion) the window holds the
    ``n = round(window_s * fps)`` jerk samples centred on the boundary between frames ``c - 1``
    and ``c`` (moved inwards near the clip's ends); its mean jerk is ranked within
    ``reference``. For a fair
    ranking the reference should be the same statistic on real clips,
    ``windowed_jerk(real, fps, window_s)`` (per-sample :func:`jerk` values, which vary more
    than window means, would make transitions look smoother than they are).

    Args:
        positions: ``(T, J, 3)`` joint positions of one clip, metres, ``T >= 4``.
        fps: frames per second.
        change_frames: ``(K,)`` frames where the emotion changes, in ``[0, T)``.
        reference: any-shaped array of reference jerk values (finite, at least one), m/s^3.
        window_s: window length in seconds.
        level: percentile of the reference that a transition must not exceed.

    Returns:
        The :class:`TransitionSmoothness` report.

    Raises:
        ValueError: bad shapes, frames out of range, an empty or non-finite reference, or a
            level outside ``[0, 100]``.
    """
    p = check_points(positions, "positions", min_frames=4)
    if p.ndim != 3:
        raise ValueError(f"positions must be one clip (T, J, 3), got {p.shape}")
    frames = np.asarray(change_frames)
    integral = np.issubdtype(frames.dtype, np.integer) or frames.size == 0
    if frames.ndim != 1 or not integral:
        raise ValueError(f"change_frames must be a (K,) integer array, got shape {frames.shape} "
                         f"of {frames.dtype}")
    frames = frames.astype(np.int64)
    if np.any((frames < 0) | (frames >= len(p))):
        raise ValueError(f"change_frames must lie in [0, {len(p)}), got {frames.tolist()}")
    ref = np.sort(np.asarray(reference, dtype=np.float64).ravel())
    if not ref.size or not np.all(np.isfinite(ref)):
        raise ValueError("reference must hold at least one value, all finite")
    if not 0 <= level <= 100:
        raise ValueError(f"level must lie in [0, 100], got {level}")
    j = jerk(p, fps)
    n = min(window_frames(window_s, fps), len(j))
    # Samples i..i+3 straddle the boundary c - 1 | c for i in [c - 3, c - 1]: centre on c - 2.
    # Near the clip's ends the window slides inwards, so every window has n samples like those
    # of windowed_jerk.
    start = np.clip(frames - 2 - n // 2, 0, len(j) - n)
    window_mean = j[start[:, None] + np.arange(n)].mean(-1)
    threshold = float(np.percentile(ref, level))
    return TransitionSmoothness(
        jerk=window_mean,
        percentile=100.0 * np.searchsorted(ref, window_mean, side="right") / ref.size,
        exceeds=window_mean > threshold,
        threshold=threshold,
    )
