"""FCRBM frames to streamed poses: one frame per agent decoded and placed in the world.

:meth:`FrameCodec.decode <emotive.models.fcrbm.data.FrameCodec.decode>` turns a whole clip
into a :class:`~emotive.core.motion.Motion`, integrating the root's path from its steps. A
stream places each agent on a ground path instead, one frame at a time, so
:class:`PoseDecoder` takes the frame apart: the body (every joint's local rotation, the mover's
without its heading, exactly as ``decode`` rebuilds it), the root height and the forward step
the model took; :meth:`PoseDecoder.place` then puts the body at a heading and ground position.
The joints above the mover (the Bandai rig's ``joint_Root``) stay at the identity, as
:func:`~emotive.core.root.fold_into_root` leaves them in the training data, so the mover
carries the whole placement.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``D`` visible units.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from emotive.core.motion import Motion
from emotive.models.fcrbm.data import ROOT_COLUMNS, FrameCodec
from emotive.transforms.fast_np import expmap_to_quat, qmul, qnormalize, yaw_quat
from emotive.transforms.kinematics import PoseFK

#: Column of the forward step (metres per model frame, in the previous frame's body frame).
FORWARD_COLUMN = 1
#: Column of the root height (metres).
HEIGHT_COLUMN = 3


class Body(NamedTuple):
    """The body of ``B`` decoded frames, before placement.

    Attributes:
        rotations: ``(B, J, 4)`` local rotations, the mover's without its heading.
        height: ``(B,)`` root height, metres.
        forward: ``(B,)`` forward step of the root, metres per model frame.
    """

    rotations: np.ndarray
    height: np.ndarray
    forward: np.ndarray


class Placed(NamedTuple):
    """``B`` bodies placed in the world.

    Attributes:
        rotations: ``(B, J, 4)`` local rotations, the mover's carrying the heading.
        positions: ``(B, J, 3)`` local translations, the mover's its world position (metres).
        world: ``(B, J + E, 3)`` world positions of joints then end sites, metres.
    """

    rotations: np.ndarray
    positions: np.ndarray
    world: np.ndarray


def _ancestors(parents: np.ndarray, joint: int) -> list[int]:
    out, j = [], int(parents[joint])
    while j >= 0:
        out.append(j)
        j = int(parents[j])
    return out


def _subtree(parents: np.ndarray, joint: int) -> np.ndarray:
    """``(J,)`` whether each joint is ``joint`` or below it (parents in topological order)."""
    inside = np.zeros(len(parents), dtype=bool)
    inside[joint] = True
    for j in range(joint + 1, len(parents)):
        inside[j] = parents[j] >= 0 and inside[parents[j]]
    return inside


def nlerp(a: np.ndarray, b: np.ndarray, weight: float) -> np.ndarray:
    """``(..., 4)`` normalized blend of unit quaternions, ``weight`` of the way from ``a`` to ``b``.

    ``b`` is flipped onto ``a``'s hemisphere first, so the blend takes the short way.
    """
    dot = (a * b).sum(-1, keepdims=True)
    return qnormalize((1.0 - weight) * a + weight * np.where(dot < 0, -b, b))


class PoseDecoder:
    """Decodes standardized frames of one codec and places the bodies.

    Args:
        codec: the model's frame codec.
    """

    def __init__(self, codec: FrameCodec) -> None:
        self.codec = codec
        sk = codec.skeleton
        parents = np.asarray(sk.parents)
        self.mover = int(codec.mover)
        self._joints = sk.num_joints
        self._above = np.array(_ancestors(parents, self.mover), dtype=np.int64)
        self._local = np.asarray(codec.local_positions, dtype=np.float64)
        offsets = self._local.copy()
        offsets[self.mover] = 0.0
        # With the ancestors at the identity, the mover's translation moves its subtree only.
        self._fk = PoseFK(parents, offsets, sk.end_site_parents, sk.end_site_offsets)
        joints = _subtree(parents, self.mover)
        ends = joints[np.asarray(sk.end_site_parents, dtype=np.int64)]
        self._moved = np.concatenate((joints, ends))
        self._reference = (None if codec.reference is None
                           else np.asarray(codec.reference, dtype=np.float64))

    def body(self, visible: np.ndarray) -> Body:
        """The bodies of ``(B, D)`` standardized frames."""
        c = self.codec
        v = np.asarray(visible, dtype=np.float64)
        frames = np.repeat(c.constant[None], len(v), axis=0)
        frames[:, c.keep] = v * c.std + c.mean
        rotations = expmap_to_quat(frames[:, ROOT_COLUMNS:].reshape(len(v), self._joints, 3))
        if self._reference is not None:
            rotations = qmul(self._reference, rotations)
        rotations[:, self._above] = (1.0, 0.0, 0.0, 0.0)
        return Body(rotations, frames[:, HEIGHT_COLUMN].copy(), frames[:, FORWARD_COLUMN].copy())

    def place(self, rotations: np.ndarray, height: np.ndarray, heading: np.ndarray,
              xz: np.ndarray) -> Placed:
        """Bodies turned to ``heading`` and stood at ``xz``.

        Args:
            rotations: ``(B, J, 4)`` local rotations, the mover's without its heading.
            height: ``(B,)`` root heights, metres.
            heading: ``(B,)`` yaw in radians (0 faces +Z).
            xz: ``(B, 2)`` ground positions of the root, metres.
        """
        out = rotations.copy()
        out[:, self.mover] = qmul(yaw_quat(heading), rotations[:, self.mover])
        root = np.stack((xz[:, 0], height, xz[:, 1]), 1)
        positions = np.repeat(self._local[None], len(out), axis=0)
        positions[:, self.mover] = root
        world = self._fk(out)
        world[:, self._moved] += root[:, None]
        return Placed(out, positions, world)

    def rest(self, fps: float) -> Motion:
        """A one-frame clip of the training data's mean pose, standing at the origin facing +Z."""
        body = self.body(np.zeros((1, self.codec.dim)))
        placed = self.place(body.rotations, body.height, np.zeros(1), np.zeros((1, 2)))
        return Motion(self.codec.skeleton, placed.rotations, placed.positions, fps,
                      {"name": "fcrbm rest", "source": "emotive fcrbm"})
