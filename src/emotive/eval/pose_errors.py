"""Errors of a motion against ground truth (Table 1 of Emotive Gaits).

:func:`pose_error` (relative to the character's bounding-box diagonal,
:func:`bounding_box_diagonal`), :func:`rotation_error` (geodesic angle) and
:func:`euler_angle_error` (the Euler-angle distance of the paper's motion loss, Eq. 8).
Conventions (shapes, units, degrees) are those of :mod:`emotive.eval.metric_inputs`.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from emotive.eval.metric_inputs import (
    check_points,
    check_quaternions,
    check_reduction,
    check_same_shape,
    reduce_values,
    root_relative,
)
from emotive.transforms.np_rotations import (
    quaternion_invert,
    quaternion_multiply,
    quaternion_to_axis_angle,
    quaternion_to_euler,
)

__all__ = [
    "bounding_box_diagonal",
    "euler_angle_error",
    "pose_error",
    "rotation_error",
]


def bounding_box_diagonal(positions: np.ndarray) -> np.ndarray:
    """Size of the character: the longest diagonal of its bounding box.

    The box is axis-aligned and taken per frame (so travelling does not enlarge it); the
    largest diagonal over the frames is returned.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.

    Returns:
        ``(...)`` diagonal lengths, metres.
    """
    p = check_points(positions, "positions")
    return np.linalg.norm(p.max(-2) - p.min(-2), axis=-1).max(-1)


def pose_error(
    predicted: np.ndarray,
    target: np.ndarray,
    root_index: int | None = 0,
    scale: float | np.ndarray | None = None,
    reduction: str = "mean",
) -> np.ndarray:
    """Joint position error relative to the size of the character (Table 1, "Pose Error").

    The paper computes "position error relative to the longest diagonal of the bounding box of
    the characters we test" and reports "mean pose errors relative to the scale of the input
    data", without a formula. This implements

        ``e_tj = || (X_tj - X_t0) - (X^_tj - X^_t0) || / D``

    averaged over frames and the non-root joints, with ``X`` the target, ``X^`` the
    prediction and ``D`` the :func:`bounding_box_diagonal` of the target. Choices: positions are
    root-relative by default, as in the paper's pose loss (Eq. 9, which sums over ``j >= 1``
    after subtracting the root), so the pose is judged apart from the trajectory; the error is
    the Euclidean distance (not squared) and the bounding box is the target's, per frame, its
    largest diagonal over the clip.

    Args:
        predicted: ``(..., T, J, 3)`` predicted positions, metres.
        target: ``(..., T, J, 3)`` ground-truth positions, metres.
        root_index: joint subtracted from every joint and left out of the mean; pass the
            index of the ``root`` role (``Hips`` on the Bandai rig, whose joint 0 is a static
            top node: :func:`emotive.eval.table1.table1` does); ``None`` compares world
            positions of all joints.
        scale: the character size ``D``, broadcastable to ``(...)``; ``None`` uses the
            target's :func:`bounding_box_diagonal`. Pass ``1.0`` for errors in metres.
        reduction: ``"mean"`` returns ``(...)``, ``"frame"`` the mean over joints ``(..., T)``,
            ``"none"`` every joint ``(..., T, J')`` (``J' = J - 1`` when root-relative).

    Returns:
        Relative errors (a fraction of ``D``), shaped by ``reduction``.

    Raises:
        ValueError: shapes differ or are not ``(..., T, J, 3)``, the reduction or root index is
            invalid, or the character size is not positive.
    """
    pred, true = check_points(predicted, "predicted"), check_points(target, "target")
    check_same_shape(pred, true)
    check_reduction(reduction)
    size = bounding_box_diagonal(true) if scale is None else np.asarray(scale, dtype=np.float64)
    if not np.all(size > 0):
        raise ValueError("the character size (bounding-box diagonal) must be positive")
    diff = root_relative(pred, root_index) - root_relative(true, root_index)
    err = np.linalg.norm(diff, axis=-1)
    err = reduce_values(err, reduction)
    extra = {"mean": 0, "frame": 1, "none": 2}[reduction]
    return err / np.reshape(size, np.shape(size) + (1,) * extra)


def rotation_error(
    predicted: np.ndarray, target: np.ndarray, reduction: str = "mean"
) -> np.ndarray:
    """Geodesic angle between predicted and true local joint rotations (Table 1, degrees).

    ``theta_tj = 2 atan2(|v|, |w|)`` of the relative rotation ``(w, v) = q_tj^-1 q^_tj``: the
    angle of the smallest rotation taking one onto the other, in ``[0, 180]`` degrees and
    blind to the sign of either versor. The paper reports rotation errors "in degrees" without a
    formula (its Table 1 values, 0.04-0.06, are too small to be degrees of this angle on
    walks and may be radians or a fraction; they are not reproduced here).

    Args:
        predicted: ``(..., T, J, 4)`` predicted local rotations (normalized first).
        target: ``(..., T, J, 4)`` ground-truth local rotations.
        reduction: ``"mean"`` ``(...)``, ``"frame"`` ``(..., T)`` or ``"none"`` ``(..., T, J)``.

    Returns:
        Angles in degrees, shaped by ``reduction``.

    Raises:
        ValueError: shapes differ or are not ``(..., T, J, 4)``, or the reduction is invalid.
    """
    pred, true = check_quaternions(predicted, "predicted"), check_quaternions(target, "target")
    check_same_shape(pred, true)
    check_reduction(reduction)
    relative = quaternion_multiply(quaternion_invert(true), pred)
    angle = np.linalg.norm(quaternion_to_axis_angle(relative), axis=-1)
    return reduce_values(np.degrees(angle), reduction)


def euler_angle_error(
    predicted: np.ndarray,
    target: np.ndarray,
    order: str | Sequence[str],
    reduction: str = "mean",
) -> np.ndarray:
    """Distance between the Euler angles of predicted and true local rotations (degrees).

    The paper's motion loss (Eq. 8) compares ``q2e(q_j^t) - q2e(q^_j^t)`` with ``q2e`` mapping
    versors to Euler angles in ``[0, 2 pi]^3``, squared and summed over joints and frames. This
    reports, per joint and frame, the Euclidean norm of that difference (not squared, so it is
    in degrees), averaged. Choice: each component of the difference is wrapped to
    ``(-180, 180]`` so that 359 and 1 degrees differ by 2, not 358 (an unwrapped difference of
    angles in ``[0, 2 pi]`` would make this jump). Euler angles come from
    :func:`emotive.transforms.np_rotations.quaternion_to_euler` (middle angle in
    ``[-90, 90]``); near gimbal lock, close rotations can have distant Euler angles, which
    :func:`rotation_error` does not suffer from.

    Args:
        predicted: ``(..., T, J, 4)`` predicted local rotations.
        target: ``(..., T, J, 4)`` ground-truth local rotations.
        order: intrinsic Euler order for every joint (``"ZXY"``) or one per joint (length
            ``J``, e.g. ``[skeleton.rotation_order(j) for j in range(J)]``).
        reduction: ``"mean"`` ``(...)``, ``"frame"`` ``(..., T)`` or ``"none"`` ``(..., T, J)``.

    Returns:
        Euler-angle distances in degrees, shaped by ``reduction``.

    Raises:
        ValueError: shapes differ or are wrong, an order is invalid or ``order`` does not have
            one entry per joint, or the reduction is invalid.
    """
    pred, true = check_quaternions(predicted, "predicted"), check_quaternions(target, "target")
    check_same_shape(pred, true)
    check_reduction(reduction)
    joints = pred.shape[-2]
    orders = [order] * joints if isinstance(order, str) else [str(o) for o in order]
    if len(orders) != joints:
        raise ValueError(f"order must be one string or one per joint ({joints}), got "
                         f"{len(orders)}")
    orders = [o.upper() for o in orders]
    diff = np.empty((*pred.shape[:-1], 3))
    # One conversion per distinct order (at most six), each over all the joints that use it.
    for o in dict.fromkeys(orders):
        cols = [j for j, x in enumerate(orders) if x == o]
        diff[..., cols, :] = (quaternion_to_euler(pred[..., cols, :], o)
                              - quaternion_to_euler(true[..., cols, :], o))
    wrapped = np.pi - np.mod(np.pi - diff, 2.0 * np.pi)
    return reduce_values(np.degrees(np.linalg.norm(wrapped, axis=-1)), reduction)
