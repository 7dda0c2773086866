"""Continuity of resampled trajectories: closing the clips into one sequence, fading jumps.

Issue 7, section 2, steps 2 and 4 (paper section 5.3).

* **Closed sequence.** The clips are joined into one closed, continuous sequence: the last
  ``blend`` frames of each clip are cross-faded into the first ``blend`` frames of the next,
  and the last clip into the first (:func:`close_sequences`). The pelvis path (stored as
  per-frame steps) is cross-faded as features; the poses are cross-faded as joint rotations
  (slerp) and their targets recomputed (:func:`pose_junctions`), which keeps every bone length.
* **Jumps.** The bootstraps draw observed successors (the successor rule). Where a chain jumps
  to another passage, its offset fades over about 10 frames (:data:`CARRY`): for the pelvis
  path in feature space (:func:`~emotive.models.lgb.bootstrap.carry_offsets`), for the chains
  after the IK in joint-rotation space (:func:`blend_jumps`). Blending target positions instead
  shortens and stretches the limbs (on sad, forearms off by 1-2 cm in the median frame the IK
  then missed by more than 1 cm); rotations keep every bone length.

Legend: ``T`` frames, ``F`` features per frame, ``C`` clips, ``k`` joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.core.motion import Motion
from emotive.models.lgb.bootstrap import LGBError
from emotive.models.lgb.features import Column, clip_features, layout_columns
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    quaternion_invert,
    quaternion_multiply,
    quaternion_slerp,
    quaternion_to_axis_angle,
)

if TYPE_CHECKING:
    from emotive.ik import Chain

__all__ = [
    "BLEND_FRAMES",
    "CARRY",
    "blend_jumps",
    "close_sequences",
    "pose_junctions",
]


#: Fraction of a jump's offset kept per frame (see the module docstring): a jump between
#: passages fades over about 10 frames, a third of a second.
CARRY = 0.9
#: Frames cross-faded at each junction between clips (half a second at 30 fps).
BLEND_FRAMES = 15


def _smoothstep(blend: int) -> np.ndarray:
    """``(blend,)`` cross-fade weights of the second sequence, rising from 0 to 1."""
    s = (np.arange(blend) + 0.5) / blend
    return s * s * (3.0 - 2.0 * s)


def close_sequences(features: Sequence[np.ndarray], blend: int = BLEND_FRAMES) -> np.ndarray:
    """Join clips into one closed, continuous sequence by cross-fades.

    The last ``blend`` frames of each clip and the first ``blend`` frames of the next (the first
    clip after the last) are replaced by their smoothstep cross-fade, so every junction,
    including the wrap-around, moves continuously from one clip into the next.

    Args:
        features: ``(T_c, F)`` rows of each clip; each needs more than ``2 * blend`` frames.
        blend: frames of each cross-fade.

    Returns:
        ``(sum(T_c) - blend * C, F)`` rows; its last row is followed by its first.

    Raises:
        LGBError: no clip, a clip too short for the cross-fades, or mismatched widths.
    """
    if not features:
        raise LGBError("no clips to join")
    short = [i for i, f in enumerate(features) if len(f) <= 2 * blend]
    if short or len({f.shape[1] for f in features}) != 1:
        raise LGBError(f"every clip needs more than {2 * blend} frames and the same features; "
                       f"clips {short} are too short")
    w = _smoothstep(blend)[:, None]
    parts = []
    for i, cur in enumerate(features):
        prev = features[i - 1]
        parts.append((1.0 - w) * prev[-blend:] + w * cur[:blend])
        parts.append(cur[blend:-blend])
    return np.concatenate(parts)


def pose_junctions(
    observed: np.ndarray,
    motions: Sequence[Motion],
    chains: dict[str, Chain],
    layout: dict[str, Column],
    blend: int = BLEND_FRAMES,
    role_map: Any = None,
) -> None:
    """Recompute the cross-faded frames from cross-faded poses, in place.

    Recompute everything but the pelvis path in the cross-faded frames of
    :func:`close_sequences` from cross-faded poses, in place.

    Cross-fading target positions shortens the limbs between two different poses (on the
    Bandai Namco data by up to several centimetres, which the IK cannot reach); cross-fading
    the joints' local rotations (slerp) keeps every bone length. The motions must share one rig.

    Args:
        observed: ``(sum(T_c) - blend * C, F)`` from :func:`close_sequences` of the motions'
            features.
        motions: the clips, in the order they were joined.
        chains: the IK chains of the rig.
        layout: the feature blocks.
        blend: frames of each cross-fade.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
    """
    w = _smoothstep(blend)
    cols = layout_columns(layout, [k for k in layout if not k.startswith("pelvis:")])
    row = 0
    for i, cur in enumerate(motions):
        prev = motions[i - 1]
        a, b = prev.rotations[-blend:], cur.rotations[:blend]
        # The shorter way round: flip the second quaternion where the two disagree in sign.
        b = np.where(np.sum(a * b, -1, keepdims=True) < 0, -b, b)
        rot = quaternion_slerp(a, b, w[:, None])
        ww = w[:, None, None]
        pos = (1.0 - ww) * prev.positions[-blend:] + ww * cur.positions[:blend]
        mixed = cur.replace(rotations=rot, positions=pos)
        observed[row : row + blend, cols] = clip_features(mixed, chains, layout, role_map)[:, cols]
        row += cur.num_frames - blend


def blend_jumps(rotations: np.ndarray, jumps: np.ndarray, carry: float = CARRY) -> np.ndarray:
    """Fade the joint-rotation discontinuities at jumps over the following frames.

    The rotation analogue of :func:`~emotive.models.lgb.bootstrap.carry_offsets`. At a jump
    frame ``t`` the new passage's previous pose is extrapolated back from its own motion,
    ``p = v^-1 q_t`` with ``v = q_{t+1} q_t^-1``, and the offset
    ``O_t = (O_{t-1} q_{t-1} p^-1)^carry`` takes it to where the joint was; between jumps the
    offset decays, ``O_t = O_{t-1}^carry`` (powers scale the rotation angle). The result is
    ``O_t q_t``: continuous in pose and, to first order, in velocity.

    Args:
        rotations: ``(T, k, 4)`` local rotations, ``w, x, y, z``.
        jumps: ``(T,)`` bool, frames that start a new passage (frame 0 is ignored).
        carry: fraction of the offset kept per frame.

    Returns:
        ``(T, k, 4)`` blended rotations.
    """
    n = len(rotations)
    where = np.flatnonzero(np.asarray(jumps, bool)[1:]) + 1
    if not len(where) or not carry or n < 2:
        return rotations.copy()
    logs = np.empty((len(where), *rotations.shape[1:-1], 3))
    last, last_log = None, None
    for m, t in enumerate(where):
        before = rotations[t - 1]
        if last is not None:
            before = quaternion_multiply(
                axis_angle_to_quaternion(last_log * carry ** (t - 1 - last)), before)
        inv_t = quaternion_invert(rotations[t])
        raw = quaternion_multiply(before, inv_t)
        if t + 1 < n:
            raw = quaternion_multiply(raw, quaternion_multiply(rotations[t + 1], inv_t))
        logs[m] = last_log = carry * quaternion_to_axis_angle(raw)
        last = t
    # For every frame from the first jump on: the last jump at or before it, and its age.
    owner = np.searchsorted(where, np.arange(n), side="right") - 1
    out = rotations.copy()
    live = owner >= 0
    age = np.arange(n)[live] - where[owner[live]]
    offset = axis_angle_to_quaternion(logs[owner[live]] * (carry ** age)[:, None, None])
    out[live] = quaternion_multiply(offset, rotations[live])
    return out
