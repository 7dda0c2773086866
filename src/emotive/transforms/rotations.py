"""Rotation representations as pure, batched torch functions.

Every function broadcasts over any number of leading dimensions ``...`` and is differentiable.

Conventions:

* Quaternions are ``(..., 4)`` tensors, real part first: ``(w, x, y, z)``. Functions that
  produce quaternions return unit quaternions; ``q`` and ``-q`` are the same rotation.
* Rotation matrices are ``(..., 3, 3)`` and act on column vectors: ``v' = R @ v``.
* Euler angles are ``(..., 3)`` in radians, ``angles[..., i]`` being the angle about the axis
  ``order[i]``, composed intrinsically: ``R = R_order[0] @ R_order[1] @ R_order[2]``. This is
  the convention of BVH channel lists (``Zrotation Xrotation Yrotation`` is order ``"ZXY"``).
* Axis-angle (exponential map) vectors are ``(..., 3)``: unit axis times angle in radians.
* The 6D representation is ``(..., 6)``: the first two columns of the rotation matrix,
  concatenated (column 0 then column 1).

NumPy callers use :mod:`emotive.transforms.np_rotations`, which wraps these kernels.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}
_EPS = 1e-12


def _check_last(x: torch.Tensor, size: int, name: str) -> None:
    if x.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {tuple(x.shape)}")


def _check_component(x: torch.Tensor, size: int, name: str, dim: int) -> None:
    if x.shape[dim] != size:
        where = "(..., {0})" if dim == -1 else "(..., {0}, B)"
        raise ValueError(f"{name} must have shape {where.format(size)}, got {tuple(x.shape)}")


def _check_order(order: str) -> str:
    order = order.upper()
    if order not in EULER_ORDERS:
        raise ValueError(f"Euler order must be one of {EULER_ORDERS}, got {order!r}")
    return order


def quaternion_identity(shape: tuple[int, ...] = (), dtype=None, device=None) -> torch.Tensor:
    """Identity quaternions of shape ``(*shape, 4)``."""
    q = torch.zeros((*shape, 4), dtype=dtype, device=device)
    q[..., 0] = 1.0
    return q


def quaternion_normalize(q: torch.Tensor) -> torch.Tensor:
    """Scale ``(..., 4)`` quaternions to unit norm (zero quaternions become identity)."""
    _check_last(q, 4, "q")
    norm = q.norm(dim=-1, keepdim=True)
    identity = torch.zeros_like(q)
    identity[..., 0] = 1.0
    return torch.where(norm > _EPS, q / norm.clamp_min(_EPS), identity)


#: The Hamilton product as ``(a * b)_i = sum_k SIGN[i, k] a_k b_{INDEX[i, k]}``: one gather,
#: two products and a sum instead of sixteen products (a few tensor operations per call matter
#: in the per-frame step of many agents, and this form exports to ONNX as it is).
_HAMILTON_INDEX = (0, 1, 2, 3, 1, 0, 3, 2, 2, 3, 0, 1, 3, 2, 1, 0)
_HAMILTON_SIGN = ((1, -1, -1, -1), (1, 1, 1, -1), (1, -1, 1, 1), (1, 1, -1, 1))
_CROSS_INDEX = ((1, 2, 0), (2, 0, 1))
_CONSTANTS: dict[tuple, torch.Tensor] = {}


def _constant(name: str, values, like: torch.Tensor, dtype=None, shape=None) -> torch.Tensor:
    """A cached constant tensor on ``like``'s device (in ``like``'s dtype unless ``dtype``)."""
    dtype = like.dtype if dtype is None else dtype
    key = (name, dtype, like.device, shape)
    if key not in _CONSTANTS:
        value = torch.tensor(values, dtype=dtype, device=like.device)
        _CONSTANTS[key] = value if shape is None else value.reshape(shape)
    return _CONSTANTS[key]


def quaternion_multiply(a: torch.Tensor, b: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """Hamilton product ``a * b`` of quaternions (rotation ``b`` first, then ``a``).

    Args:
        a: quaternions with their 4 components along ``dim``, broadcast with ``b`` over the
            other dimensions: ``(..., 4)`` by default; ``dim=-2`` takes ``(..., 4, B)``,
            the batch last, so that every arithmetic operation runs over long contiguous
            rows (several times faster on many small quaternions).
        b: quaternions, the same way.
        dim: the component dimension, ``-1`` or ``-2``.
    """
    if dim not in (-1, -2):
        raise ValueError(f"dim must be -1 or -2, got {dim}")
    _check_component(a, 4, "a", dim)
    _check_component(b, 4, "b", dim)
    index = _constant("hamilton_index", _HAMILTON_INDEX, b, torch.long)
    shape = (4, 4) if dim == -1 else (4, 4, 1)
    sign = _constant("hamilton_sign", _HAMILTON_SIGN, b, shape=shape)
    terms = b.index_select(dim, index).unflatten(dim, (4, 4))
    return (terms * (sign * a.unsqueeze(dim - 1))).sum(dim)


def quaternion_conjugate(q: torch.Tensor) -> torch.Tensor:
    """Conjugate ``(w, -x, -y, -z)`` of ``(..., 4)`` quaternions."""
    _check_last(q, 4, "q")
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def quaternion_invert(q: torch.Tensor) -> torch.Tensor:
    """Inverse of ``(..., 4)`` quaternions (the conjugate divided by the squared norm)."""
    return quaternion_conjugate(q) / (q * q).sum(-1, keepdim=True).clamp_min(_EPS)


def quaternion_apply(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate ``(..., 3)`` vectors ``v`` by unit quaternions ``q`` of shape ``(..., 4)``."""
    _check_last(q, 4, "q")
    _check_last(v, 3, "v")
    shape = torch.broadcast_shapes(q.shape[:-1], v.shape[:-1])
    q = q.expand(*shape, 4)
    v = v.expand(*shape, 3)
    w = q[..., :1]
    u = q[..., 1:]
    # v' = v + 2 w (u x v) + 2 u x (u x v), valid for unit q; cheaper than two products.
    uv = torch.linalg.cross(u, v)
    return v + 2.0 * (w * uv + torch.linalg.cross(u, uv))


