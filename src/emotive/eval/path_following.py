"""Path following: distance from the path and facing error.

Path following: distance of the root from a 2D polyline, by
:func:`emotive.paths.closest_points`, and angle between facing and the path's tangent.

Conventions (shapes, units) are those of :mod:`emotive.eval.metric_inputs`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints (``J + E`` joints
then end sites where joint roles are looked up), ``P`` vertices of a path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.roles import JointRoles
from emotive.eval.metric_inputs import check_points
from emotive.features.affective import role_indices
from emotive.features.movement import facing_directions
from emotive.paths import closest_points

__all__ = [
    "PathFollowing",
    "path_following",
]


@dataclass(frozen=True)
class PathFollowing:
    """Deviation from a desired path, per frame.

    Attributes:
        position_deviation: ``(..., T)`` distance of the root's ``(x, z)`` from the path,
            metres.
        heading_deviation: ``(..., T)`` unsigned angle between the body's facing and the
            path's tangent at the nearest point, degrees in ``[0, 180]``.
    """

    position_deviation: np.ndarray
    heading_deviation: np.ndarray


def path_following(positions: np.ndarray, roles: JointRoles, path: np.ndarray) -> PathFollowing:
    """How closely a character follows a desired 2D polyline path.

    Position deviation is the distance from the root's ``(x, z)`` to the path
    (:func:`emotive.paths.closest_points`); heading deviation is the unsigned angle
    ``atan2(|f x u|, f . u)`` between the facing direction ``f``
    (:func:`emotive.features.movement.facing_directions`, from hips and shoulders) and the
    path's unit tangent ``u`` at that nearest point.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
        path: ``(P, 2)`` ``(x, z)`` vertices in walking order, ``P >= 2``.

    Returns:
        The per-frame :class:`PathFollowing` deviations.

    Raises:
        ValueError: bad shapes or a degenerate path.
    """
    p = check_points(positions, "positions")
    root = p[..., role_indices(roles, ("root",))[0], :][..., [0, 2]]
    distance, _, tangent, _ = closest_points(root, path)
    facing = facing_directions(p.reshape(-1, *p.shape[-2:]), roles).reshape(*p.shape[:-2], 2)
    cross = facing[..., 0] * tangent[..., 1] - facing[..., 1] * tangent[..., 0]
    dot = (facing * tangent).sum(-1)
    return PathFollowing(distance, np.degrees(np.arctan2(np.abs(cross), dot)))
