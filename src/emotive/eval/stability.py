"""Long-horizon stability.

:func:`motion_energy` and :func:`stability_report` (collapse and explosion).

Conventions (shapes, units) are those of :mod:`emotive.eval.metric_inputs`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints, ``W`` windows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.eval.metric_inputs import check_points, check_positive, root_relative, window_frames

__all__ = [
    "BONE_FACTOR",
    "COLLAPSE_FRACTION",
    "EXPLOSION_FACTOR",
    "FREEZE_SPEED",
    "StabilityReport",
    "motion_energy",
    "stability_report",
]


#: Share of the reference level below which a window's motion energy counts as collapsed.
COLLAPSE_FRACTION = 0.2
#: Mean joint speed (m/s) under which a window counts as frozen, whatever the reference: motion
#: capture noise alone moves joints faster than 1 mm/s.
FREEZE_SPEED = 1e-3
#: Multiple of the reference level above which a window's motion energy counts as exploded.
EXPLOSION_FACTOR = 5.0
#: Bone length, as a multiple of its first-frame length, above which a bone has blown up.
BONE_FACTOR = 1.5


def _joint_speed(p: np.ndarray, fps: float, root_index: int | None) -> np.ndarray:
    """``(..., T - 1, J')`` speed of every (root-relative) joint between consecutive frames."""
    with np.errstate(invalid="ignore", over="ignore"):
        rel = root_relative(p, root_index)
        return np.linalg.norm(np.diff(rel, axis=-3), axis=-1) * fps


def motion_energy(
    positions: np.ndarray, fps: float, window_s: float = 1.0, root_index: int | None = 0
) -> np.ndarray:
    """Mean joint speed in consecutive windows, over time.

    ``E_w = mean over the speed samples i in window w and joints j of |x_{i+1,j} - x_{ij}| fps``
    on windows of ``n = round(window_s * fps)`` samples (frame pairs); a last, partial window
    is dropped. Positions are root-relative by default, so a character gliding with a frozen
    pose has no energy.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.
        fps: frames per second.
        window_s: window length in seconds.
        root_index: joint subtracted from the others and left out; ``None`` keeps world
            positions.

    Returns:
        ``(..., W)`` energies in m/s, ``W = (T - 1) // n``; NaN or inf where the input is.

    Raises:
        ValueError: the clip is shorter than one window, or bad shapes.
    """
    p = check_points(positions, "positions", min_frames=2)
    fps = check_positive(fps, "fps")
    speed = _joint_speed(p, fps, root_index).mean(-1)
    n = window_frames(window_s, fps)
    count = speed.shape[-1] // n
    if count == 0:
        raise ValueError(f"a clip of {p.shape[-3]} frames is shorter than one window of "
                         f"{window_s} s ({n + 1} frames)")
    return speed[..., : count * n].reshape(*speed.shape[:-1], count, n).mean(-1)


@dataclass(frozen=True)
class StabilityReport:
    """Long-horizon stability of one clip.

    Attributes:
        energy: ``(W,)`` :func:`motion_energy` per window, m/s.
        window_s: window length, seconds (window ``w`` starts at ``w * window_s``).
        reference_energy: the level collapse and explosion are measured against, m/s.
        collapsed: some window's energy fell below the collapse fraction of the reference, or
            under the freeze speed.
        collapse_time: start of the first such window, seconds (``None`` if none).
        exploded: non-finite positions, a window above the explosion factor times the
            reference, or a bone stretched beyond the bone factor.
        explosion_time: first frame or window start at which that happened, seconds.
        non_finite: some position is NaN or infinite.
        max_bone_ratio: largest bone length over its first-frame length (NaN without
            ``parents``).
    """

    energy: np.ndarray
    window_s: float
    reference_energy: float
    collapsed: bool
    collapse_time: float | None
    exploded: bool
    explosion_time: float | None
    non_finite: bool
    max_bone_ratio: float

    @property
    def stable(self) -> bool:
        """Neither collapsed nor exploded."""
        return not (self.collapsed or self.exploded)


def _first_time(mask: np.ndarray, seconds_per_step: float) -> float | None:
    hits = np.flatnonzero(mask)
    return float(hits[0] * seconds_per_step) if hits.size else None


def stability_report(
    positions: np.ndarray,
    fps: float,
    parents: Sequence[int] | None = None,
    reference_energy: float | None = None,
    window_s: float = 1.0,
    root_index: int | None = 0,
    collapse_fraction: float = COLLAPSE_FRACTION,
    freeze_speed: float = FREEZE_SPEED,
    explosion_factor: float = EXPLOSION_FACTOR,
    bone_factor: float = BONE_FACTOR,
) -> StabilityReport:
    """Detect collapse (the motion dies out or freezes) and explosion (it blows up).

    * Collapse: a window of :func:`motion_energy` below ``collapse_fraction`` times the
      reference, or below ``freeze_speed`` (a frozen pose, whatever the reference).
    * Explosion: a NaN or infinite position; a window above ``explosion_factor`` times the
      reference; or, with ``parents``, a bone longer than ``bone_factor`` times its length in
      the first frame (bones of forward kinematics never stretch; this catches models that
      output positions).

    The reference defaults to the first window's energy, which suits autoregressive
    continuations of a real seed; pass the energy of real clips of the same kind otherwise.
    Without a finite positive reference only freezes, non-finite values and bones are judged.

    Args:
        positions: ``(T, J, 3)`` joint positions of one clip, metres.
        fps: frames per second.
        parents: ``(J,)`` parent of each joint (``-1`` for roots), for the bone check.
        reference_energy: reference mean joint speed, m/s.
        window_s: window length in seconds.
        root_index: as in :func:`motion_energy`.
        collapse_fraction: share of the reference below which a window has collapsed.
        freeze_speed: energy (m/s) below which a window is frozen.
        explosion_factor: multiple of the reference above which a window has exploded.
        bone_factor: bone stretch above which the skeleton has exploded.

    Returns:
        The :class:`StabilityReport`.

    Raises:
        ValueError: bad shapes, a clip shorter than one window, ``parents`` of the wrong
            length or a negative given reference.
    """
    p = check_points(positions, "positions", min_frames=2)
    if p.ndim != 3:
        raise ValueError(f"positions must be one clip (T, J, 3), got {p.shape}")
    fps = check_positive(fps, "fps")
    energy = motion_energy(p, fps, window_s, root_index)
    n = window_frames(window_s, fps)
    window_time = n / fps
    if reference_energy is None:
        ref = float(energy[0])
    else:
        ref = float(reference_energy)
        if not ref >= 0:
            raise ValueError(f"reference_energy must be non-negative, got {ref}")
    judged = bool(np.isfinite(ref) and ref > 0)

    collapsed_windows = energy < freeze_speed
    if judged:
        collapsed_windows |= energy < collapse_fraction * ref
    finite_frames = np.isfinite(p).all((-2, -1))
    times = [_first_time(~finite_frames, 1.0 / fps)]
    if judged:
        times.append(_first_time(energy > explosion_factor * ref, window_time))

    max_ratio = float("nan")
    if parents is not None:
        par = np.asarray(parents, dtype=np.int64)
        if par.shape != (p.shape[1],):
            raise ValueError(f"parents must have one entry per joint ({p.shape[1]}), got "
                             f"{par.shape}")
        child = np.flatnonzero(par >= 0)
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            length = np.linalg.norm(p[:, child] - p[:, par[child]], axis=-1)
            ratio = length / length[:1]
        # Bones of zero rest length (coincident joints) have no scale to stretch against.
        ratio = np.where(length[:1] > 0, ratio, 1.0)
        if ratio.size and np.isfinite(ratio).any():
            max_ratio = float(np.nanmax(np.where(np.isfinite(ratio), ratio, np.nan)))
        times.append(_first_time((ratio > bone_factor).any(-1), 1.0 / fps))

    hits = [t for t in times if t is not None]
    return StabilityReport(
        energy=energy,
        window_s=window_time,
        reference_energy=ref,
        collapsed=bool(collapsed_windows.any()),
        collapse_time=_first_time(collapsed_windows, window_time),
        exploded=bool(hits),
        explosion_time=min(hits) if hits else None,
        non_finite=not bool(finite_frames.all()),
        max_bone_ratio=max_ratio,
    )
