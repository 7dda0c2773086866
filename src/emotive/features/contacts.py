"""Foot contacts from heel (ankle) and toe height and speed, with hysteresis.

Legend: ``T`` frames, ``J + E`` joints followed by end sites, ``...`` any leading dimensions.

A foot touches the ground in a frame when its heel or its toe is *planted*: low (near that
point's own ground height) and slow. Hysteresis keeps a point planted until it is clearly
lifted or moving, so contacts do not flicker around the thresholds; then contacts shorter
than ``min_contact_s`` are dropped and gaps shorter than ``min_gap_s`` between two contacts
are filled.

Thresholds scale with the rig and the frame rate: heights are fractions of the leg length
(hip -> knee -> ankle, median over the clip) and speeds are leg lengths per second (finite
differences times ``fps``), so the same defaults serve rigs of any size and unit and clips
of any frame rate. The ground height of each point is a low percentile of its own height
over the clip, which absorbs the ankle joint sitting some centimetres above the floor; it
assumes level ground and a clip in which each foot touches it at least ``ground_percentile``
per cent of the time (true of gaits).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import ndimage

from emotive.core.roles import JointRoles
from emotive.features.affective import role_indices

#: Heel and toe roles of the left then the right foot.
FOOT_ROLES: tuple[str, ...] = ("l_ankle", "l_toe", "r_ankle", "r_toe")
#: Names of the contact columns, left then right.
CONTACT_NAMES: tuple[str, ...] = ("contact_left", "contact_right")


@dataclass(frozen=True)
class ContactThresholds:
    """Contact detection settings, relative to the leg length ``L`` and to seconds.

    The defaults were tuned on Bandai Namco walks (``L`` about 0.8 m, 30 fps): a planted heel
    or toe stays within 1 cm of its floor height and moves under 0.1 m/s, a swinging foot
    moves at 1-4 m/s; at heel strike the heel is still moving at 0.3-0.4 m/s. With them,
    left and right strikes alternate in every locomotion clip of both Bandai Namco data sets
    (walks, turns, walking back and sideways, runs, dashes). In runs the foot rolls faster
    than ``speed_off`` during stance, so fewer stance frames are labelled than are on the
    ground, but strikes are still found.

    Attributes:
        height_on: a point may plant below this height above its ground (x ``L``; 0.03 is
            about 2.4 cm).
        height_off: a planted point lifts above this height (x ``L``; about 4 cm).
        speed_on: a point may plant below this speed (x ``L`` per second; about 0.4 m/s).
        speed_off: a planted point is released above this speed (x ``L`` per second;
            about 0.65 m/s).
        ground_percentile: percentile of each point's height over the clip taken as its
            ground height.
        min_contact_s: contacts shorter than this (seconds) are dropped.
        min_gap_s: gaps shorter than this (seconds) between two contacts are filled.
    """

    height_on: float = 0.03
    height_off: float = 0.05
    speed_on: float = 0.5
    speed_off: float = 0.8
    ground_percentile: float = 5.0
    min_contact_s: float = 0.1
    min_gap_s: float = 0.1

    def __post_init__(self) -> None:
        if not (0 < self.height_on <= self.height_off and 0 < self.speed_on <= self.speed_off):
            raise ValueError("contact thresholds need 0 < *_on <= *_off")


def foot_positions(positions: Any, roles: JointRoles) -> Any:
    """Heel (ankle) and toe positions of both feet.

    Args:
        positions: ``(..., J + E, 3)`` NumPy array or torch tensor of joint then end-site
            positions.
        roles: resolved roles of the rig.

    Returns:
        ``(..., 2, 2, 3)`` of the same type: ``[..., foot, point]`` with foot 0 = left,
        1 = right and point 0 = heel (ankle), 1 = toe.
    """
    idx = role_indices(roles, FOOT_ROLES)
    feet = positions[..., idx, :]
    return feet.reshape(*feet.shape[:-2], 2, 2, 3)


def leg_length(positions: np.ndarray, roles: JointRoles) -> float:
    """Median over frames and both legs of the hip -> knee -> ankle length.

    Args:
        positions: ``(T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
    """
    i = role_indices(roles, ("l_hip", "l_knee", "l_ankle", "r_hip", "r_knee", "r_ankle"))
    p = np.asarray(positions)[:, i].reshape(-1, 2, 3, 3)
    length = np.linalg.norm(np.diff(p, axis=-2), axis=-1).sum(-1)
    return float(np.median(length)) if length.size else 0.0


def _hysteresis(on: np.ndarray, off: np.ndarray) -> np.ndarray:
    """State along axis 0: set where ``on``, cleared where ``off``, else held (starts cleared)."""
    decided = on | off
    t = np.arange(on.shape[0]).reshape(-1, *([1] * (on.ndim - 1)))
    last = np.maximum.accumulate(np.where(decided, t, -1), axis=0)
    state = np.take_along_axis(on, np.maximum(last, 0), axis=0)
    return state & (last >= 0)


def _clean_runs(mask: np.ndarray, min_contact: int, min_gap: int) -> np.ndarray:
    """Fill short gaps, then drop short runs, in a ``(T,)`` bool mask.

    Fill interior gaps shorter than ``min_gap`` frames, then drop runs shorter than
    ``min_contact`` frames, in a ``(T,)`` bool mask.
    """
    mask = mask.copy()
    labels, count = ndimage.label(~mask)
    if count:
        sizes = np.bincount(labels)[1:]
        # Gaps touching the clip's ends are not between two contacts: keep them.
        short = (sizes < min_gap) & ~np.isin(np.arange(1, count + 1), [labels[0], labels[-1]])
        mask |= np.isin(labels, np.flatnonzero(short) + 1)
    labels, count = ndimage.label(mask)
    if count:
        sizes = np.bincount(labels)[1:]
        mask &= ~np.isin(labels, np.flatnonzero(sizes < min_contact) + 1)
    return mask


def ground_heights(feet: np.ndarray, thresholds: ContactThresholds | None = None,
                   up_axis: int = 1) -> np.ndarray:
    """``(T, P)`` height of each foot point above its own ground.

    Its ``ground_percentile`` height over the clip.

    Args:
        feet: ``(T, P, 3)`` world positions of the foot points (e.g. the heels and toes of
            :func:`foot_positions`, reshaped).
        thresholds: settings (:class:`ContactThresholds` defaults when ``None``).
        up_axis: index of the vertical coordinate (1: Y up).
    """
    th = thresholds or ContactThresholds()
    height = feet[..., up_axis]
    return height - np.percentile(height, th.ground_percentile, axis=0)


def foot_contacts(
    positions: np.ndarray,
    roles: JointRoles,
    fps: float,
    thresholds: ContactThresholds | None = None,
    up_axis: int = 1,
) -> np.ndarray:
    """Which foot touches the ground in each frame.

    Args:
        positions: ``(T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
        fps: frames per second of the clip.
        thresholds: detection settings (:class:`ContactThresholds` defaults when ``None``).
        up_axis: index of the vertical coordinate (1: Y up).

    Returns:
        ``(T, 2)`` bool, columns left and right foot.
    """
    th = thresholds or ContactThresholds()
    positions = np.asarray(positions, dtype=np.float64)
    n = positions.shape[0]
    if n == 0:
        return np.zeros((0, 2), dtype=bool)
    feet = foot_positions(positions, roles).reshape(n, 4, 3)
    scale = leg_length(positions, roles)
    if not scale > 0:
        return np.zeros((n, 2), dtype=bool)
    height = ground_heights(feet, th, up_axis)
    if n > 1:
        speed = np.linalg.norm(np.gradient(feet, axis=0), axis=-1) * fps
    else:
        speed = np.zeros_like(height)
    on = (height < th.height_on * scale) & (speed < th.speed_on * scale)
    off = (height > th.height_off * scale) | (speed > th.speed_off * scale)
    planted = _hysteresis(on, off & ~on)
    contact = planted.reshape(n, 2, 2).any(-1)
    min_contact = max(1, round(th.min_contact_s * fps))
    min_gap = max(1, round(th.min_gap_s * fps))
    return np.stack([_clean_runs(contact[:, k], min_contact, min_gap) for k in range(2)], 1)


def foot_strikes(contacts: np.ndarray) -> np.ndarray:
    """``(T, 2)`` bool: frames where a contact starts (rising edges; frame 0 never counts)."""
    contacts = np.asarray(contacts, dtype=bool)
    strikes = np.zeros_like(contacts)
    strikes[1:] = contacts[1:] & ~contacts[:-1]
    return strikes