def cross_product(a: torch.Tensor, b: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """Cross products of 3-vectors along ``dim`` (``-1``: ``(..., 3)``; ``-2``: ``(..., 3, B)``).

    Gathers along ``dim`` and products, which broadcast and export to ONNX as they are.
    """
    first = _constant("cross_first", _CROSS_INDEX[0], a, torch.long)
    second = _constant("cross_second", _CROSS_INDEX[1], a, torch.long)
    return (a.index_select(dim, first) * b.index_select(dim, second)
            - a.index_select(dim, second) * b.index_select(dim, first))


def quaternion_rotate(q: torch.Tensor, v: torch.Tensor, dim: int = -1) -> torch.Tensor:
    """:func:`quaternion_apply` in a few operations, as it exports to ONNX.

    ``q`` holds 4 components and ``v`` 3 along ``dim`` (``-1`` or ``-2``, as in
    :func:`quaternion_multiply`); the result has the shape of ``v`` broadcast with ``q``.
    """
    w, u = q.narrow(dim, 0, 1), q.narrow(dim, 1, 3)
    uv = cross_product(u, v, dim)
    return v + 2.0 * (w * uv + cross_product(u, uv, dim))


def quaternion_continuity(q: torch.Tensor, dim: int = 0) -> torch.Tensor:
    """Flip signs along ``dim`` so consecutive quaternions lie in the same hemisphere.

    Args:
        q: ``(..., 4)`` quaternions.
        dim: the leading (time) dimension along which to make them continuous.

    Returns:
        Quaternions of the same shape representing the same rotations, with
        ``dot(q[t], q[t-1]) >= 0`` for every ``t``.
    """
    _check_last(q, 4, "q")
    dim = dim % q.dim()
    if dim == q.dim() - 1:
        raise ValueError("dim must index a leading dimension, not the quaternion components")
    n = q.shape[dim]
    if n < 2:
        return q
    prev = q.narrow(dim, 0, n - 1)
    cur = q.narrow(dim, 1, n - 1)
    flips = ((prev * cur).sum(-1, keepdim=True) < 0).to(q.dtype)
    # The sign of frame t is the parity of the flips up to t.
    parity = torch.cumsum(flips, dim=dim) % 2
    first = torch.zeros_like(q.narrow(dim, 0, 1)[..., :1])
    sign = 1.0 - 2.0 * torch.cat((first, parity), dim=dim)
    return q * sign


def quaternion_slerp(a: torch.Tensor, b: torch.Tensor, t: torch.Tensor | float) -> torch.Tensor:
    """Spherical linear interpolation between unit quaternions along the shorter arc.

    Args:
        a: ``(..., 4)`` unit quaternions, the start.
        b: ``(..., 4)`` unit quaternions, the end.
        t: interpolation weights broadcastable to ``(...,)``; 0 gives ``a``, 1 gives ``b``.

    Returns:
        ``(..., 4)`` unit quaternions.
    """
    _check_last(a, 4, "a")
    _check_last(b, 4, "b")
    t = torch.as_tensor(t, dtype=a.dtype, device=a.device)[..., None]
    dot = (a * b).sum(-1, keepdim=True)
    b = torch.where(dot < 0, -b, b)
    dot = dot.abs()
    # Nearly equal rotations interpolate linearly; keeping them out of acos keeps the gradient
    # finite (acos has an infinite slope at 1).
    close = dot > 1.0 - 1e-9
    theta = torch.acos(torch.where(close, torch.zeros_like(dot), dot))
    sin_theta = torch.sin(theta)
    safe = torch.where(close, torch.ones_like(sin_theta), sin_theta)
    wa = torch.where(close, 1.0 - t, torch.sin((1.0 - t) * theta) / safe)
    wb = torch.where(close, t, torch.sin(t * theta) / safe)
    return quaternion_normalize(wa * a + wb * b)


def quaternion_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """Convert ``(..., 4)`` quaternions (normalized first) to ``(..., 3, 3)`` rotation matrices."""
    _check_last(q, 4, "q")
    w, x, y, z = quaternion_normalize(q).unbind(-1)
    m = torch.stack(
        (
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ),
        dim=-1,
    )
    return m.reshape(*q.shape[:-1], 3, 3)


def matrix_to_quaternion(m: torch.Tensor) -> torch.Tensor:
    """Convert ``(..., 3, 3)`` rotation matrices to ``(..., 4)`` unit quaternions with ``w >= 0``.

    Uses the numerically best of the four candidate formulas per matrix (largest diagonal term).
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"m must have shape (..., 3, 3), got {tuple(m.shape)}")
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # 4*w^2, 4*x^2, 4*y^2, 4*z^2 from the trace; pick the largest for stability.
    sq = torch.stack(
        (1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22),
        dim=-1,
    )
    root = torch.sqrt(sq.clamp_min(_EPS))
    candidates = torch.stack(
        (
            torch.stack((sq[..., 0], m21 - m12, m02 - m20, m10 - m01), -1),
            torch.stack((m21 - m12, sq[..., 1], m10 + m01, m02 + m20), -1),
            torch.stack((m02 - m20, m10 + m01, sq[..., 2], m12 + m21), -1),
            torch.stack((m10 - m01, m20 + m02, m21 + m12, sq[..., 3]), -1),
        ),
        dim=-2,
    ) / (2.0 * root[..., None])
    best = sq.argmax(-1)
    q = torch.gather(candidates, -2, best[..., None, None].expand(*best.shape, 1, 4))[..., 0, :]
    q = torch.where(q[..., :1] < 0, -q, q)
    return quaternion_normalize(q)


def _axis_matrix(axis: str, angle: torch.Tensor) -> torch.Tensor:
    c, s = torch.cos(angle), torch.sin(angle)
    one, zero = torch.ones_like(angle), torch.zeros_like(angle)
    if axis == "X":
        rows = (one, zero, zero, zero, c, -s, zero, s, c)
    elif axis == "Y":
        rows = (c, zero, s, zero, one, zero, -s, zero, c)
    else:
        rows = (c, -s, zero, s, c, zero, zero, zero, one)
    return torch.stack(rows, -1).reshape(*angle.shape, 3, 3)


def euler_to_matrix(angles: torch.Tensor, order: str) -> torch.Tensor:
    """Convert ``(..., 3)`` intrinsic Euler angles (radians) in ``order`` to ``(..., 3, 3)``."""
    _check_last(angles, 3, "angles")
    order = _check_order(order)
    m = _axis_matrix(order[0], angles[..., 0])
    m = m @ _axis_matrix(order[1], angles[..., 1])
    return m @ _axis_matrix(order[2], angles[..., 2])


def matrix_to_euler(m: torch.Tensor, order: str) -> torch.Tensor:
    """Convert ``(..., 3, 3)`` rotation matrices to intrinsic Euler angles in ``order``.

    Returns ``(..., 3)`` radians with the middle angle in ``[-pi/2, pi/2]`` and the others in
    ``(-pi, pi]``. At gimbal lock (middle angle +-pi/2) the third angle is set to zero.
    """
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"m must have shape (..., 3, 3), got {tuple(m.shape)}")
    order = _check_order(order)
    i, j, k = (_AXIS_INDEX[a] for a in order)
    # +1 for cyclic orders (XYZ, YZX, ZXY), -1 for the others.
    s = 1.0 if (j - i) % 3 == 1 else -1.0
    sin_b = (s * m[..., i, k]).clamp(-1.0, 1.0)
    # cos(b) straight from the matrix row keeps b and the lock test accurate near +-pi/2, where
    # asin loses digits; the general formulas stay accurate down to cos(b) ~ sqrt(eps).
    cos_b = torch.hypot(m[..., i, i], m[..., i, j])
    b = torch.atan2(sin_b, cos_b)
    locked = cos_b < 1e-8
    a = torch.atan2(-s * m[..., j, k], m[..., k, k])
    c = torch.atan2(-s * m[..., i, j], m[..., i, i])
    # Gimbal lock: only a +- c is defined; recover it from the j-column block with c = 0.
    a_locked = torch.atan2(s * m[..., k, j], m[..., j, j])
    a = torch.where(locked, a_locked, a)
    c = torch.where(locked, torch.zeros_like(c), c)
    return torch.stack((a, b, c), -1)


def euler_to_quaternion(angles: torch.Tensor, order: str) -> torch.Tensor:
    """Convert ``(..., 3)`` intrinsic Euler angles (radians) in ``order`` to ``(..., 4)``."""
    _check_last(angles, 3, "angles")
    order = _check_order(order)
    half = 0.5 * angles
    c, s = torch.cos(half), torch.sin(half)
    q = None
    for n, axis in enumerate(order):
        part = torch.cat(
            [c[..., n : n + 1]]
            + [s[..., n : n + 1] if a == axis else torch.zeros_like(c[..., :1]) for a in "XYZ"],
            dim=-1,
        )
        q = part if q is None else quaternion_multiply(q, part)
    return q


def quaternion_to_euler(q: torch.Tensor, order: str) -> torch.Tensor:
    """Convert ``(..., 4)`` quaternions to intrinsic Euler angles in ``order`` (radians)."""
    return matrix_to_euler(quaternion_to_matrix(q), order)


def axis_angle_to_quaternion(v: torch.Tensor) -> torch.Tensor:
    """Exponential map: ``(..., 3)`` axis-angle vectors to ``(..., 4)`` unit quaternions."""
    _check_last(v, 3, "v")
    angle = v.norm(dim=-1, keepdim=True)
    half = 0.5 * angle
    # sin(x/2)/x with its Taylor series near zero keeps gradients finite at the identity.
    small = angle < 1e-4
    safe = torch.where(small, torch.ones_like(angle), angle)
    k = torch.where(small, 0.5 - angle * angle / 48.0, torch.sin(half) / safe)
    return torch.cat((torch.cos(half), v * k), -1)


def quaternion_to_axis_angle(q: torch.Tensor) -> torch.Tensor:
    """Logarithmic map: ``(..., 4)`` quaternions to ``(..., 3)`` axis-angle, angle in [0, pi]."""
    _check_last(q, 4, "q")
    q = quaternion_normalize(q)
    q = torch.where(q[..., :1] < 0, -q, q)
    sin_half = q[..., 1:].norm(dim=-1, keepdim=True)
    half = torch.atan2(sin_half, q[..., :1])
    small = sin_half < 1e-6
    safe = torch.where(small, torch.ones_like(sin_half), sin_half)
    k = torch.where(small, 2.0 / q[..., :1].clamp_min(_EPS), 2.0 * half / safe)
    return q[..., 1:] * k


def matrix_to_rotation_6d(m: torch.Tensor) -> torch.Tensor:
    """``(..., 3, 3)`` rotation matrices to the ``(..., 6)`` continuous representation."""
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"m must have shape (..., 3, 3), got {tuple(m.shape)}")
    return torch.cat((m[..., :, 0], m[..., :, 1]), -1)


def rotation_6d_to_matrix(d6: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` (two matrix columns) to ``(..., 3, 3)`` by Gram-Schmidt orthogonalization."""
    _check_last(d6, 6, "d6")
    a = F.normalize(d6[..., :3], dim=-1)
    b = d6[..., 3:]
    b = F.normalize(b - (a * b).sum(-1, keepdim=True) * a, dim=-1)
    c = torch.linalg.cross(a, b)
    return torch.stack((a, b, c), -1)


def quaternion_to_rotation_6d(q: torch.Tensor) -> torch.Tensor:
    """``(..., 4)`` quaternions to the ``(..., 6)`` representation."""
    return matrix_to_rotation_6d(quaternion_to_matrix(q))


def rotation_6d_to_quaternion(d6: torch.Tensor) -> torch.Tensor:
    """``(..., 6)`` representation to ``(..., 4)`` unit quaternions."""
    return matrix_to_quaternion(rotation_6d_to_matrix(d6))


def quaternion_between(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Shortest-arc unit quaternions rotating direction ``u`` onto ``v`` (both ``(..., 3)``)."""
    _check_last(u, 3, "u")
    _check_last(v, 3, "v")
    u = F.normalize(u, dim=-1)
    v = F.normalize(v, dim=-1)
    w = 1.0 + (u * v).sum(-1, keepdim=True)
    axis = torch.linalg.cross(u, v)
    # Opposite vectors: rotate by pi about any axis orthogonal to u.
    ortho = torch.linalg.cross(u, u.new_tensor([1.0, 0.0, 0.0]).expand_as(u))
    ortho2 = torch.linalg.cross(u, u.new_tensor([0.0, 1.0, 0.0]).expand_as(u))
    ortho = torch.where(ortho.norm(dim=-1, keepdim=True) < 1e-6, ortho2, ortho)
    opposite = w < 1e-9
    q = torch.where(opposite, torch.cat((torch.zeros_like(w), ortho), -1), torch.cat((w, axis), -1))
    return quaternion_normalize(q)


def yaw_quaternion(angle: torch.Tensor) -> torch.Tensor:
    """Rotations about the vertical (Y) axis: ``(...,)`` radians to ``(..., 4)``."""
    half = 0.5 * angle
    zero = torch.zeros_like(half)
    return torch.stack((torch.cos(half), zero, torch.sin(half), zero), -1)
