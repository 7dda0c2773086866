"""Movement features of Emotive Gaits (section 3.2.4): root joint and stepping features.

Legend: ``T`` frames, ``J + E`` joints followed by end sites. Y is up and the ground is the
XZ plane; "2D" means the ``(x, z)`` projection on the ground.

Following the paper, every feature is per frame (not per second), with backward differences
``tau_t = p_t - p_{t-1}`` of the 2D root positions ``p``:

* ``root_height`` ``h_t``: root height minus its mean over the clip (metres).
* ``root_speed`` ``s_t = |tau_t|`` (metres per frame).
* ``root_speed_lowpass``: ``s`` through a zero-phase Butterworth low-pass filter
  (:data:`LOWPASS_HZ`, :data:`LOWPASS_ORDER`), which keeps the walking pace and removes the
  sway at the stepping frequency (about 1-2.5 Hz in walks).
* ``orientation_difference`` ``delta_t``: unsigned angle in ``[0, pi]`` between the body's
  facing direction and ``tau_t``. The facing direction is computed from world positions (the
  horizontal perpendicular to the hips' and shoulders' left-right axes), never from the root
  rotation, whose forward axis depends on the rig's rest pose. Where the root barely moves
  (``s_t`` below :data:`STILL_SPEED` x ``L`` per second, ``L`` the leg length) the direction of
  travel is undefined and ``delta_t = 0``.
* ``curvature`` ``kappa_t = |tau_t - tau_{t-1}|`` (metres per frame squared).
* ``step_phase`` ``theta_t`` in ``[0, 2 pi)``: 0 at each left foot strike, pi at each right
  strike, linear in between (two strikes of the same foot in a row, a missed strike, span a
  whole 2 pi). Before the first strike and after the last, the phase continues at the rate of
  the nearest half-period, for at most one such half-period, and is held constant beyond (a
  clip that starts or ends standing gets ``omega = 0`` there). With fewer than two strikes
  the phase is constant: 0, or that single strike's phase.
* ``step_frequency`` ``omega_t = theta_t - theta_{t-1}`` wrapped to ``(-pi, pi]`` (radians
  per frame; ``omega * fps / pi`` is steps per second).

The first frames lack predecessors: ``tau_0 = tau_1``, ``omega_0 = omega_1`` and
``kappa_0 = kappa_1 = kappa_2``; clips too short for a difference give zeros.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy import signal

from emotive.core.roles import JointRoles
from emotive.features.affective import role_indices
from emotive.features.contacts import (
    ContactThresholds,
    foot_contacts,
    foot_strikes,
    leg_length,
)

#: Cut-off of the root speed low-pass filter in Hz: half the stepping frequency of the slowest
#: walks (about 1 Hz), so the per-step sway of the root speed is removed (attenuated 17 times
#: at 1 Hz, 257 times at 2 Hz) while changes of pace over a second or more pass.
LOWPASS_HZ = 0.5
#: Butterworth order (applied forwards and backwards, so the magnitude response is squared).
LOWPASS_ORDER = 2
#: Root speed below which the direction of travel is undefined, in leg lengths per second.
STILL_SPEED = 0.05

#: Names of the movement feature columns, in :meth:`MovementFeatures.as_array` order.
MOVEMENT_FEATURE_NAMES: tuple[str, ...] = (
    "root_height", "root_speed", "root_speed_lowpass", "orientation_difference",
    "curvature", "step_phase", "step_frequency",
)

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class MovementFeatures:
    """Per-frame movement features of a clip; every field is ``(T,)`` (see the module doc).

    Attributes:
        root_height: root height minus its clip mean, metres.
        root_speed: 2D root displacement per frame, metres.
        root_speed_lowpass: low-pass filtered ``root_speed``.
        orientation_difference: angle between facing and travel direction, radians in ``[0, pi]``.
        curvature: ``|tau_t - tau_{t-1}|``, metres per frame squared.
        step_phase: stepping phase, radians in ``[0, 2 pi)``.
        step_frequency: phase increment per frame, radians in ``(-pi, pi]``.
    """

    root_height: np.ndarray
    root_speed: np.ndarray
    root_speed_lowpass: np.ndarray
    orientation_difference: np.ndarray
    curvature: np.ndarray
    step_phase: np.ndarray
    step_frequency: np.ndarray

    names = MOVEMENT_FEATURE_NAMES

    def as_array(self) -> np.ndarray:
        """``(T, 7)`` columns in :data:`MOVEMENT_FEATURE_NAMES` order."""
        return np.stack([getattr(self, f.name) for f in fields(self)], axis=1)


def _backward_diff(x: np.ndarray) -> np.ndarray:
    """``x_t - x_{t-1}`` along axis 0, with the first frame copying the second."""
    if len(x) < 2:
        return np.zeros_like(x)
    d = np.diff(x, axis=0)
    return np.concatenate((d[:1], d), axis=0)


def _second_diff(x: np.ndarray) -> np.ndarray:
    """``x_t - 2 x_{t-1} + x_{t-2}`` along axis 0, the first two frames copying the third."""
    if len(x) < 3:
        return np.zeros_like(x)
    d = np.diff(x, n=2, axis=0)
    return np.concatenate((d[:1], d[:1], d), axis=0)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Wrap angles to ``(-pi, pi]``."""
    return np.pi - np.mod(np.pi - angle, TWO_PI)


def root_tangents(root_xz: np.ndarray) -> np.ndarray:
    """``(T, 2)`` backward differences ``tau_t`` of ``(T, 2)`` ground-plane root positions."""
    return _backward_diff(np.asarray(root_xz, dtype=np.float64))


