"""Plain NumPy rotation kernels for a few poses at a time (streaming).

:mod:`emotive.transforms.np_rotations` wraps the torch kernels of
:mod:`emotive.transforms.rotations`; each call converts arrays to tensors and back, which costs
more than the arithmetic on the few quaternions of one streamed frame. These are the same
formulas (same conventions: ``(w, x, y, z)``, Hamilton product, ``+Y`` up) on NumPy arrays;
``tests/transforms/test_fast_np.py`` checks them against the torch kernels.
:class:`emotive.transforms.kinematics.PoseFK` uses :func:`qmatrix` for NumPy input.
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-12
#: Conjugation signs of a ``(w, x, y, z)`` quaternion.
CONJUGATE = np.array([1.0, -1.0, -1.0, -1.0])


def qnormalize(q: np.ndarray) -> np.ndarray:
    """``(..., 4)`` quaternions scaled to unit norm (zero quaternions become identity)."""
    norm = np.sqrt((q * q).sum(-1, keepdims=True))
    unit = q / np.maximum(norm, _EPS)
    if np.all(norm > _EPS):
        return unit
    identity = np.zeros_like(q)
    identity[..., 0] = 1.0
    return np.where(norm > _EPS, unit, identity)


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` of ``(..., 4)`` quaternions (``b`` first, then ``a``)."""
    a, b = np.asarray(a), np.asarray(b)
    aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack((aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw), -1)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(..., 3)`` cross products of broadcastable ``(..., 3)`` vectors.

    The same products as :func:`numpy.cross`, without its axis handling, which dominates for
    the few vectors of a streamed frame.
    """
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), -1)


def qapply(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(..., 3)`` vectors ``v`` rotated by unit quaternions ``q`` ``(..., 4)``."""
    w, u = q[..., :1], q[..., 1:]
    uv = cross(u, v)
    return v + 2.0 * (w * uv + cross(u, uv))


def qmatrix(q: np.ndarray) -> np.ndarray:
    """``(..., 3, 3)`` rotation matrices of ``(..., 4)`` quaternions (normalized first)."""
    w, x, y, z = np.moveaxis(qnormalize(q), -1, 0)
    m = np.stack((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                  2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                  2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)), -1)
    return m.reshape(*q.shape[:-1], 3, 3)


def expmap_to_quat(v: np.ndarray) -> np.ndarray:
    """Exponential map: ``(..., 3)`` axis-angle vectors to ``(..., 4)`` unit quaternions."""
    angle = np.sqrt((v * v).sum(-1, keepdims=True))
    half = 0.5 * angle
    small = angle < 1e-4
    k = np.where(small, 0.5 - angle * angle / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    return np.concatenate((np.cos(half), v * k), -1)


def quat_to_expmap(q: np.ndarray) -> np.ndarray:
    """Logarithmic map: ``(..., 4)`` quaternions to ``(..., 3)`` axis-angle, angle in [0, pi]."""
    q = qnormalize(q)
    q = np.where(q[..., :1] < 0, -q, q)
    sin_half = np.sqrt((q[..., 1:] ** 2).sum(-1, keepdims=True))
    half = np.arctan2(sin_half, q[..., :1])
    small = sin_half < 1e-6
    k = np.where(small, 2.0 / np.maximum(q[..., :1], _EPS),
                 2.0 * half / np.where(small, 1.0, sin_half))
    return q[..., 1:] * k


def yaw_quat(angle: np.ndarray) -> np.ndarray:
    """Rotations about ``+Y``: ``(...,)`` radians to ``(..., 4)`` quaternions."""
    half = 0.5 * np.asarray(angle, dtype=np.float64)
    zero = np.zeros_like(half)
    return np.stack((np.cos(half), zero, np.sin(half), zero), -1)
