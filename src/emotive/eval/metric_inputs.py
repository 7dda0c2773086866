"""Conventions and input checks shared by the motion metrics of :mod:`emotive.eval`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints (``J + E`` joints
then end sites where joint roles are looked up), ``C`` channels of a feature vector, ``N`` and
``M`` samples, ``P`` vertices of a path, ``K`` emotion changes, ``W`` windows.

Conventions: quaternions are ``(..., 4)`` unit versors ``(w, x, y, z)``; lengths are metres,
Y is up and the ground is the XZ plane ("2D" means the ``(x, z)`` projection); speeds are
finite differences times ``fps`` (per second); every angle a metric returns is in degrees.
Each metric is a pure function of NumPy arrays and raises ``ValueError`` on a bad shape.

The metrics, by family: :mod:`~emotive.eval.pose_errors` (errors against ground truth),
:mod:`~emotive.eval.feet` (skating and ground penetration), :mod:`~emotive.eval.path_following`,
:mod:`~emotive.eval.smoothness` (jerk), :mod:`~emotive.eval.stability` (long-horizon collapse
and explosion) and :mod:`~emotive.eval.distributions` (Fréchet distance and diversity).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "REDUCTIONS",
    "check_points",
    "check_positive",
    "check_quaternions",
    "check_reduction",
    "check_same_shape",
    "reduce_values",
    "root_relative",
    "window_frames",
]


#: Reductions of per-joint values (see :func:`reduce_values`).
REDUCTIONS = ("mean", "frame", "none")


def check_points(x: np.ndarray, name: str, min_frames: int = 1) -> np.ndarray:
    """``x`` as float64 ``(..., T, J, 3)`` with at least ``min_frames`` frames and one joint."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim < 3 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., T, J, 3), got {a.shape}")
    if a.shape[-3] < min_frames or a.shape[-2] < 1:
        raise ValueError(
            f"{name} needs at least {min_frames} frame(s) and one joint, got shape {a.shape}"
        )
    return a


def check_quaternions(q: np.ndarray, name: str) -> np.ndarray:
    """``q`` as float64 ``(..., T, J, 4)`` with at least one frame and one joint."""
    a = np.asarray(q, dtype=np.float64)
    if a.ndim < 3 or a.shape[-1] != 4 or a.shape[-3] < 1 or a.shape[-2] < 1:
        raise ValueError(f"{name} must have shape (..., T, J, 4) with T, J >= 1, got {a.shape}")
    return a


def check_same_shape(a: np.ndarray, b: np.ndarray) -> None:
    """Raise ``ValueError`` unless predicted ``a`` and target ``b`` have one shape."""
    if a.shape != b.shape:
        raise ValueError(f"predicted and target must have the same shape, got {a.shape} and "
                         f"{b.shape}")


def check_positive(value: float, name: str) -> float:
    """``value`` as a float, which must be finite and positive (``ValueError`` naming it)."""
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value}")
    return value


def reduce_values(values: np.ndarray, reduction: str) -> np.ndarray:
    """Reduce ``(..., T, J)`` per-joint values by ``reduction``.

    See :func:`emotive.eval.pose_errors.pose_error` for the reductions.
    """
    if reduction == "none":
        return values
    if reduction == "frame":
        return values.mean(-1)
    return values.mean((-2, -1))


def check_reduction(reduction: str) -> None:
    """Raise ``ValueError`` unless ``reduction`` is one of :data:`REDUCTIONS`."""
    if reduction not in REDUCTIONS:
        raise ValueError(f"reduction must be one of {REDUCTIONS}, got {reduction!r}")


def root_relative(p: np.ndarray, root_index: int | None) -> np.ndarray:
    """Positions ``(..., T, J, 3)`` minus the root's, without the root joint itself."""
    if root_index is None:
        return p
    joints = p.shape[-2]
    if not -joints <= root_index < joints:
        raise ValueError(f"root_index {root_index} is out of range for {joints} joints")
    if joints < 2:
        raise ValueError("root-relative positions need at least two joints (pass root_index=None)")
    root = root_index % joints
    keep = np.arange(joints) != root
    return (p - p[..., root : root + 1, :])[..., keep, :]


def window_frames(window_s: float, fps: float) -> int:
    """Frames in a window of ``window_s`` seconds (positive) at ``fps``, at least one."""
    return max(1, round(check_positive(window_s, "window_s") * fps))
