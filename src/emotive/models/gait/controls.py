"""What a checkpoint needs to animate without data: the rig, a standing pose and walking paces.

Legend: ``J`` joints, ``E`` end sites, ``C`` emotion labels.

At animation time the movement inputs of the network are controls, not measurements: the
stepping phase advances at a step frequency ``omega`` and the low-passed speed ``s_lowpass``
says how fast to walk. :func:`gait_controls` takes both from the training split, per label, as
medians over the walking frames of the ``walk`` clips of that label (frames where the phase
advances and the root moves); a label without such frames gets the median over all labels. The
generator blends them with the emotion weights, so a sad walk is slower than a happy one as in
the data.

Walkers slow down in turns: over the walking frames of the ``walk`` and ``walk-turn-*`` clips,
the low-passed speed relative to its clip's median falls linearly with the path curvature ``k``
(the rate of turn of the body's heading, smoothed over a second, per metre walked); the least
squares slope of that line relative to its intercept is :attr:`GaitControls.turn_slowing`, and
the generator scales its target speed by ``1 - turn_slowing * |k|`` (at least
:data:`MIN_TURN_FACTOR`). On the training split of both data sets: 8 % slower per 1/m.

The standing pose of the default start is the mean, per joint, of the heading-canonical local
rotations of the frames where a ``walk`` clip stands still (root speed under
:data:`STANDING_SPEED`), or of the clips' first frames when none stands. Everything here is a
statistic of the training data, like the feature means in the network's buffers; no motion is
stored.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from emotive.core.skeleton import Skeleton, skeleton_from_dict, skeleton_to_dict
from emotive.errors import DataError
from emotive.transforms.np_rotations import quaternion_mean

#: Root speed (metres per second) under which a frame counts as standing.
STANDING_SPEED = 0.1
#: Column of ``omega`` and of ``s_lowpass`` in the movement inputs, of ``h`` in the root ones.
OMEGA, SPEED_LOWPASS, HEIGHT = 2, 3, 0
#: Lowest factor the turn slowing may put on the target speed.
MIN_TURN_FACTOR = 0.3
#: Contents whose frames measure the slowing in turns.
WALK_CONTENTS = ("walk", "walk-turn-left", "walk-turn-right")


@dataclass(frozen=True, eq=False)
class GaitControls:
    """Per-label walking paces, the standing pose and the rig of a gait checkpoint.

    Attributes:
        labels: the ``C`` labels.
        step_frequency: ``(C,)`` median ``omega`` of walking, radians per frame.
        speed: ``(C,)`` median ``s_lowpass`` of walking, metres per frame.
        standing_rotations: ``(J, 4)`` heading-canonical local rotations of the standing pose.
        standing_positions: ``(J, 3)`` local translations of the standing pose (the mover's
            ground position at the origin, its height kept).
        standing_height: ``h`` (root height minus the clip mean) of standing frames, metres.
        turn_slowing: relative loss of walking speed per 1/m of path curvature.
        mover: joint carrying the world placement (its local transform).
        skeleton: the rig (names, hierarchy, offsets, channels, end sites).
        fps: frame rate of the network.
    """

    labels: tuple[str, ...]
    step_frequency: np.ndarray
    speed: np.ndarray
    standing_rotations: np.ndarray
    standing_positions: np.ndarray
    standing_height: float
    turn_slowing: float
    mover: int
    skeleton: Skeleton
    fps: float

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and numbers (for a ``weights_only`` checkpoint)."""
        return {
            "labels": list(self.labels),
            "step_frequency": self.step_frequency.tolist(),
            "speed": self.speed.tolist(),
            "standing_rotations": self.standing_rotations.tolist(),
            "standing_positions": self.standing_positions.tolist(),
            "standing_height": float(self.standing_height),
            "turn_slowing": float(self.turn_slowing),
            "mover": int(self.mover),
            "fps": float(self.fps),
            "skeleton": skeleton_to_dict(self.skeleton),
        }

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> GaitControls:
        """The controls saved by :meth:`to_dict`.

        Raises:
            KeyError, ValueError: a missing key or a bad value.
        """
        skeleton = skeleton_from_dict(values["skeleton"])
        labels = tuple(values["labels"])
        out = cls(
            labels, np.array(values["step_frequency"], dtype=np.float64),
            np.array(values["speed"], dtype=np.float64),
            np.array(values["standing_rotations"], dtype=np.float64),
            np.array(values["standing_positions"], dtype=np.float64),
            float(values["standing_height"]), float(values["turn_slowing"]),
            int(values["mover"]), skeleton,
            float(values["fps"]),
        )
        n, c = skeleton.num_joints, len(labels)
        if out.step_frequency.shape != (c,) or out.speed.shape != (c,):
            raise ValueError(f"walking paces must have one value per label ({c})")
        if out.standing_rotations.shape != (n, 4) or out.standing_positions.shape != (n, 3):
            raise ValueError(f"the standing pose must have {n} joints")
        return out


