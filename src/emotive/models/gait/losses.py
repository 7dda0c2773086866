"""Training losses of the emotive gait network (Emotive Gaits, section 4.3), differentiable.

Legend: ``B...`` any leading dimensions (agents, frames), ``J`` joints, ``E`` end sites.

Every term is written in the paper as a sum over joints and prediction frames. Here each term
is summed within a frame, as in its equation, and averaged over all leading dimensions, so
its size does not depend on the batch size or window length (the weights of equation (13)
then keep their meaning across settings).

* motion (8): ``sum_j |q2e(q_j) - q2e(q^_j)|^2 + lambda_versor (|q^_j| - 1)^2``, Euler angles
  in each joint's own channel order, differences wrapped to ``(-pi, pi]``.
* pose (9): ``sum_j |(X_j - X_0) - (X^_j - X^_0)|^2`` on forward-kinematics joint positions,
  ``X_0`` the position of the ``root`` role.
* affective (10): ``|a - a^|^2`` over the 18 affective features of the poses, ratios in log
  space (:mod:`~emotive.models.gait.affect`).
* root (11): ``|[h, s, delta] - [h^, s^, delta^]|_1``.
* foot contact (12): ``|[lh, lt, rh, rt] - [lh^, lt^, rh^, rt^]|_1`` over heel (ankle) and
  toe positions.
* amplitude (an extension, weight 0 by default): ``sum_p |std_t(X_p - X_0) - std_t(X^_p - X^_0)|
  + |std_t(h) - std_t(h^)|`` over the frames ``t`` of each window, all joints and end sites
  ``p``; it counters the damping of oscillations in free-running rollouts.
* total (13): the weighted sum, weights from :class:`~emotive.models.gait.config.GaitConfig`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from emotive.core.roles import JointRoles, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.features.contacts import foot_positions
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.network import GaitOutputs
from emotive.transforms.kinematics import forward_kinematics
from emotive.transforms.rotations import (
    quaternion_apply,
    quaternion_normalize,
    quaternion_to_euler,
)

#: Names of the loss terms, in the order of equation (13).
LOSS_TERMS: tuple[str, ...] = ("motion", "pose", "affective", "root", "foot_contact",
                                "amplitude")


@dataclass(frozen=True, eq=False)
class GaitRig:
    """What the losses need of a rig: hierarchy, Euler orders, end sites and roles.

    Attributes:
        parents: ``J`` parent indices in topological order.
        euler_orders: ``J`` Euler orders (``"ZXY"``, ...) of the joints' rotation channels;
            ``""`` for a joint without rotation channels (left out of the Euler difference).
        end_site_parents: ``E`` joint indices the end sites hang from.
        end_site_offsets: ``(E, 3)`` end-site offsets from their joints, metres.
        roles: resolved roles, indexing the ``J + E`` joint-then-end-site array.
    """

    parents: tuple[int, ...]
    euler_orders: tuple[str, ...]
    end_site_parents: tuple[int, ...]
    end_site_offsets: np.ndarray
    roles: JointRoles

    def __post_init__(self) -> None:
        parents = tuple(int(p) for p in self.parents)
        orders = tuple(self.euler_orders)
        ends = tuple(int(p) for p in self.end_site_parents)
        offsets = np.array(self.end_site_offsets, dtype=np.float64).reshape(-1, 3)
        if len(orders) != len(parents):
            raise ValueError(f"{len(parents)} joints need as many Euler orders, got {len(orders)}")
        if len(offsets) != len(ends) or any(not 0 <= p < len(parents) for p in ends):
            raise ValueError("end sites need one valid parent joint and one offset each")
        for name, value in (("parents", parents), ("euler_orders", orders),
                            ("end_site_parents", ends), ("end_site_offsets", offsets)):
            object.__setattr__(self, name, value)

    @classmethod
    def from_skeleton(cls, skeleton: Skeleton, roles: JointRoles | None = None) -> GaitRig:
        """The rig of a :class:`~emotive.core.Skeleton` (roles resolved by name if not given).

        Raises:
            RigError: the rig lacks roles the affective features or the feet need.
        """
        return cls(
            tuple(skeleton.parents),
            tuple(skeleton.rotation_order(j) for j in range(skeleton.num_joints)),
            tuple(skeleton.end_site_parents),
            skeleton.end_site_offsets,
            roles if roles is not None else resolve_roles(skeleton),
        )

    @property
    def num_joints(self) -> int:
        """``J``."""
        return len(self.parents)

    @property
    def root_index(self) -> int:
        """Index of the ``root`` role (the hips), the origin of the pose loss."""
        return int(self.roles.index["root"])


def _check_rotations(pred: torch.Tensor, true: torch.Tensor, num_joints: int) -> None:
    if pred.shape != true.shape or pred.ndim < 2 or tuple(pred.shape[-2:]) != (num_joints, 4):
        raise ValueError(
            f"predicted and true rotations must both have shape (B..., J={num_joints}, 4), got "
            f"{tuple(pred.shape)} and {tuple(true.shape)}"
        )


def rig_positions(
    rotations: torch.Tensor, local_positions: torch.Tensor, rig: GaitRig
) -> torch.Tensor:
    """World positions of joints then end sites.

    As :meth:`emotive.core.Motion.positions_with_end_sites` places them.

    Args:
        rotations: ``(B..., J, 4)`` local unit quaternions.
        local_positions: ``(B..., J, 3)`` local translations (root: its world position),
            broadcastable to the rotations' leading shape.
        rig: the rig.

    Returns:
        ``(B..., J + E, 3)``, differentiable in both inputs.
    """
    grot, gpos = forward_kinematics(rotations, local_positions, rig.parents)
    if not rig.end_site_parents:
        return gpos
    idx = torch.as_tensor(rig.end_site_parents, device=gpos.device)
    offsets = torch.tensor(rig.end_site_offsets, dtype=gpos.dtype, device=gpos.device)
    ends = quaternion_apply(grot.index_select(-2, idx), offsets) + gpos.index_select(-2, idx)
    return torch.cat((gpos, ends), -2)


def _wrap(angle: torch.Tensor) -> torch.Tensor:
    """Angles to ``(-pi, pi]``, with slope 1 everywhere (``atan2(sin, cos)``)."""
    return torch.atan2(torch.sin(angle), torch.cos(angle))


def _frame_mean(per_frame: torch.Tensor) -> torch.Tensor:
    return per_frame.mean() if per_frame.ndim else per_frame


def motion_loss(
    raw_rotations: torch.Tensor,
    true_rotations: torch.Tensor,
    euler_orders: Sequence[str],
    versor_weight: float = 0.01,
) -> torch.Tensor:
    """Equation (8): Euler-angle difference plus the unit-norm penalty.

    ``L_motion = mean_frames sum_j |wrap(q2e(q_j) - q2e(q^_j / |q^_j|))|^2
    + lambda_versor (|q^_j| - 1)^2``, with ``q2e`` in joint ``j``'s own Euler order. The
    differences are wrapped to ``(-pi, pi]`` so that angles on both sides of ``+-pi`` (the
    same rotation) cost nothing.

    Args:
        raw_rotations: ``(B..., J, 4)`` predicted quaternions before normalization.
        true_rotations: ``(B..., J, 4)`` true unit quaternions.
        euler_orders: ``J`` Euler orders; joints with ``""`` only get the norm penalty.
        versor_weight: ``lambda_versor``.

    Returns:
        Scalar tensor.

    Raises:
        ValueError: shapes that differ or do not match ``euler_orders``.
    """
    _check_rotations(raw_rotations, true_rotations, len(euler_orders))
    pred = quaternion_normalize(raw_rotations)
    per_frame = versor_weight * ((raw_rotations.norm(dim=-1) - 1.0) ** 2).sum(-1)
    for order in sorted(set(euler_orders) - {""}):
        idx = torch.as_tensor(
            [j for j, o in enumerate(euler_orders) if o == order], device=pred.device
        )
        diff = quaternion_to_euler(true_rotations.index_select(-2, idx), order) - (
            quaternion_to_euler(pred.index_select(-2, idx), order)
        )
        per_frame = per_frame + (_wrap(diff) ** 2).sum((-1, -2))
    return _frame_mean(per_frame)


def _pose_term(pred_pos: torch.Tensor, true_pos: torch.Tensor, rig: GaitRig) -> torch.Tensor:
    n, r = rig.num_joints, rig.root_index
    pred_rel = pred_pos[..., :n, :] - pred_pos[..., r : r + 1, :]
    true_rel = true_pos[..., :n, :] - true_pos[..., r : r + 1, :]
    return _frame_mean(((pred_rel - true_rel) ** 2).sum((-1, -2)))


def _affective_term(
    pred_pos: torch.Tensor, true_pos: torch.Tensor, rig: GaitRig
) -> torch.Tensor:
    diff = gait_affective(true_pos, rig.roles) - gait_affective(pred_pos, rig.roles)
    return _frame_mean((diff**2).sum(-1))


def _foot_term(pred_pos: torch.Tensor, true_pos: torch.Tensor, rig: GaitRig) -> torch.Tensor:
    diff = foot_positions(pred_pos, rig.roles) - foot_positions(true_pos, rig.roles)
    return _frame_mean(diff.abs().sum((-1, -2, -3)))


def amplitude_loss(pred_pos: torch.Tensor, true_pos: torch.Tensor, pred_height: torch.Tensor,
                   true_height: torch.Tensor, rig: GaitRig) -> torch.Tensor:
    """The amplitude term of the loss.

    The amplitude term: how far the prediction's movement range within a window is from
    the truth's.

    Args:
        pred_pos: ``(B, T, J + E, 3)`` predicted positions of joints and end sites.
        true_pos: ``(B, T, J + E, 3)`` true positions.
        pred_height: ``(B, T)`` predicted root height ``h``.
        true_height: ``(B, T)`` true root height.
        rig: the rig.

    Returns:
        Scalar tensor (metres): per window the sum over points and axes of the absolute
        difference of standard deviations over ``T``, plus that of the root height, averaged
        over windows.
    """
    if pred_pos.ndim != 4 or pred_pos.shape[1] < 2:
        raise ValueError(f"the amplitude term needs (B, T, P, 3) windows of T >= 2 frames, got "
                         f"{tuple(pred_pos.shape)}")
    r = rig.root_index
    spread = [(x - x[..., r : r + 1, :]).std(1) for x in (pred_pos, true_pos)]
    joints = (spread[0] - spread[1]).abs().sum((-1, -2))
    height = (pred_height.std(1) - true_height.std(1)).abs()
    return (joints + height).mean()


def pose_loss(
    pred_rotations: torch.Tensor,
    true_rotations: torch.Tensor,
    local_positions: torch.Tensor,
    rig: GaitRig,
) -> torch.Tensor:
    """Equation (9): squared error of root-relative joint positions.

    ``L_pose = mean_frames sum_j |(X_j - X_0) - (X^_j - X^_0)|^2`` over the ``J`` joints
    (end sites excluded, as in the paper), ``X`` from forward kinematics of the rotations with
    the same ``local_positions``, ``X_0`` the ``root`` role. The trajectory is not compared.

    Args:
        pred_rotations: ``(B..., J, 4)`` predicted local unit quaternions.
        true_rotations: ``(B..., J, 4)`` true local unit quaternions.
        local_positions: ``(B..., J, 3)`` local translations (bone offsets; root: world).
        rig: the rig.

    Returns:
        Scalar tensor (square metres).
    """
    _check_rotations(pred_rotations, true_rotations, rig.num_joints)
    return _pose_term(
        rig_positions(pred_rotations, local_positions, rig),
        rig_positions(true_rotations, local_positions, rig),
        rig,
    )


def affective_loss(
    pred_rotations: torch.Tensor,
    true_rotations: torch.Tensor,
    local_positions: torch.Tensor,
    rig: GaitRig,
) -> torch.Tensor:
    """Equation (10): squared error of the 18 affective features of the poses.

    ``L_aff = mean_frames |a - a^|^2``, ``a`` from
    :func:`emotive.models.gait.affect.gait_affective` (ratios in log space) on the
    forward-kinematics positions
    of joints and end sites (hand tips and toes are end sites on the Bandai rig).

    Args:
        pred_rotations: ``(B..., J, 4)`` predicted local unit quaternions.
        true_rotations: ``(B..., J, 4)`` true local unit quaternions.
        local_positions: ``(B..., J, 3)`` local translations.
        rig: the rig.

    Returns:
        Scalar tensor.
    """
    _check_rotations(pred_rotations, true_rotations, rig.num_joints)
    return _affective_term(
        rig_positions(pred_rotations, local_positions, rig),
        rig_positions(true_rotations, local_positions, rig),
        rig,
    )


def root_loss(pred_root: torch.Tensor, true_root: torch.Tensor) -> torch.Tensor:
    """Equation (11): ``L_root = mean_frames |[h, s, delta] - [h^, s^, delta^]|_1``.

    Args:
        pred_root: ``(B..., 3)`` predicted ``[h, s, delta]``.
        true_root: ``(B..., 3)`` true ``[h, s, delta]``.

    Returns:
        Scalar tensor.
    """
    if pred_root.shape != true_root.shape or pred_root.shape[-1:] != (3,):
        raise ValueError(
            "predicted and true root features must both have shape (B..., 3), got "
            f"{tuple(pred_root.shape)} and {tuple(true_root.shape)}"
        )
    return _frame_mean((pred_root - true_root).abs().sum(-1))


def foot_contact_loss(
    pred_rotations: torch.Tensor,
    true_rotations: torch.Tensor,
    local_positions: torch.Tensor,
    rig: GaitRig,
    pred_local_positions: torch.Tensor | None = None,
) -> torch.Tensor:
    """Equation (12): L1 error of heel (ankle) and toe positions of both feet.

    ``L_ft_ct = mean_frames |[lh, lt, rh, rt] - [lh^, lt^, rh^, rt^]|_1`` over world
    positions (:func:`emotive.features.contacts.foot_positions`).

    Args:
        pred_rotations: ``(B..., J, 4)`` predicted local unit quaternions.
        true_rotations: ``(B..., J, 4)`` true local unit quaternions.
        local_positions: ``(B..., J, 3)`` local translations of the truth, root world
            position included.
        rig: the rig.
        pred_local_positions: local translations of the prediction (a predicted root
            trajectory); ``None`` uses ``local_positions``, so only the pose is compared.

    Returns:
        Scalar tensor (metres).
    """
    _check_rotations(pred_rotations, true_rotations, rig.num_joints)
    pred_local = local_positions if pred_local_positions is None else pred_local_positions
    return _foot_term(
        rig_positions(pred_rotations, pred_local, rig),
        rig_positions(true_rotations, local_positions, rig),
        rig,
    )


class GaitLoss:
    """Equation (13): the weighted sum of the loss terms.

    Equation (13): the weighted sum of the five terms (and the amplitude extension when its
    weight is positive), with the config's weights and switches.

    With ``use_affective=False`` the affective term is not computed; with
    ``use_root_loss=False`` the root term is not. Forward kinematics runs once per call for
    the prediction and once, without gradient, for the truth.

    Args:
        config: weights, ``lambda_versor`` and switches; ``config.num_joints`` must match.
        rig: the rig of the training motion.

    Raises:
        ValueError: the rig's joint count differs from the config's.
    """

    def __init__(self, config: GaitConfig, rig: GaitRig) -> None:
        if rig.num_joints != config.num_joints:
            raise ValueError(
                f"the rig has {rig.num_joints} joints but the config expects "
                f"{config.num_joints}"
            )
        self.config = config
        self.rig = rig
        self.weights = {
            "motion": config.motion_weight,
            "pose": config.pose_weight,
            "affective": config.affective_weight,
            "root": config.root_weight,
            "foot_contact": config.foot_contact_weight,
            "amplitude": config.amplitude_weight,
        }

    @property
    def active_terms(self) -> tuple[str, ...]:
        """The terms this loss computes, in :data:`LOSS_TERMS` order."""
        off = {"affective"} if not self.config.use_affective else set()
        if not self.config.use_root_loss:
            off.add("root")
        if not self.config.amplitude_weight > 0:
            off.add("amplitude")
        return tuple(t for t in LOSS_TERMS if t not in off)

    def __call__(
        self,
        outputs: GaitOutputs,
        true_rotations: torch.Tensor,
        true_root: torch.Tensor,
        local_positions: torch.Tensor,
    ) -> tuple[torch.Tensor, dict[str, float]]:
        """Total loss and each unweighted term.

        Args:
            outputs: the network's prediction, ``rotations``/``raw_rotations``
                ``(B..., J, 4)`` and ``root`` ``(B..., 3)``.
            true_rotations: ``(B..., J, 4)`` true next-frame local rotations.
            true_root: ``(B..., 3)`` true next-frame ``[h, s, delta]``.
            local_positions: ``(B..., J, 3)`` local translations of the true next frames.

        Returns:
            The scalar total (differentiable) and ``{term: value}`` as floats, for logging.
        """
        rig = self.rig
        _check_rotations(outputs.rotations, true_rotations, rig.num_joints)
        terms: dict[str, torch.Tensor] = {
            "motion": motion_loss(
                outputs.raw_rotations, true_rotations, rig.euler_orders,
                self.config.versor_weight,
            )
        }
        pred_pos = rig_positions(outputs.rotations, local_positions, rig)
        with torch.no_grad():
            true_pos = rig_positions(true_rotations, local_positions, rig)
        terms["pose"] = _pose_term(pred_pos, true_pos, rig)
        if self.config.use_affective:
            terms["affective"] = _affective_term(pred_pos, true_pos, rig)
        if self.config.use_root_loss:
            terms["root"] = root_loss(outputs.root, true_root)
        terms["foot_contact"] = _foot_term(pred_pos, true_pos, rig)
        if "amplitude" in self.active_terms:
            terms["amplitude"] = amplitude_loss(pred_pos, true_pos, outputs.root[..., 0],
                                                true_root[..., 0], rig)
        total = sum(
            (self.weights[name] * value for name, value in terms.items()),
            start=torch.zeros((), dtype=pred_pos.dtype, device=pred_pos.device),
        )
        values = {name: float(value.detach()) for name, value in terms.items()}
        values["total"] = float(total.detach())
        return total, values