def facing_directions(positions: np.ndarray, roles: JointRoles) -> np.ndarray:
    """Ground-plane facing direction of the body in each frame.

    The left-right axis is ``(l_hip - r_hip) + (l_shoulder - r_shoulder)``; forward is its
    horizontal perpendicular ``left x up`` (with Y up, a body whose left is +X faces +Z).

    Args:
        positions: ``(T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.

    Returns:
        ``(T, 2)`` unit ``(x, z)`` vectors (``(0, 0)`` where hips and shoulders coincide).
    """
    lh, rh, ls, rs = role_indices(roles, ("l_hip", "r_hip", "l_shoulder", "r_shoulder"))
    p = np.asarray(positions, dtype=np.float64)
    left = p[:, lh] - p[:, rh] + p[:, ls] - p[:, rs]
    forward = np.stack((-left[:, 2], left[:, 0]), axis=1)
    norm = np.linalg.norm(forward, axis=1, keepdims=True)
    return np.divide(forward, norm, out=np.zeros_like(forward), where=norm > 1e-12)


def lowpass(
    x: np.ndarray, fps: float, cutoff_hz: float = LOWPASS_HZ, order: int = LOWPASS_ORDER
) -> np.ndarray:
    """Zero-phase Butterworth low-pass of a ``(T,)`` signal sampled at ``fps``.

    Returned unchanged when the cut-off is at or above the Nyquist rate or the clip is too
    short to filter (fewer than 3 frames); edges are padded by odd reflection of up to
    ``T - 1`` frames.
    """
    x = np.asarray(x, dtype=np.float64)
    if len(x) < 3 or cutoff_hz >= 0.5 * fps:
        return x.copy()
    sos = signal.butter(order, cutoff_hz, btype="low", fs=fps, output="sos")
    pad = min(3 * (2 * len(sos) + 1), len(x) - 1)
    return signal.sosfiltfilt(sos, x, padlen=pad)


def stepping_phase(contacts: np.ndarray) -> np.ndarray:
    """Stepping phase ``theta`` from foot contacts (see the module doc for the edge rules).

    Args:
        contacts: ``(T, 2)`` bool, left and right foot.

    Returns:
        ``(T,)`` phase in ``[0, 2 pi)``.
    """
    strikes = foot_strikes(contacts)
    n = len(strikes)
    frames, feet = np.nonzero(strikes)
    if len(frames) == 0:
        return np.zeros(n)
    # Unwrapped phase of each strike: the next value congruent to 0 (left) or pi (right).
    target = feet * np.pi
    phase = np.empty(len(frames))
    phase[0] = target[0]
    if len(frames) > 1:
        step = np.where(feet[1:] != feet[:-1], np.pi, TWO_PI)
        phase[1:] = target[0] + np.cumsum(step)
    t = np.arange(n, dtype=np.float64)
    theta = np.interp(t, frames, phase)  # constant before the first and after the last
    if len(frames) > 1:
        before, after = t < frames[0], t > frames[-1]
        span = frames[1] - frames[0]
        if span > 0:
            rate = (phase[1] - phase[0]) / span
            theta[before] = phase[0] - rate * np.minimum(frames[0] - t[before], span)
        span = frames[-1] - frames[-2]
        if span > 0:
            rate = (phase[-1] - phase[-2]) / span
            theta[after] = phase[-1] + rate * np.minimum(t[after] - frames[-1], span)
    return np.mod(theta, TWO_PI)


def movement_features(
    positions: np.ndarray,
    roles: JointRoles,
    fps: float,
    contacts: np.ndarray | None = None,
    lowpass_hz: float = LOWPASS_HZ,
    thresholds: ContactThresholds | None = None,
) -> MovementFeatures:
    """Root joint and stepping features of a clip.

    Args:
        positions: ``(T, J + E, 3)`` world positions of joints then end sites, Y up.
        roles: resolved roles of the rig.
        fps: frames per second.
        contacts: ``(T, 2)`` bool foot contacts (left, right); detected with
            :func:`emotive.features.contacts.foot_contacts` when ``None``.
        lowpass_hz: cut-off of the root speed low-pass filter.
        thresholds: contact detection settings when ``contacts`` is ``None``.

    Returns:
        The features, each ``(T,)``.
    """
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 3 or p.shape[-1] != 3:
        raise ValueError(f"positions must have shape (T, J + E, 3), got {p.shape}")
    if contacts is None:
        contacts = foot_contacts(p, roles, fps, thresholds)
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.shape != (len(p), 2):
        raise ValueError(f"contacts must have shape ({len(p)}, 2), got {contacts.shape}")
    root = p[:, role_indices(roles, ("root",))[0]]
    height = root[:, 1] - root[:, 1].mean() if len(root) else root[:, 1]
    tau = root_tangents(root[:, [0, 2]])
    speed = np.linalg.norm(tau, axis=1)
    facing = facing_directions(p, roles)
    cross = facing[:, 0] * tau[:, 1] - facing[:, 1] * tau[:, 0]
    dot = (facing * tau).sum(1)
    moving = speed * fps > STILL_SPEED * leg_length(p, roles)
    delta = np.where(moving, np.arctan2(np.abs(cross), dot), 0.0)
    kappa = np.linalg.norm(_second_diff(root[:, [0, 2]]), axis=1)
    theta = stepping_phase(contacts)
    omega = _wrap(_backward_diff(theta))
    return MovementFeatures(
        root_height=height,
        root_speed=speed,
        root_speed_lowpass=lowpass(speed, fps, lowpass_hz),
        orientation_difference=delta,
        curvature=kappa,
        step_phase=theta,
        step_frequency=omega,
    )
