"""Registration of the examples of one action to a reference example (paper section 4).

Gaits (walks, runs: actions whose reference has repeated foot strikes) are registered cycle
by cycle (:class:`GaitCycle`): the canonical timeline is one gait cycle of the reference,
annotated with its contact events (left strike at 0, right strike at ``right``), and every
example frame gets its phase by linear interpolation between its own foot strikes. Takes of a
gait in different styles hold different numbers of steps, and warping whole takes onto each
other matched steps with other steps. Other actions are warped whole, as follows.

Every example is time-aligned to the action's reference (its neutral example) by dynamic time
warping on body-frame poses; the warping gives each example frame a *canonical time*, a
(fractional) frame of the reference. The canonical timeline is what the styles of one action
share: the output pose of style ``o`` for an input frame at canonical time ``tau`` is the pose
of ``o``'s example at ``tau``.

Legend: ``T`` example frames, ``R`` reference frames, ``F`` feature columns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from emotive.transforms.np_rotations import quaternion_apply, yaw_quaternion

#: Weight of the velocity columns against the pose columns in the warping features.
VELOCITY_WEIGHT = 0.5
#: Smoothing (frames) of the canonical time after warping; removes the staircase of the path.
TAU_SMOOTHING = 2.0
#: Bounds of the local time rate d tau / d frame.
RATE_BOUNDS = (0.05, 20.0)


def body_features(points: np.ndarray, yaws: np.ndarray, root_slot: int = 0) -> np.ndarray:
    """``(T, F)`` features for warping.

    Role points relative to the root on the ground and turned to face +Z, and their velocities.

    Args:
        points: ``(T, P, 3)`` point clouds.
        yaws: ``(T,)`` headings.
        root_slot: column of the root role among the ``P`` points.
    """
    rel = points - points[:, root_slot:root_slot + 1] * np.array([1.0, 0.0, 1.0])
    turn = np.broadcast_to(yaw_quaternion(-yaws)[:, None], (*rel.shape[:2], 4))
    body = quaternion_apply(turn, rel)
    vel = np.gradient(body, axis=0) if len(body) > 1 else np.zeros_like(body)
    return np.concatenate((body.reshape(len(body), -1),
                           VELOCITY_WEIGHT * vel.reshape(len(body), -1)), 1)


def dtw_path(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Dynamic time warping of two feature sequences.

    The cumulative cost is filled one anti-diagonal at a time (each diagonal is one vector
    operation), with the symmetric steps (1, 0), (0, 1), (1, 1).

    Args:
        a: ``(T, F)`` features.
        b: ``(R, F)`` features.

    Returns:
        Matched indices into ``a`` and ``b`` (monotone, from ``(0, 0)`` to ``(T-1, R-1)``)
        and the mean cost along the path.
    """
    n, m = len(a), len(b)
    cost = (np.sum(a * a, 1)[:, None] + np.sum(b * b, 1)[None] - 2.0 * a @ b.T)
    cost = np.sqrt(np.maximum(cost, 0.0))
    acc = np.full((n + 1, m + 1), np.inf)
    acc[0, 0] = 0.0
    for d in range(2, n + m + 1):
        i = np.arange(max(1, d - m), min(n, d - 1) + 1)
        j = d - i
        best = np.minimum(np.minimum(acc[i - 1, j], acc[i, j - 1]), acc[i - 1, j - 1])
        acc[i, j] = cost[i - 1, j - 1] + best
    path_i, path_j = [n - 1], [m - 1]
    i, j = n, m
    while i > 1 or j > 1:
        steps = ((i - 1, j - 1), (i - 1, j), (i, j - 1))
        i, j = min(steps, key=lambda s: acc[s])
        path_i.append(i - 1)
        path_j.append(j - 1)
    pi, pj = np.array(path_i[::-1]), np.array(path_j[::-1])
    return pi, pj, float(acc[n, m] / len(pi))


def canonical_time(path_a: np.ndarray, path_b: np.ndarray, frames: int) -> np.ndarray:
    """``(T,)`` canonical time of each example frame from a warping path.

    Each frame takes the mean reference frame it was matched to; the result is smoothed and
    made strictly increasing, so that every frame has a positive rate.

    Args:
        path_a: matched example frames.
        path_b: matched reference frames.
        frames: ``T``, the example's length.
    """
    total = np.bincount(path_a, weights=path_b, minlength=frames)
    count = np.bincount(path_a, minlength=frames)
    tau = total / np.maximum(count, 1)
    if frames > 1 and TAU_SMOOTHING > 0:
        tau = gaussian_filter1d(tau, TAU_SMOOTHING, mode="nearest")
    floor = RATE_BOUNDS[0] * np.arange(frames)
    return np.maximum.accumulate(tau - floor) + floor


def time_rate(tau: np.ndarray) -> np.ndarray:
    """``(T,)`` local rate ``d tau / d frame`` of a canonical time, bounded."""
    if len(tau) < 2:
        return np.ones(len(tau))
    return np.clip(np.gradient(tau), *RATE_BOUNDS)


