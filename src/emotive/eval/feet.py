"""Foot metrics: skating and ground penetration.

Foot metrics: :func:`foot_skating` (horizontal speed of planted feet) and
:func:`ground_penetration` (depth of heel and toe below the ground).

Conventions (shapes, units) are those of :mod:`emotive.eval.metric_inputs`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints (``J + E`` joints
then end sites where joint roles are looked up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.roles import JointRoles
from emotive.eval.metric_inputs import check_points, check_positive
from emotive.features.contacts import foot_contacts, foot_positions

__all__ = [
    "SKATE_SPEED",
    "FootSkating",
    "GroundPenetration",
    "foot_skating",
    "ground_penetration",
]


#: Horizontal speed (m/s) above which a planted foot counts as skating. Planted heels and toes
#: of Bandai Namco walks move under 0.1 m/s (see :class:`emotive.features.contacts.
#: ContactThresholds`), so faster motion of a foot that should stand still is visible sliding.
SKATE_SPEED = 0.1


@dataclass(frozen=True)
class FootSkating:
    """Sliding of planted feet; every field is ``(...)``.

    Attributes:
        mean_speed: mean horizontal speed of the planted feet, m/s (0 without contacts).
        ratio: share of the planted intervals faster than the threshold (0 without contacts).
        intervals: number of planted (foot, consecutive-frame) intervals measured, to weight
            averages over clips.
    """

    mean_speed: np.ndarray
    ratio: np.ndarray
    intervals: np.ndarray


def foot_skating(
    positions: np.ndarray,
    roles: JointRoles,
    fps: float,
    contacts: np.ndarray | None = None,
    threshold: float = SKATE_SPEED,
) -> FootSkating:
    """Horizontal speed of feet that touch the ground.

    For each foot and each pair of consecutive frames ``t, t + 1`` in which it is in contact,
    its speed is ``min(|dh_heel|, |dh_toe|) * fps``, ``dh`` the ``(x, z)`` displacement of the
    heel (ankle) and toe. Choices: the slower point is taken because a foot rolling over its
    heel or its toe keeps that point still and does not slide; only intervals with contact at
    both ends count, so the swing before a strike is never mistaken for sliding.

    Contacts detected from the motion itself (``contacts=None``) are frames in which a heel or
    toe is low and slow, so they hide fast sliding; for generated motion pass the contacts of
    the ground truth or of the generator. Real captures do not score zero (heels still move at
    strike), so compare against the same metric on real data.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites, ``T >= 2``.
        roles: resolved roles of the rig (heel = ``*_ankle``, toe = ``*_toe``).
        fps: frames per second.
        contacts: ``(..., T, 2)`` bool, left then right foot; ``None`` detects them clip by
            clip with :func:`emotive.features.contacts.foot_contacts`.
        threshold: speed in m/s above which a planted foot counts as skating.

    Returns:
        The :class:`FootSkating` report.

    Raises:
        ValueError: bad shapes, or a non-positive ``fps``.
    """
    p = check_points(positions, "positions", min_frames=2)
    fps = check_positive(fps, "fps")
    if contacts is None:
        clips = p.reshape(-1, *p.shape[-3:])
        found = np.stack([foot_contacts(clip, roles, fps) for clip in clips])
        contacts = found.reshape(*p.shape[:-2], 2)
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.shape != (*p.shape[:-2], 2):
        raise ValueError(f"contacts must have shape {(*p.shape[:-2], 2)} (..., T, 2) to match "
                         f"positions {p.shape}, got {contacts.shape}")
    feet = foot_positions(p, roles)[..., [0, 2]]
    speed = np.linalg.norm(np.diff(feet, axis=-4), axis=-1).min(-1) * fps
    planted = contacts[..., 1:, :] & contacts[..., :-1, :]
    count = planted.sum((-2, -1))
    total = np.where(planted, speed, 0.0).sum((-2, -1))
    fast = (planted & (speed > threshold)).sum((-2, -1)).astype(np.float64)
    denom = np.maximum(count, 1)
    return FootSkating(
        mean_speed=np.where(count > 0, total / denom, 0.0),
        ratio=np.where(count > 0, fast / denom, 0.0),
        intervals=count,
    )


@dataclass(frozen=True)
class GroundPenetration:
    """Depth of heels and toes below the ground; every field is ``(...)``.

    Attributes:
        mean: mean depth over every heel and toe sample (points above the ground count 0),
            metres.
        max: largest depth, metres (0 when nothing goes below the ground).
        ratio: share of heel and toe samples below the ground.
    """

    mean: np.ndarray
    max: np.ndarray
    ratio: np.ndarray


def ground_penetration(
    positions: np.ndarray, roles: JointRoles, ground_height: float = 0.0
) -> GroundPenetration:
    """How far the heels (ankles) and toes go below the ground ``y = ground_height``.

    ``d = max(0, ground_height - y)`` for the heel and toe of both feet in every frame. The
    ankle joint sits centimetres above the sole, so in practice the toes (end sites) are what
    penetrates.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
        ground_height: height of the ground plane, metres.

    Returns:
        The :class:`GroundPenetration` report.

    Raises:
        ValueError: positions are not ``(..., T, J + E, 3)``.
    """
    p = check_points(positions, "positions")
    depth = np.maximum(float(ground_height) - foot_positions(p, roles)[..., 1], 0.0)
    axes = (-3, -2, -1)
    return GroundPenetration(depth.mean(axes), depth.max(axes), (depth > 0).mean(axes))
