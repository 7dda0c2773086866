"""Frames and valence/arousal context of the FCRBM (issue 6, section 1; paper section 3).

Legend: ``T`` frames, ``J`` joints, ``D`` kept dimensions, ``K`` all dimensions (``4 + 3 J``).

A frame (:func:`frame_vectors`) is, after the transforms above the root role are folded into
it (:func:`emotive.core.root.fold_into_root`):

* the root motion made relative: the ground step of the root role since the previous frame in
  the body frame of that previous frame (sideways, forward; metres), the change of heading
  (radians) and the root height (metres);
* the root role's rotation with its heading removed, as an exponential map (3);
* every other joint's local rotation as an exponential map (3 each; joints that never move
  give constant dimensions).

The first frame of a clip repeats the second frame's step and turn. :class:`FrameCodec` first
expresses every joint's rotation relative to its training mean rotation (the reference, a
quaternion average): an exponential map is discontinuous at angles of π (the vector flips to
the opposite side), and on rigs whose rest pose is far from the identity some joints sit near
π all the time (the upper legs of the Bandai Namco rig: standard deviation 1.7-2.5 rad of the
raw exponential map, most of it flips); relative to the mean they stay far from π, as Grassia
(1998) prescribes. It then removes the dimensions that are constant in the training data
(standard deviation under :data:`CONSTANT_STD`, and for joint rotations under
:data:`CONSTANT_ROTATION_STD`: standardizing a joint axis that moves less than a degree only
blows its capture noise up to unit variance), standardizes the rest with the training mean and
standard deviation and keeps everything the way back needs: the rig, the references, the local
translations of the joints (their training mean: bones do not stretch), the constant values.
:meth:`FrameCodec.decode` integrates the heading and the ground path from the steps and
rebuilds a :class:`~emotive.core.motion.Motion`.

Context (:func:`clip_context`): valence and arousal of the clip's style from
:data:`emotive.data.emotion.VALENCE_AROUSAL`, on the paper's 1-3 scale (1 low, 2 neutral,
3 high): ``2 + v`` for the circumplex value ``v`` in ``[-1, 1]``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import uniform_filter1d

from emotive.core.motion import Motion
from emotive.core.ops import heading
from emotive.core.roles import resolve_roles
from emotive.core.root import fold_into_root
from emotive.core.skeleton import Skeleton, skeleton_from_dict, skeleton_to_dict
from emotive.data.emotion import label_points, style_to_label
from emotive.errors import DataError, RigError
from emotive.features.contacts import foot_contacts, foot_strikes
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    quaternion_apply,
    quaternion_conjugate,
    quaternion_mean,
    quaternion_multiply,
    quaternion_to_axis_angle,
    yaw_quaternion,
)

#: Dimensions whose training standard deviation is below this are constant and left out.
CONSTANT_STD = 1e-6
#: Joint-rotation dimensions (radians, relative to the joint's mean rotation) whose training
#: standard deviation is below this (one degree) are treated as constant too: the knees' side
#: axes and the toes of the Bandai Namco rig move 0.1-0.7 degrees, which is capture noise.
CONSTANT_ROTATION_STD = np.deg2rad(1.0)
#: Columns of the root motion: sideways step, forward step, turn, height.
ROOT_COLUMNS = 4
#: Accepted valence/arousal values (the paper's scale is 1-3; beyond it exaggerates).
CONTEXT_RANGE = (0.25, 5.0)


def _wrap(angle: np.ndarray) -> np.ndarray:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def _prepare(motion: Motion) -> tuple[Motion, int]:
    try:
        roles = resolve_roles(motion.skeleton)
    except Exception as exc:
        raise RigError(f"{motion.metadata.get('name', 'the motion')}: the FCRBM needs a rig "
                       f"with the joint roles (root, hips, legs, ...): {exc}") from exc
    mover = int(roles.index["root"])
    return fold_into_root(motion, mover), mover


def frame_vectors(motion: Motion) -> np.ndarray:
    """``(T, K)`` frames of a clip (see the module docstring); ``T >= 2``.

    Raises:
        RigError: the rig has no joint roles.
        DataError: fewer than two frames, or NaN in the motion.
    """
    name = motion.metadata.get("name", "the motion")
    if motion.num_frames < 2:
        raise DataError(f"{name}: the FCRBM needs at least 2 frames, got {motion.num_frames}")
    if not (np.isfinite(motion.rotations).all() and np.isfinite(motion.positions).all()):
        raise DataError(f"{name}: NaN or infinite values in the motion; repair or drop them")
    motion, mover = _prepare(motion)
    yaw = heading(motion)
    root = motion.positions[:, mover]
    step = np.diff(root[:, [0, 2]], axis=0)
    step3 = np.stack((step[:, 0], np.zeros(len(step)), step[:, 1]), 1)
    body = quaternion_apply(yaw_quaternion(-yaw[:-1]), step3)[:, [0, 2]]
    turn = _wrap(np.diff(yaw))
    body = np.concatenate((body[:1], body))
    turn = np.concatenate((turn[:1], turn))
    local = motion.rotations.copy()
    local[:, mover] = quaternion_multiply(yaw_quaternion(-yaw), local[:, mover])
    expmap = quaternion_to_axis_angle(local)
    return np.concatenate(
        (body, turn[:, None], root[:, 1:2], expmap.reshape(len(local), -1)), axis=1
    )


def _rotation_columns(frames: np.ndarray) -> np.ndarray:
    """``(T, J, 4)`` quaternions of the joint-rotation columns of ``(T, K)`` frames."""
    return axis_angle_to_quaternion(frames[:, ROOT_COLUMNS:].reshape(len(frames), -1, 3))


def mean_rotations(frames: Sequence[np.ndarray]) -> np.ndarray:
    """``(J, 4)`` average rotation of every joint over ``(T, K)`` frames.

    ``(J, 4)`` average rotation of every joint over ``(T, K)`` frames (Markley's average:
    the principal eigenvector of the sum of ``q qᵀ``, blind to the sign of ``q``).
    """
    return quaternion_mean(np.concatenate([_rotation_columns(f) for f in frames]), axis=0)


def _rereference(frames: np.ndarray, reference: np.ndarray, inverse: bool) -> np.ndarray:
    """Joint rotations made relative to ``reference``, or back with ``inverse``.

    Joint rotations of ``(T, K)`` frames made relative to ``reference`` (``q_ref⁻¹ q``), or
    back (``q_ref q``) with ``inverse``.
    """
    ref = np.broadcast_to(reference, (len(frames), *reference.shape))
    q = _rotation_columns(frames)
    q = quaternion_multiply(ref if inverse else quaternion_conjugate(ref), q)
    out = np.array(frames, dtype=np.float64, copy=True)
    out[:, ROOT_COLUMNS:] = quaternion_to_axis_angle(q).reshape(len(frames), -1)
    return out


def clip_context(style: str, frames: int) -> np.ndarray:
    """``(frames, 2)`` valence and arousal (1-3 scale) of a style, e.g. ``"sad"``.

    Raises:
        EmotionError: the style has no valence/arousal entry.
    """
    point = label_points([style_to_label(style)])[0]
    return np.repeat((2.0 + point)[None], frames, axis=0)


def step_rate(visible: np.ndarray, codec: FrameCodec) -> np.ndarray:
    """How fast a clip steps around each frame.

    The clip is decoded (:meth:`FrameCodec.decode`), its foot strikes found
    (:func:`~emotive.features.contacts.foot_strikes`, either foot), and each frame takes the
    rate of the interval between the strikes around it (before the first strike the first
    interval's, after the last the last one's), averaged over a centred window of about a
    second (edges repeated).

    Args:
        visible: ``(T, D)`` encoded frames of one clip (:meth:`FrameCodec.encode`).
        codec: their codec.

    Returns:
        ``(T,)`` steps per second; zeros when the clip has fewer than two strikes.
    """
    motion = codec.decode(visible)
    positions = motion.positions_with_end_sites()
    contacts = foot_contacts(positions, resolve_roles(motion.skeleton), motion.fps)
    strikes = np.flatnonzero(foot_strikes(contacts).any(axis=1))
    if len(strikes) < 2:
        return np.zeros(len(visible))
    rates = motion.fps / np.diff(strikes)
    interval = np.searchsorted(strikes, np.arange(len(visible)), side="right") - 1
    per_frame = rates[np.clip(interval, 0, len(rates) - 1)]
    return uniform_filter1d(per_frame, round(codec.fps) | 1, mode="nearest")


@dataclass(frozen=True, eq=False)
class FrameCodec:
    """Standardization of frames and the way back to motion.

    Attributes:
        keep: ``(D,)`` indices of the kept columns among the ``K``.
        mean: ``(D,)`` training mean of the kept columns.
        std: ``(D,)`` training standard deviation of the kept columns.
        constant: ``(K,)`` training mean of every column (the value of the left-out ones),
            joint rotations relative to ``reference``.
        skeleton: the rig.
        local_positions: ``(J, 3)`` mean local translation of every joint (the root role's
            is replaced by the integrated path).
        mover: the root role joint.
        fps: frame rate.
        reference: ``(J, 4)`` rotation of every joint that the encoded rotations are relative
            to (the training mean; the identity in checkpoints made before it existed).
    """

    keep: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    constant: np.ndarray
    skeleton: Skeleton
    local_positions: np.ndarray
    mover: int
    fps: float
    reference: np.ndarray | None = None

    @classmethod
    def fit(cls, frames: Sequence[np.ndarray], motions: Sequence[Motion]) -> FrameCodec:
        """The codec of training clips.

        Args:
            frames: ``(T_c, K)`` :func:`frame_vectors` of each clip.
            motions: the clips (one rig; their mean local translations are kept).

        Raises:
            DataError: no frames, or clips on different rigs or frame rates.
        """
        if not frames:
            raise DataError("no training frames for the FCRBM")
        first = motions[0]
        for m in motions:
            if m.skeleton.names != first.skeleton.names or m.fps != first.fps:
                raise DataError(f"{m.metadata.get('name')}: every FCRBM training clip must share "
                                f"the rig and frame rate of {first.metadata.get('name')}")
        reference = mean_rotations(frames)
        allf = np.concatenate([_rereference(f, reference, False) for f in frames])
        std = allf.std(0)
        floor = np.full(len(std), CONSTANT_ROTATION_STD)
        floor[:ROOT_COLUMNS] = CONSTANT_STD
        keep = np.flatnonzero(std >= np.maximum(floor, CONSTANT_STD))
        prepared = [_prepare(m) for m in motions]
        positions = np.concatenate([m.positions for m, _ in prepared]).mean(0)
        return cls(keep, allf.mean(0)[keep], std[keep], allf.mean(0), first.skeleton, positions,
                   prepared[0][1], float(first.fps), reference)

    @property
    def dim(self) -> int:
        """``D``, the visible units of the model."""
        return len(self.keep)

    def encode(self, frames: np.ndarray) -> np.ndarray:
        """``(T, K)`` frames -> ``(T, D)`` standardized kept columns (float32)."""
        if self.reference is not None:
            frames = _rereference(frames, self.reference, False)
        return ((frames[:, self.keep] - self.mean) / self.std).astype(np.float32)

    def decode(self, visible: np.ndarray, name: str = "fcrbm") -> Motion:
        """``(T, D)`` standardized frames -> motion starting at the origin facing +Z."""
        v = np.asarray(visible, dtype=np.float64)
        frames = np.repeat(self.constant[None], len(v), axis=0)
        frames[:, self.keep] = v * self.std + self.mean
        if self.reference is not None:
            frames = _rereference(frames, self.reference, True)
        yaw = np.cumsum(frames[:, 2]) - frames[0, 2]
        step = np.stack((frames[:, 0], np.zeros(len(v)), frames[:, 1]), 1)
        # Frame t's step is in the body frame of frame t - 1.
        world = quaternion_apply(yaw_quaternion(np.concatenate(([0.0], yaw[:-1]))), step)
        world[0] = 0.0
        path = np.cumsum(world, axis=0)
        rotations = axis_angle_to_quaternion(frames[:, ROOT_COLUMNS:].reshape(len(v), -1, 3))
        rotations[:, self.mover] = quaternion_multiply(yaw_quaternion(yaw),
                                                       rotations[:, self.mover])
        positions = np.repeat(self.local_positions[None], len(v), axis=0)
        positions[:, self.mover] = np.stack((path[:, 0], frames[:, 3], path[:, 2]), 1)
        return Motion(self.skeleton, rotations, positions, self.fps,
                      {"name": name, "source": "emotive fcrbm"})

    def to_dict(self) -> dict[str, Any]:
        """Plain lists and numbers (for a ``weights_only`` checkpoint)."""
        return {
            "keep": self.keep.tolist(), "mean": self.mean.tolist(), "std": self.std.tolist(),
            "constant": self.constant.tolist(), "skeleton": skeleton_to_dict(self.skeleton),
            "local_positions": self.local_positions.tolist(), "mover": int(self.mover),
            "fps": float(self.fps),
            "reference": None if self.reference is None else self.reference.tolist(),
        }

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> FrameCodec:
        """The codec saved by :meth:`to_dict` (``KeyError``/``ValueError`` on bad input)."""
        skeleton = skeleton_from_dict(values["skeleton"])
        out = cls(
            np.array(values["keep"], dtype=np.int64), np.array(values["mean"], dtype=np.float64),
            np.array(values["std"], dtype=np.float64),
            np.array(values["constant"], dtype=np.float64), skeleton,
            np.array(values["local_positions"], dtype=np.float64), int(values["mover"]),
            float(values["fps"]),
            None if values.get("reference") is None
            else np.array(values["reference"], dtype=np.float64),
        )
        if out.reference is not None and out.reference.shape != (skeleton.num_joints, 4):
            raise ValueError("the codec's references do not match its rig")
        if out.constant.shape != (ROOT_COLUMNS + 3 * skeleton.num_joints,):
            raise ValueError("the codec does not match its rig")
        return out
