"""Frames of the style transfer: translation- and heading-invariant pose vectors and point clouds.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``P`` point-cloud roles (the 21 joint
roles of :data:`emotive.core.roles.ROLES`), ``D`` pose dimensions.

A pose vector (paper section 4: poses decoupled from ground translation and hip heading, joint
angles as exponential maps) holds, for the rig's root role (the *mover*, Bandai ``Hips``):

* the ground step since the previous frame in the previous frame's heading frame (sideways,
  forward), the heading change (radians) and the height; lengths are divided by the rig's leg
  length so that performers of different size share one scale;
* the mover's world rotation with the heading removed, as an exponential map (3);
* every joint below the mover: its local rotation as an exponential map (3 each).

The exponential maps are taken relative to a fixed *reference rotation* per slot (Grassia
1998: keep the parameterization away from its singular shell at angle ``pi``): slot ``i``
holds ``log(r_i^-1 q_i)``. Without it, joints whose local rotation sits near 180 degrees (the
Bandai thighs hang from the hips rotated by about ``pi``) flip between ``theta n`` and
``-(2 pi - theta) n`` from frame to frame, and any average or regression of them (every
local model of the style transfer) gives nonsense legs. The database computes the references
(the mean rotation of each slot over its examples, :func:`reference_rotations`) and stores
them; a codec without references (``reference`` None) uses the identity.

Joints above the mover (Bandai's static ``joint_Root``) are folded into it, as in
:func:`emotive.core.root.fold_into_root`. The heading is the facing of
:func:`emotive.core.ops.facing_directions` (from hips and shoulders), computed here from the
role points of one frame at a time so that the encoder can run on a stream.

The point cloud of a frame is the world positions of the ``P`` roles divided by the leg
length; the distance of the search is invariant to ground translation and heading anyway.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import ROLES, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import RigError
from emotive.features.contacts import leg_length
from emotive.models.mar.config import TransferError
from emotive.transforms.fast_np import (
    CONJUGATE,
    expmap_to_quat,
    qapply,
    qmul,
    quat_to_expmap,
    yaw_quat,
)
from emotive.transforms.kinematics import PoseFK, forward_kinematics_np
from emotive.transforms.np_rotations import quaternion_mean

#: Columns of the root motion: sideways step, forward step, turn, height.
ROOT_COLUMNS = 4
#: Roles whose points count for the footplant search (the upper body weighs zero there).
LOWER_BODY_ROLES: tuple[str, ...] = (
    "root", "l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe",
)


class RigMappingError(TransferError, RigError):
    """A rig whose joints cannot be mapped onto the joint roles."""


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped into ``[-pi, pi)``."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def heading_of_points(points: np.ndarray, hips: tuple[int, int],
                      shoulders: tuple[int, int]) -> np.ndarray:
    """``(T,)`` yaw (facing ``(sin a, 0, cos a)``) of ``(T, P, 3)`` points.

    The rule of :func:`emotive.core.ops.facing_directions`: facing is ``across x up`` with
    ``across`` the sum of the unit left-minus-right hip and shoulder vectors on the ground.
    """
    pairs = np.stack((points[:, hips[0]] - points[:, hips[1]],
                      points[:, shoulders[0]] - points[:, shoulders[1]]), 1)[..., [0, 2]]
    norm = np.linalg.norm(pairs, axis=-1, keepdims=True)
    across = (pairs / np.maximum(norm, 1e-12)).sum(1)
    return np.arctan2(-across[:, 1], across[:, 0])


@dataclass
class CodecState:
    """What encoding or decoding the next frame needs from the previous one.

    Attributes:
        root: ``(3,)`` world position of the mover.
        yaw: its heading, radians.
    """

    root: np.ndarray
    yaw: float


@dataclass(frozen=True, eq=False)
class RigCodec:
    """Pose vectors and point clouds of one rig.

    Attributes:
        skeleton: the rig.
        mover: index of the root role joint.
        above: joints above the mover (folded into it).
        below: ``(J_b,)`` joints below the mover, in rig order (their rotations are encoded).
        points: ``(P,)`` indices of the role points in the ``(J + E)`` array.
        leg: leg length (hip -> knee -> ankle), metres.
        local_positions: ``(J, 3)`` local translations used when decoding (bones keep length).
        reference: ``(1 + J_b, 4)`` reference rotation of each exponential-map slot (the
            mover's tilt, then :attr:`below`), or None for the identity.
    """

    skeleton: Skeleton
    mover: int
    above: tuple[int, ...]
    below: np.ndarray
    points: np.ndarray
    leg: float
    local_positions: np.ndarray
    reference: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def with_reference(self, reference: np.ndarray | None) -> RigCodec:
        """The same codec with exponential maps relative to ``reference`` ``(1 + J_b, 4)``."""
        ref = None if reference is None else np.asarray(reference, dtype=np.float64)
        if ref is not None and ref.shape != (1 + len(self.below), 4):
            raise RigMappingError(f"reference rotations of shape {ref.shape} do not fit a rig "
                                  f"of {1 + len(self.below)} rotation slots")
        return RigCodec(self.skeleton, self.mover, self.above, self.below, self.points,
                        self.leg, self.local_positions, ref)

    def slot_rotations(self, rotations: np.ndarray, grot_mover: np.ndarray,
                       yaw: np.ndarray) -> np.ndarray:
        """``(T, 1 + J_b, 4)`` rotations of the exponential-map slots.

        ``(T, 1 + J_b, 4)`` rotations of the exponential-map slots (absolute, before the
        reference is taken off).
        """
        tilt = qmul(yaw_quat(-yaw), grot_mover)
        return np.concatenate((tilt[:, None], rotations[:, self.below]), 1)

    @classmethod
    def for_motion(cls, motion: Motion, role_map=None, name: str | None = None) -> RigCodec:
        """The codec of a clip's rig; bone lengths and leg length from its first frame.

        Raises:
            RigMappingError: the rig lacks joint roles; the message names the clip and the fix.
        """
        sk = motion.skeleton
        label = name or motion.metadata.get("name", "the input")
        try:
            roles = resolve_roles(sk, role_map)
        except RigError as exc:
            raise RigMappingError(f"{label}: cannot map the rig onto the joint roles: {exc}") \
                from None
        mover = int(roles.index["root"])
        if mover >= sk.num_joints:
            raise RigMappingError(f"{label}: the root role must be a joint, not an end site")
        above, j = [], int(sk.parents[mover])
        while j >= 0:
            above.append(j)
            j = int(sk.parents[j])
        for a in above:
            kids = [k for k in range(sk.num_joints) if sk.parents[k] == a]
            if len(kids) > 1 or a in sk.end_site_parents:
                raise RigMappingError(
                    f"{label}: joint {sk.names[a]} above the root role {sk.names[mover]} has "
                    "other children; pass a role map (--roles) whose root is the top joint"
                )
        below = np.array([k for k in range(sk.num_joints) if k != mover and k not in above],
                         dtype=np.int64)
        first = motion.replace(rotations=motion.rotations[:1], positions=motion.positions[:1])
        points = roles.indices(ROLES)
        leg = leg_length(first.positions_with_end_sites(), roles)
        if not leg > 0:
            raise RigMappingError(f"{label}: the legs have zero length; check the rig's offsets")
        local = motion.positions[0].copy()
        local[list(above)] = 0.0
        return cls(sk, mover, tuple(above), below, points, float(leg), local)

    @property
    def dim(self) -> int:
        """``D``, the length of a pose vector."""
        return ROOT_COLUMNS + 3 * (1 + len(self.below))

    @property
    def role_slots(self) -> dict[str, int]:
        """Role name -> its column among the ``P`` points."""
        return {r: i for i, r in enumerate(ROLES)}

    def _heading(self, points: np.ndarray) -> np.ndarray:
        slot = self.role_slots
        return heading_of_points(points, (slot["l_hip"], slot["r_hip"]),
                                 (slot["l_shoulder"], slot["r_shoulder"]))

    def world_points(self, rotations: np.ndarray, positions: np.ndarray) -> tuple[
            np.ndarray, np.ndarray, np.ndarray]:
        """World rotations, positions and role points of local rotations and translations.

        World rotations ``(T, J, 4)``, positions ``(T, J, 3)`` and role points ``(T, P, 3)``
        (metres) of local rotations ``(T, J, 4)`` and translations ``(T, J, 3)``.

        A single frame (streaming) goes through a faster path that returns only the mover's
        world transform among the joints (see :meth:`_stream_points`).
        """
        sk = self.skeleton
        if len(rotations) == 1:
            return self._stream_points(rotations, positions)
        grot, gpos = forward_kinematics_np(rotations, positions, sk.parents)
        esp = sk.end_site_parents
        if len(esp):
            ends = qapply(grot[:, esp],
                                    np.broadcast_to(sk.end_site_offsets, (len(grot), len(esp), 3)))
            allpos = np.concatenate((gpos, ends + gpos[:, esp]), 1)
        else:
            allpos = gpos
        return grot, gpos, allpos[:, self.points]

    def _stream_points(self, rotations: np.ndarray, positions: np.ndarray) -> tuple[
            np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`world_points` of one frame by forward kinematics.

        :meth:`world_points` of one frame by :class:`~emotive.transforms.kinematics.PoseFK`
        (bones of the codec's fixed lengths); only the mover's world transform is returned in
        the rotations and positions (the rest is left at zero).
        """
        if "fk" not in self._cache:
            offsets = self.local_positions.copy()
            offsets[self.mover] = 0.0
            sk = self.skeleton
            self._cache["fk"] = PoseFK(sk.parents, offsets, sk.end_site_parents,
                                        sk.end_site_offsets)
        rot_m, pos_m = rotations[0, self.mover], positions[0, self.mover]
        for a in self.above:
            rot_m = qmul(rotations[0, a], rot_m)
            pos_m = qapply(rotations[0, a], pos_m) + positions[0, a]
        local = rotations.copy()
        local[0, list(self.above)] = (1.0, 0.0, 0.0, 0.0)
        local[0, self.mover] = rot_m
        world = self._cache["fk"](local) + pos_m
        grot = np.zeros_like(rotations)
        gpos = np.zeros_like(positions)
        grot[0, self.mover], gpos[0, self.mover] = rot_m, pos_m
        return grot, gpos, world[:, self.points]

    def encode(self, rotations: np.ndarray, positions: np.ndarray,
               state: CodecState | None = None) -> tuple[np.ndarray, np.ndarray, CodecState]:
        """Pose vectors and point clouds of consecutive frames.

        Args:
            rotations: ``(T, J, 4)`` local rotations, ``T >= 1``.
            positions: ``(T, J, 3)`` local translations.
            state: the previous frame's state; ``None`` for the first frames of a clip (the
                first frame then repeats the second frame's step and turn).

        Returns:
            ``(T, D)`` pose vectors, ``(T, P, 3)`` point clouds (in leg lengths) and the state
            after the last frame.
        """
        grot, gpos, pts = self.world_points(rotations, positions)
        yaw = self._heading(pts)
        root = gpos[:, self.mover]
        if state is None:
            prev_root = np.concatenate((root[:1], root[:-1]))
            prev_yaw = np.concatenate((yaw[:1], yaw[:-1]))
        else:
            prev_root = np.concatenate((state.root[None], root[:-1]))
            prev_yaw = np.concatenate(([state.yaw], yaw[:-1]))
        step = root - prev_root
        step[:, 1] = 0.0
        body = qapply(yaw_quat(-prev_yaw), step)[:, [0, 2]] / self.leg
        turn = wrap_angle(yaw - prev_yaw)
        if state is None and len(yaw) > 1:
            body[0], turn[0] = body[1], turn[1]
        rot = self.slot_rotations(rotations, grot[:, self.mover], yaw)
        if self.reference is not None:
            inv = self.reference * CONJUGATE
            rot = qmul(np.broadcast_to(inv, rot.shape), rot)
        rot = rot * np.where(rot[..., :1] < 0, -1.0, 1.0)
        expmap = quat_to_expmap(rot).reshape(len(rot), -1)
        vectors = np.concatenate(
            (body, turn[:, None], root[:, 1:2] / self.leg, expmap), axis=1
        )
        return vectors, pts / self.leg, CodecState(root[-1].copy(), float(yaw[-1]))

    def encode_motion(self, motion: Motion) -> tuple[np.ndarray, np.ndarray]:
        """``(T, D)`` pose vectors and ``(T, P, 3)`` point clouds of a whole clip.

        Raises:
            TransferError: NaN or infinite values (naming the first bad frame).
        """
        check_finite(motion)
        vectors, points, _ = self.encode(motion.rotations, motion.positions)
        return vectors, points

    def decode(self, vectors: np.ndarray, roots: np.ndarray, yaws: np.ndarray) -> tuple[
            np.ndarray, np.ndarray]:
        """Local rotations ``(T, J, 4)`` and translations ``(T, J, 3)`` of pose vectors.

        Args:
            vectors: ``(T, D)`` pose vectors (their root steps are ignored: the path is given).
            roots: ``(T, 2)`` world ground position ``(x, z)`` of the mover, metres.
            yaws: ``(T,)`` heading of the mover, radians.
        """
        n = len(vectors)
        rot = expmap_to_quat(vectors[:, ROOT_COLUMNS:].reshape(n, -1, 3))
        if self.reference is not None:
            rot = qmul(np.broadcast_to(self.reference, rot.shape), rot)
        out_rot = np.zeros((n, self.skeleton.num_joints, 4))
        out_rot[..., 0] = 1.0
        out_rot[:, self.mover] = qmul(yaw_quat(yaws), rot[:, 0])
        out_rot[:, self.below] = rot[:, 1:]
        pos = np.repeat(self.local_positions[None], n, axis=0)
        pos[:, self.mover] = np.stack(
            (roots[:, 0], vectors[:, 3] * self.leg, roots[:, 1]), 1
        )
        return out_rot, pos

    def integrate(self, vectors: np.ndarray, advance: np.ndarray, state: CodecState) -> tuple[
            np.ndarray, np.ndarray, CodecState]:
        """The ground path of pose vectors whose steps are scaled by ``advance``.

        Args:
            vectors: ``(T, D)`` pose vectors; their steps and turns are per frame of their own
                timeline.
            advance: ``(T,)`` frames of that timeline elapsed at each vector (the timing
                prediction; 1 keeps the steps as they are).
            state: mover position and heading before the first vector.

        Returns:
            ``(T, 2)`` ground positions, ``(T,)`` headings and the state after the last one.
        """
        root, yaw = state.root.copy(), state.yaw
        roots, yaws = np.empty((len(vectors), 2)), np.empty(len(vectors))
        for t, (v, w) in enumerate(zip(vectors, advance, strict=True)):
            c, s = np.cos(yaw), np.sin(yaw)
            dx, dz = v[0] * self.leg * w, v[1] * self.leg * w
            root[0] += c * dx + s * dz
            root[2] += -s * dx + c * dz
            yaw = float(wrap_angle(yaw + v[2] * w))
            roots[t], yaws[t] = root[[0, 2]], yaw
        return roots, yaws, CodecState(root, yaw)


def slot_quaternions(vectors: np.ndarray) -> np.ndarray:
    """``(T, S, 4)`` rotations of the exponential-map slots of pose vectors.

    ``(T, S, 4)`` rotations of the exponential-map slots of ``(T, D)`` pose vectors
    encoded without a reference.
    """
    return expmap_to_quat(vectors[:, ROOT_COLUMNS:].reshape(len(vectors), -1, 3))


def rebase(vectors: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """``(T, D)`` pose vectors re-expressed relative to ``reference``.

    ``(T, D)`` pose vectors encoded without a reference, re-expressed relative to
    ``reference`` ``(S, 4)`` (what a codec :meth:`~RigCodec.with_reference` would give).
    """
    rot = slot_quaternions(vectors)
    inv = np.asarray(reference) * CONJUGATE
    rot = qmul(np.broadcast_to(inv, rot.shape), rot)
    rot = rot * np.where(rot[..., :1] < 0, -1.0, 1.0)
    out = vectors.copy()
    out[:, ROOT_COLUMNS:] = quat_to_expmap(rot).reshape(len(vectors), -1)
    return out


def reference_rotations(slots: list[np.ndarray]) -> np.ndarray:
    """``(S, 4)`` mean rotation of each slot over clips' slot rotations.

    ``(S, 4)`` mean rotation of each slot over clips' ``(T, S, 4)`` slot rotations
    (:meth:`RigCodec.slot_rotations`; :func:`~emotive.transforms.np_rotations.quaternion_mean`).
    """
    return quaternion_mean(np.concatenate(slots), axis=0)


def check_finite(motion: Motion, label: str | None = None) -> None:
    """Raise :class:`TransferError` naming the first frame with NaN or infinite values."""
    bad = ~(np.isfinite(motion.rotations).all((1, 2)) & np.isfinite(motion.positions).all((1, 2)))
    if bad.any():
        name = label or motion.metadata.get("name", "the input")
        raise TransferError(
            f"{name}: frame {int(np.argmax(bad))} holds NaN or infinite values "
            f"({int(bad.sum())} bad frames); repair or cut those frames first"
        )