def register(features: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, float]:
    """Canonical time ``(T,)`` of an example against a reference, and the warping cost.

    Args:
        features: ``(T, F)`` :func:`body_features` of the example.
        reference: ``(R, F)`` the same of the reference.
    """
    pa, pb, cost = dtw_path(features, reference)
    return canonical_time(pa, pb, len(features)), cost


def frame_at(tau: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Fractional example frames at canonical times ``target`` (inverse of ``tau``).

    Args:
        tau: ``(T,)`` increasing canonical time of the example's frames.
        target: ``(N,)`` canonical times.

    Returns:
        ``(N,)`` example frames, held at the ends.
    """
    return np.interp(target, tau, np.arange(len(tau), dtype=np.float64))


# ---------------------------------------------------------------------- gait cycles


#: A group is registered by gait cycles when its reference has at least this many strikes of
#: each foot (otherwise: dynamic time warping of whole takes).
MIN_STRIKES = 2


def strike_events(contacts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames where a foot lands, and which foot, in time order.

    Frames where a foot lands (rising edges of ``(T, 2)`` contacts) and which foot
    (``0`` left, ``1`` right), in time order.
    """
    c = np.asarray(contacts, dtype=bool)
    rise = np.zeros_like(c)
    rise[1:] = c[1:] & ~c[:-1]
    frames, feet = np.nonzero(rise)
    order = np.lexsort((feet, frames))
    return frames[order].astype(np.int64), feet[order].astype(np.int64)


@dataclass(frozen=True)
class GaitCycle:
    """The canonical gait cycle of a cyclic action.

    The canonical gait cycle of a cyclic action (paper section 4: the reference's contact
    events annotate the canonical timeline).

    Canonical time runs over ``[0, length)`` and wraps: the left foot lands at 0, the right
    foot at ``right``.

    Attributes:
        length: canonical frames per cycle (the reference's median cycle).
        right: canonical time of the right foot's strike.
    """

    length: float
    right: float

    @classmethod
    def of(cls, contacts: np.ndarray) -> GaitCycle | None:
        """The cycle of a reference clip's ``(T, 2)`` contacts, or None.

        The cycle of a reference clip's ``(T, 2)`` contacts, or None when it has fewer
        than :data:`MIN_STRIKES` strikes of either foot (not a gait).
        """
        frames, feet = strike_events(contacts)
        left, right = frames[feet == 0], frames[feet == 1]
        if len(left) < MIN_STRIKES or len(right) < MIN_STRIKES - 1:
            return None
        length = float(np.round(np.median(np.diff(left))))
        offsets = [(r - left[left <= r].max()) / length for r in right if (left <= r).any()]
        offsets = [o for o in offsets if 0.0 < o < 1.0]
        if not length > 0 or not offsets:
            return None
        return cls(length, float(np.median(offsets)) * length)

    def unwrapped(self, contacts: np.ndarray) -> np.ndarray | None:
        """``(T,)`` unwrapped canonical time of a clip, 0 at its first left strike.

        Between consecutive strikes the canonical time runs linearly (left -> right strike:
        ``right`` canonical frames, right -> left: ``length - right``, same foot twice: a whole
        cycle); before the first and after the last strike it goes on at the rate of the
        nearest half cycle. None when the clip has fewer than two strikes.
        """
        frames, feet = strike_events(contacts)
        n = len(contacts)
        if len(frames) < 2:
            return None
        values = np.zeros(len(frames))
        values[0] = 0.0 if feet[0] == 0 else self.right
        for i in range(1, len(frames)):
            if feet[i] == feet[i - 1]:
                gap = self.length
            elif feet[i] == 1:
                gap = self.right
            else:
                gap = self.length - self.right
            values[i] = values[i - 1] + gap
        # Strikes of both feet on one frame: keep the first of each frame.
        keep = np.concatenate(([True], np.diff(frames) > 0))
        frames, values = frames[keep], values[keep]
        if len(frames) < 2:
            return None
        t = np.arange(n, dtype=np.float64)
        u = np.interp(t, frames, values)
        lo = np.clip((values[1] - values[0]) / (frames[1] - frames[0]), *RATE_BOUNDS)
        hi = np.clip((values[-1] - values[-2]) / (frames[-1] - frames[-2]), *RATE_BOUNDS)
        u = np.where(t < frames[0], values[0] - (frames[0] - t) * lo, u)
        u = np.where(t > frames[-1], values[-1] + (t - frames[-1]) * hi, u)
        first_left = values[int(np.argmax(feet[keep] == 0))] if (feet[keep] == 0).any() else 0.0
        return u - first_left

    def wrap(self, unwrapped: np.ndarray) -> np.ndarray:
        """Canonical time in ``[0, length)`` of unwrapped canonical time."""
        return np.mod(unwrapped, self.length)


def unwrapped_rate(unwrapped: np.ndarray) -> np.ndarray:
    """``(T,)`` canonical frames per frame of an unwrapped canonical time, bounded."""
    return time_rate(unwrapped)
