"""Feet and stops of streamed FCRBM agents: the root from the stance foot, planted feet, stops.

The FCRBM predicts its root's forward step apart from the legs, and in the stream (as in the
paper's own results, Sec. V-A: "occasional foot sliding") a planted foot slides whenever that
step and the legs disagree. Three causal fixes, every agent at once, with the shared pieces of
:mod:`emotive.ik` (the gait network's stream uses the same foot lock):

* **Root from the stance foot** (:func:`emotive.ik.stance_root.stance_shift`, the causal step
  of the offline :func:`~emotive.ik.stance_root.root_from_stance` that
  :func:`~emotive.models.fcrbm.generate.generate_motion` applies): the agent advances along its
  path by how far the stance foot moved back under the body since the last model frame, the
  foot points taken in the body's own frame (heading removed, root over the origin);
  in the air the model's own step is kept, in proportion.
* **Planted feet locked** (:func:`emotive.ik.foot_lock.lock_feet`): what is left of a planted
  foot's slide (the path's turns, the body's sway, which the path drops) is held by the
  two-bone leg IK on the placed frame.
* **Stops.** The FCRBM has no speed input, so near the end of an open path (where slowing
  down linearly over :data:`STOP_SECONDS` from its speed ends at the end) the agent blends
  from the model's body to the standing pose (the training data's mean frame, by a
  smoothstep of the stop weight) over :data:`STOP_SECONDS`, its advance scaled down
  linearly by the same weight; once standing it holds that pose and is not sampled (its
  window is kept, so a new path or target starts it walking again, blending back the same
  way).

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``P = J + E`` points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.roles import resolve_roles
from emotive.ik.foot_lock import LegRig, LockState, initial_lock_state, leg_rig, lock_feet
from emotive.ik.stance_root import stance_shift
from emotive.models.fcrbm.stream_pose import Body, PoseDecoder, nlerp

#: Metres before the end of an open path within which a stop, once begun, goes on.
STOP_DISTANCE = 1.5
#: An agent starts to stop where slowing down linearly over :data:`STOP_SECONDS` from its
#: speed ends at the path's end (``speed * STOP_SECONDS / 2``), and this near at the latest.
MIN_STOP_DISTANCE = 0.05
#: Seconds of the blend from walking to standing (and back when it walks on).
STOP_SECONDS = 0.8
#: Foot points of the stance fix, in this order (heel = ankle joint).
FOOT_ROLES = ("l_ankle", "l_toe", "r_ankle", "r_toe")


def smoothstep(x: np.ndarray) -> np.ndarray:
    """``(...)`` ``3 x^2 - 2 x^3`` of ``x`` clipped to ``[0, 1]``."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass
class StreamFeet:
    """The rig's feet, its standing pose and the foot lock of a stream.

    Attributes:
        pose: the stream's pose decoder.
        legs: the legs for the foot lock (:func:`~emotive.ik.foot_lock.leg_rig`).
        points: ``(4,)`` indices of the heel and toe points (:data:`FOOT_ROLES`) in ``P``.
        ground: ``(4,)`` their heights in the standing pose, metres.
        standing: the standing body (one row).
    """

    pose: PoseDecoder
    legs: LegRig
    points: np.ndarray
    ground: np.ndarray
    standing: Body

    @classmethod
    def of(cls, pose: PoseDecoder) -> StreamFeet:
        """The feet of ``pose``'s rig, standing in the training data's mean frame."""
        sk = pose.codec.skeleton
        roles = resolve_roles(sk)
        standing = pose.body(np.zeros((1, pose.codec.dim)))
        world = pose.place(standing.rotations, standing.height, np.zeros(1),
                           np.zeros((1, 2))).world[0]
        points = np.array([roles.index[r] for r in FOOT_ROLES], dtype=np.int64)
        return cls(pose, leg_rig(sk, roles, world), points, world[points, 1].copy(), standing)

    def local_feet(self, rotations: np.ndarray, height: np.ndarray) -> np.ndarray:
        """``(B, 4, 3)`` heel and toe points of bodies facing +Z with the root over the origin."""
        n = len(rotations)
        world = self.pose.place(rotations, height, np.zeros(n), np.zeros((n, 2))).world
        return world[:, self.points]

    def advance(self, previous: np.ndarray, current: np.ndarray, forward: np.ndarray
                ) -> np.ndarray:
        """``(B,)`` forward move of each body between two model frames, metres.

        Args:
            previous: ``(B, 4, 3)`` :meth:`local_feet` of the last model frame.
            current: ``(B, 4, 3)`` those of this one.
            forward: ``(B,)`` the model's own forward step (kept in the air, in proportion).
        """
        shift, share = stance_shift(previous, current, self.ground, self.legs.leg_length)
        return shift[:, 1] + (1.0 - share) * forward

    def blend(self, body: Body, stop: np.ndarray) -> Body:
        """``body`` blended towards the standing pose by ``(B,)`` stop weights in ``[0, 1]``."""
        w = smoothstep(stop)
        if not (w > 0).any():
            return body
        rotations = nlerp(body.rotations, self.standing.rotations, w[:, None, None])
        height = body.height + w * (self.standing.height - body.height)
        return Body(rotations, height, body.forward * (1.0 - w))

    def lock(self, state: LockState, rotations: np.ndarray, world: np.ndarray,
             speed: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray, LockState]:
        """Planted feet of placed frames held still (:func:`~emotive.ik.foot_lock.lock_feet`)."""
        return lock_feet(self.legs, state, rotations, world, speed, fps)


def lock_rows(agents: int) -> dict[str, np.ndarray]:
    """The foot-lock state of ``agents`` new agents as :class:`Rows` fields (``lock_*``)."""
    return {f"lock_{k}": v for k, v in initial_lock_state(agents)._asdict().items()}


def lock_state(rows: object, index: np.ndarray) -> LockState:
    """The :class:`~emotive.ik.foot_lock.LockState` of rows ``index`` of ``rows``."""
    return LockState(*(getattr(rows, f"lock_{k}")[index] for k in LockState._fields))


def store_lock(rows: object, index: np.ndarray, state: LockState) -> None:
    """Write ``state`` back into rows ``index`` of ``rows``."""
    for k, v in state._asdict().items():
        getattr(rows, f"lock_{k}")[index] = v