def mean_rotations(q: np.ndarray) -> np.ndarray:
    """Per-joint mean of ``(N, J, 4)`` unit quaternions (sign-blind). Returns ``(J, 4)``."""
    return quaternion_mean(q, axis=0)


def gait_controls(data: Any) -> GaitControls:
    """The controls of a :class:`~emotive.models.gait.data.GaitData` (the training split).

    Raises:
        DataError: the data hold no ``walk`` clip.
    """
    offsets = data.clip_offsets
    walk = [k for k, info in enumerate(data.clips) if info.content == "walk"]
    if not walk:
        raise DataError("the training data hold no 'walk' clip to take walking paces from")
    frames = np.concatenate([np.arange(offsets[k], offsets[k + 1]) for k in walk])
    clip_of = np.concatenate([np.full(offsets[k + 1] - offsets[k], k) for k in walk])
    label_of = data.emotions[clip_of].argmax(1)
    omega = data.movement[frames, OMEGA].astype(np.float64)
    speed = data.movement[frames, SPEED_LOWPASS].astype(np.float64)
    still = STANDING_SPEED / data.fps
    walking = (omega > 1e-4) & (speed > still)
    if not walking.any():
        raise DataError("the 'walk' clips of the training data never walk (no phase advance)")
    labels = tuple(data.labels)
    freq = np.full(len(labels), np.median(omega[walking]))
    pace = np.full(len(labels), np.median(speed[walking]))
    for c in range(len(labels)):
        sel = walking & (label_of == c)
        if sel.any():
            freq[c], pace[c] = np.median(omega[sel]), np.median(speed[sel])
    standing = frames[data.root[frames, 1] < still]
    turn = turn_slowing(data, still)
    if not len(standing):
        standing = offsets[walk]
    positions = data.positions[standing].astype(np.float64).mean(0)
    positions[data.mover, [0, 2]] = 0.0
    return GaitControls(
        labels, freq, pace, mean_rotations(data.rotations[standing]), positions,
        float(np.median(data.root[standing, HEIGHT])), turn, int(data.mover), data.skeleton,
        float(data.fps),
    )


def turn_slowing(data: Any, still: float) -> float:
    """The slope of walking speed against path curvature.

    The slope of walking speed against path curvature (see the module docstring), clipped
    to ``[0, 1]``; 0 without turning frames.
    """
    offsets = data.clip_offsets
    curvature, ratio = [], []
    for k, info in enumerate(data.clips):
        if info.content not in WALK_CONTENTS:
            continue
        a, b = offsets[k], offsets[k + 1]
        speed = data.movement[a:b, SPEED_LOWPASS].astype(np.float64)
        walking = speed > still
        if walking.sum() < 2:
            continue
        rate = np.abs(uniform_filter1d(np.gradient(np.unwrap(data.heading[a:b])),
                                       max(1, round(data.fps))))
        curvature.append(rate[walking] / speed[walking])
        ratio.append(speed[walking] / np.median(speed[walking]))
    if not curvature:
        return 0.0
    k, r = np.concatenate(curvature), np.concatenate(ratio)
    (intercept, slope), *_ = np.linalg.lstsq(np.stack((np.ones_like(k), k), 1), r, rcond=None)
    return float(np.clip(-slope / intercept, 0.0, 1.0)) if intercept > 0 else 0.0
