"""The 18 pose affective features of Emotive Gaits (section 3.2.3).

11 angles, 4 distance ratios and 3 area ratios per frame, as one differentiable torch kernel with a
NumPy wrapper.

Legend: ``...`` any leading (batch, time) dimensions, ``R`` the :data:`AFFECTIVE_ROLES`
positions, ``J + E`` joints followed by end sites (see
:meth:`emotive.core.Motion.positions_with_end_sites`).

Definitions (``docs/affective-features.md`` is the authoritative table): ``angle(a, b, c)`` is
the angle at ``b`` between ``b -> a`` and ``b -> c`` in radians, ``d(a, b)`` the Euclidean
distance, ``area(a, b, c)`` the area of triangle ``abc``. Every feature is a ratio of lengths,
a ratio of areas or an angle, so it is unchanged by uniform scaling, rotation and translation
of the whole pose.

Degenerate input (coincident joints, collinear triangles) gives finite values and finite
gradients: lengths are ``sqrt(|x|^2 + eps^2)`` and angles are ``atan2(|u x v|, u . v)`` of
the unit-normalised arms with a tiny floor under ``|u x v|`` (no ``acos``, whose gradient is
infinite at 0 and pi). A zero-length arm gives an angle of pi/2; a ratio of two zero
lengths (or areas) gives 1.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import torch

from emotive.core.roles import JointRoles
from emotive.errors import RigError
from emotive.transforms.numpy_bridge import numpy_kernel
from emotive.transforms.rotations import cross_product

#: Roles the features use, in the order the kernel expects along the ``R`` axis.
AFFECTIVE_ROLES: tuple[str, ...] = (
    "root", "spine", "neck", "head",
    "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
    "l_handtip", "r_handtip",
    "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe",
)

# (name, kind, roles): angles name (a, b, c); distance ratios (a, b, c, d) for
# d(a, b) / d(c, d); area ratios (a, b, c, d, e, f) for area(a, b, c) / area(d, e, f).
_TABLE: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("shoulders_angle_at_spine", "angle", ("r_shoulder", "spine", "l_shoulder")),
    ("wrists_angle_at_spine", "angle", ("r_wrist", "spine", "l_wrist")),
    ("l_handtip_neck_root_ratio", "distance_ratio", ("l_handtip", "neck", "l_handtip", "root")),
    ("r_handtip_neck_root_ratio", "distance_ratio", ("r_handtip", "neck", "r_handtip", "root")),
    ("handtips_torso_ratio", "distance_ratio", ("l_handtip", "r_handtip", "neck", "root")),
    ("shoulders_spine_root_area_ratio", "area_ratio",
     ("r_shoulder", "spine", "l_shoulder", "r_shoulder", "root", "l_shoulder")),
    ("wrists_spine_root_area_ratio", "area_ratio",
     ("r_wrist", "spine", "l_wrist", "r_wrist", "root", "l_wrist")),
    ("l_elbow_angle", "angle", ("l_shoulder", "l_elbow", "l_wrist")),
    ("r_elbow_angle", "angle", ("r_shoulder", "r_elbow", "r_wrist")),
    ("head_neck_l_shoulder_angle", "angle", ("head", "neck", "l_shoulder")),
    ("head_neck_r_shoulder_angle", "angle", ("head", "neck", "r_shoulder")),
    ("head_root_l_knee_angle", "angle", ("head", "root", "l_knee")),
    ("head_root_r_knee_angle", "angle", ("head", "root", "r_knee")),
    ("toes_torso_ratio", "distance_ratio", ("l_toe", "r_toe", "neck", "root")),
    ("toes_angle_at_root", "angle", ("r_toe", "root", "l_toe")),
    ("l_knee_angle", "angle", ("l_hip", "l_knee", "l_ankle")),
    ("r_knee_angle", "angle", ("r_hip", "r_knee", "r_ankle")),
    ("handtips_neck_toes_root_area_ratio", "area_ratio",
     ("r_handtip", "neck", "l_handtip", "r_toe", "root", "l_toe")),
)

#: The 18 feature names, in the stable order of the table (feature ``k`` is column ``k - 1``).
AFFECTIVE_FEATURE_NAMES: tuple[str, ...] = tuple(name for name, _, _ in _TABLE)
#: Kind of each feature: ``"angle"`` (radians), ``"distance_ratio"`` or ``"area_ratio"``.
AFFECTIVE_FEATURE_KINDS: tuple[str, ...] = tuple(kind for _, kind, _ in _TABLE)
#: Roles each feature is computed from, as in the table.
AFFECTIVE_FEATURE_ROLES: tuple[tuple[str, ...], ...] = tuple(roles for _, _, roles in _TABLE)

#: Default length floor in metres (areas use its square). Far below any body length, so the
#: features of real poses are unaffected; only coincident joints feel it.
DEFAULT_EPS = 1e-6
# Floor under |u x v| of unit arms: angles are exact to ~1e-9 rad, gradients stay finite at 0, pi.
_ANGLE_EPS = 1e-9


def _columns(kind: str) -> tuple[list[int], list[list[int]]]:
    """Output columns of one kind and, per role slot, the role indices of those features."""
    cols = [k for k, kd in enumerate(AFFECTIVE_FEATURE_KINDS) if kd == kind]
    slots = list(zip(*(AFFECTIVE_FEATURE_ROLES[k] for k in cols), strict=True))
    return cols, [[AFFECTIVE_ROLES.index(r) for r in slot] for slot in slots]


def _safe_norm(x: torch.Tensor, eps: float, dim: int = -1) -> torch.Tensor:
    return torch.sqrt((x * x).sum(dim) + eps * eps)


def _angle(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor, eps: float,
           dim: int = -1) -> torch.Tensor:
    u = a - b
    v = c - b
    u = u / _safe_norm(u, eps, dim).unsqueeze(dim)
    v = v / _safe_norm(v, eps, dim).unsqueeze(dim)
    sin = _safe_norm(cross_product(u, v, dim), _ANGLE_EPS, dim)
    return torch.atan2(sin, (u * v).sum(dim))


def _double_area(a: torch.Tensor, b: torch.Tensor, c: torch.Tensor, eps: float,
                 dim: int = -1) -> torch.Tensor:
    return _safe_norm(cross_product(b - a, c - a, dim), eps * eps, dim)


def role_indices(
    roles: JointRoles | Mapping[str, int], names: tuple[str, ...] = AFFECTIVE_ROLES
) -> list[int]:
    """Indices of ``names`` in the joint-then-end-site array, from resolved roles.

    Raises:
        RigError: a role is missing from ``roles``.
    """
    index = roles.index if isinstance(roles, JointRoles) else roles
    missing = [r for r in names if r not in index]
    if missing:
        raise RigError(f"the role map lacks {missing}, which the features need")
    return [int(index[r]) for r in names]


def affective_features(
    positions: torch.Tensor,
    roles: JointRoles | Mapping[str, int] | None = None,
    eps: float = DEFAULT_EPS,
) -> torch.Tensor:
    """The 18 pose affective features of every pose.

    Args:
        positions: ``(..., R, 3)`` world positions of :data:`AFFECTIVE_ROLES` in that order, or,
            with ``roles``, ``(..., J + E, 3)`` positions of joints then end sites.
        roles: resolved roles (:func:`emotive.core.roles.resolve_roles`) or a mapping
            ``role -> index`` into the second-to-last axis; ``None`` when ``positions`` is
            already in :data:`AFFECTIVE_ROLES` order.
        eps: length floor in the units of ``positions`` (areas use ``eps**2``).

    Returns:
        ``(..., 18)`` features in the order of :data:`AFFECTIVE_FEATURE_NAMES`: angles in
        radians in ``[0, pi]``, ratios positive. Differentiable; same dtype and device.

    Raises:
        ValueError: ``positions`` does not have shape ``(..., R, 3)`` (without ``roles``).
        RigError: ``roles`` lacks a role the features need.
    """
    if positions.ndim < 2 or positions.shape[-1] != 3:
        raise ValueError(f"positions must have shape (..., N, 3), got {tuple(positions.shape)}")
    if roles is not None:
        idx = role_indices(roles)
        if max(idx) >= positions.shape[-2]:
            raise ValueError(
                f"roles index up to {max(idx)} but positions hold {positions.shape[-2]} points"
            )
        positions = positions[..., idx, :]
    elif positions.shape[-2] != len(AFFECTIVE_ROLES):
        raise ValueError(
            f"positions must have shape (..., {len(AFFECTIVE_ROLES)}, 3) in AFFECTIVE_ROLES "
            f"order, or pass roles; got {tuple(positions.shape)}"
        )
    return _features(positions, -2, eps)


def affective_features_batch_last(points: torch.Tensor, roles: JointRoles | Mapping[str, int],
                                  eps: float = DEFAULT_EPS) -> torch.Tensor:
    """:func:`affective_features` of points given with the poses last.

    With the poses last every operation runs over long contiguous rows (the per-frame step
    of many agents).

    Args:
        points: ``(J + E, 3, B)`` positions of joints then end sites.
        roles: as in :func:`affective_features`.
        eps: length floor.

    Returns:
        ``(18, B)`` features, in the order of :data:`AFFECTIVE_FEATURE_NAMES`.
    """
    return _features(points, 0, eps, role_indices(roles))


def _index(values: list[int], like: torch.Tensor) -> torch.Tensor:
    return torch.as_tensor(values, dtype=torch.long, device=like.device)


def _features(p: torch.Tensor, axis: int, eps: float,
              lookup: list[int] | None = None) -> torch.Tensor:
    """The features of points along ``axis``, the roles at ``lookup`` (default: in order).

    ``axis`` is ``-2`` for ``(..., R, 3)`` (features ``(..., 18)``) or ``0`` for ``(R, 3, B)``
    (features ``(18, B)``); the components lie next to it.
    """
    dim = -1 if axis == -2 else 1
    out = -1 if axis == -2 else 0
    lookup = list(range(len(AFFECTIVE_ROLES))) if lookup is None else lookup

    def pts(slot: list[int]) -> torch.Tensor:
        return p.index_select(axis, _index([lookup[r] for r in slot], p))

    groups = []
    cols_a, (a, b, c) = _columns("angle")
    groups.append(_angle(pts(a), pts(b), pts(c), eps, dim))
    cols_d, (a, b, c, d) = _columns("distance_ratio")
    groups.append(_safe_norm(pts(a) - pts(b), eps, dim) / _safe_norm(pts(c) - pts(d), eps, dim))
    cols_r, (a, b, c, d, e, f) = _columns("area_ratio")
    groups.append(_double_area(pts(a), pts(b), pts(c), eps, dim)
                  / _double_area(pts(d), pts(e), pts(f), eps, dim))
    # Back from kind-grouped columns to the table's order.
    order = np.argsort(cols_a + cols_d + cols_r).tolist()
    return torch.cat(groups, out).index_select(out, _index(order, p))


_affective_features_np = numpy_kernel(affective_features)


def affective_features_np(
    positions: np.ndarray,
    roles: JointRoles | Mapping[str, int] | None = None,
    eps: float = DEFAULT_EPS,
) -> np.ndarray:
    """NumPy wrapper of :func:`affective_features`: ``(..., R or J + E, 3)`` -> ``(..., 18)``.

    Same arguments and results as the torch kernel; the dtype of ``positions`` is kept.
    """
    return _affective_features_np(np.asarray(positions), roles, eps=eps)
