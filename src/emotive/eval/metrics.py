"""Batched motion metrics with documented formulas.

Legend: ``...`` any leading (batch) dimensions, ``T`` frames, ``J`` joints (``J + E`` joints
then end sites where joint roles are looked up), ``C`` channels of a feature vector, ``N`` and
``M`` samples, ``P`` vertices of a path, ``K`` emotion changes, ``W`` windows.

Conventions: quaternions are ``(..., 4)`` unit versors ``(w, x, y, z)``; lengths are metres,
Y is up and the ground is the XZ plane ("2D" means the ``(x, z)`` projection); speeds are
finite differences times ``fps`` (per second); every angle a metric returns is in degrees.
Each metric is a pure function of NumPy arrays and raises ``ValueError`` on a bad shape.

Metrics, by family:

* Errors against ground truth (Table 1 of Emotive Gaits): :func:`pose_error` (relative to the
  character's bounding-box diagonal, :func:`bounding_box_diagonal`), :func:`rotation_error`
  (geodesic angle) and :func:`euler_angle_error` (the Euler-angle distance of the paper's
  motion loss, Eq. 8).
* Feet: :func:`foot_skating` (horizontal speed of planted feet) and
  :func:`ground_penetration` (depth of heel and toe below the ground).
* Path following: :func:`path_following` (distance of the root from a 2D polyline, by
  :func:`emotive.paths.closest_points`, and angle between facing and the path's tangent).
* Smoothness: :func:`jerk`, :func:`windowed_jerk` and :func:`transition_smoothness` (jerk
  around emotion changes against real-data jerk).
* Long-horizon stability: :func:`motion_energy` and :func:`stability_report` (collapse and
  explosion).
* Distributions: :func:`frechet_distance`, :func:`gaussian_frechet_distance` and
  :func:`diversity`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, LinAlgWarning, sqrtm
from scipy.spatial.distance import pdist

from emotive.core.roles import JointRoles
from emotive.features.affective import role_indices
from emotive.features.contacts import foot_contacts, foot_positions
from emotive.features.movement import facing_directions
from emotive.paths import closest_points
from emotive.transforms.np_rotations import (
    quaternion_invert,
    quaternion_multiply,
    quaternion_to_axis_angle,
    quaternion_to_euler,
)

#: Horizontal speed (m/s) above which a planted foot counts as skating. Planted heels and toes
#: of Bandai Namco walks move under 0.1 m/s (see :class:`emotive.features.contacts.
#: ContactThresholds`), so faster motion of a foot that should stand still is visible sliding.
SKATE_SPEED = 0.1
#: Share of the reference level below which a window's motion energy counts as collapsed.
COLLAPSE_FRACTION = 0.2
#: Mean joint speed (m/s) under which a window counts as frozen, whatever the reference: motion
#: capture noise alone moves joints faster than 1 mm/s.
FREEZE_SPEED = 1e-3
#: Multiple of the reference level above which a window's motion energy counts as exploded.
EXPLOSION_FACTOR = 5.0
#: Bone length, as a multiple of its first-frame length, above which a bone has blown up.
BONE_FACTOR = 1.5

_REDUCTIONS = ("mean", "frame", "none")


# --------------------------------------------------------------------------- input checks


def _points(x: np.ndarray, name: str, min_frames: int = 1) -> np.ndarray:
    """``x`` as float64 ``(..., T, J, 3)`` with at least ``min_frames`` frames and one joint."""
    a = np.asarray(x, dtype=np.float64)
    if a.ndim < 3 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., T, J, 3), got {a.shape}")
    if a.shape[-3] < min_frames or a.shape[-2] < 1:
        raise ValueError(
            f"{name} needs at least {min_frames} frame(s) and one joint, got shape {a.shape}"
        )
    return a


def _quaternions(q: np.ndarray, name: str) -> np.ndarray:
    """``q`` as float64 ``(..., T, J, 4)`` with at least one frame and one joint."""
    a = np.asarray(q, dtype=np.float64)
    if a.ndim < 3 or a.shape[-1] != 4 or a.shape[-3] < 1 or a.shape[-2] < 1:
        raise ValueError(f"{name} must have shape (..., T, J, 4) with T, J >= 1, got {a.shape}")
    return a


def _same_shape(a: np.ndarray, b: np.ndarray) -> None:
    if a.shape != b.shape:
        raise ValueError(f"predicted and target must have the same shape, got {a.shape} and "
                         f"{b.shape}")


def _positive(value: float, name: str) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number, got {value}")
    return value


def _reduce(values: np.ndarray, reduction: str) -> np.ndarray:
    """Reduce ``(..., T, J)`` per-joint values by ``reduction`` (see :func:`pose_error`)."""
    if reduction == "none":
        return values
    if reduction == "frame":
        return values.mean(-1)
    return values.mean((-2, -1))


def _check_reduction(reduction: str) -> None:
    if reduction not in _REDUCTIONS:
        raise ValueError(f"reduction must be one of {_REDUCTIONS}, got {reduction!r}")


def _root_relative(p: np.ndarray, root_index: int | None) -> np.ndarray:
    """Positions ``(..., T, J, 3)`` minus the root's, without the root joint itself."""
    if root_index is None:
        return p
    joints = p.shape[-2]
    if not -joints <= root_index < joints:
        raise ValueError(f"root_index {root_index} is out of range for {joints} joints")
    if joints < 2:
        raise ValueError("root-relative positions need at least two joints (pass root_index=None)")
    root = root_index % joints
    keep = np.arange(joints) != root
    return (p - p[..., root : root + 1, :])[..., keep, :]


# ------------------------------------------------------------- errors against ground truth


def bounding_box_diagonal(positions: np.ndarray) -> np.ndarray:
    """Size of the character: the longest diagonal of its bounding box.

    The box is axis-aligned and taken per frame (so travelling does not enlarge it); the
    largest diagonal over the frames is returned.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.

    Returns:
        ``(...)`` diagonal lengths, metres.
    """
    p = _points(positions, "positions")
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
    pred, true = _points(predicted, "predicted"), _points(target, "target")
    _same_shape(pred, true)
    _check_reduction(reduction)
    size = bounding_box_diagonal(true) if scale is None else np.asarray(scale, dtype=np.float64)
    if not np.all(size > 0):
        raise ValueError("the character size (bounding-box diagonal) must be positive")
    diff = _root_relative(pred, root_index) - _root_relative(true, root_index)
    err = np.linalg.norm(diff, axis=-1)
    err = _reduce(err, reduction)
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
    pred, true = _quaternions(predicted, "predicted"), _quaternions(target, "target")
    _same_shape(pred, true)
    _check_reduction(reduction)
    relative = quaternion_multiply(quaternion_invert(true), pred)
    angle = np.linalg.norm(quaternion_to_axis_angle(relative), axis=-1)
    return _reduce(np.degrees(angle), reduction)


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
    pred, true = _quaternions(predicted, "predicted"), _quaternions(target, "target")
    _same_shape(pred, true)
    _check_reduction(reduction)
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
    return _reduce(np.degrees(np.linalg.norm(wrapped, axis=-1)), reduction)


# --------------------------------------------------------------------------------- feet


@dataclass(frozen=True)
class FootSkating:
    """Sliding of planted feet; every field is ``(...)``.

    Attributes:
        mean_speed: mean horizontal speed of the planted feet, m/s (0 without contacts).
        ratio: share of the planted intervals faster than the threshold (0 without contacts).
        intervals: number of planted (foot, consecutive-frame) intervals measured, to weight
            averages over clips.
    """

    mean_speed: np.ndarray
    ratio: np.ndarray
    intervals: np.ndarray


def foot_skating(
    positions: np.ndarray,
    roles: JointRoles,
    fps: float,
    contacts: np.ndarray | None = None,
    threshold: float = SKATE_SPEED,
) -> FootSkating:
    """Horizontal speed of feet that touch the ground.

    For each foot and each pair of consecutive frames ``t, t + 1`` in which it is in contact,
    its speed is ``min(|dh_heel|, |dh_toe|) * fps``, ``dh`` the ``(x, z)`` displacement of the
    heel (ankle) and toe. Choices: the slower point is taken because a foot rolling over its
    heel or its toe keeps that point still and does not slide; only intervals with contact at
    both ends count, so the swing before a strike is never mistaken for sliding.

    Contacts detected from the motion itself (``contacts=None``) are frames in which a heel or
    toe is low and slow, so they hide fast sliding; for generated motion pass the contacts of
    the ground truth or of the generator. Real captures do not score zero (heels still move at
    strike), so compare against the same metric on real data.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites, ``T >= 2``.
        roles: resolved roles of the rig (heel = ``*_ankle``, toe = ``*_toe``).
        fps: frames per second.
        contacts: ``(..., T, 2)`` bool, left then right foot; ``None`` detects them clip by
            clip with :func:`emotive.features.contacts.foot_contacts`.
        threshold: speed in m/s above which a planted foot counts as skating.

    Returns:
        The :class:`FootSkating` report.

    Raises:
        ValueError: bad shapes, or a non-positive ``fps``.
    """
    p = _points(positions, "positions", min_frames=2)
    fps = _positive(fps, "fps")
    if contacts is None:
        clips = p.reshape(-1, *p.shape[-3:])
        found = np.stack([foot_contacts(clip, roles, fps) for clip in clips])
        contacts = found.reshape(*p.shape[:-2], 2)
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.shape != (*p.shape[:-2], 2):
        raise ValueError(f"contacts must have shape {(*p.shape[:-2], 2)} (..., T, 2) to match "
                         f"positions {p.shape}, got {contacts.shape}")
    feet = foot_positions(p, roles)[..., [0, 2]]
    speed = np.linalg.norm(np.diff(feet, axis=-4), axis=-1).min(-1) * fps
    planted = contacts[..., 1:, :] & contacts[..., :-1, :]
    count = planted.sum((-2, -1))
    total = np.where(planted, speed, 0.0).sum((-2, -1))
    fast = (planted & (speed > threshold)).sum((-2, -1)).astype(np.float64)
    denom = np.maximum(count, 1)
    return FootSkating(
        mean_speed=np.where(count > 0, total / denom, 0.0),
        ratio=np.where(count > 0, fast / denom, 0.0),
        intervals=count,
    )


@dataclass(frozen=True)
class GroundPenetration:
    """Depth of heels and toes below the ground; every field is ``(...)``.

    Attributes:
        mean: mean depth over every heel and toe sample (points above the ground count 0),
            metres.
        max: largest depth, metres (0 when nothing goes below the ground).
        ratio: share of heel and toe samples below the ground.
    """

    mean: np.ndarray
    max: np.ndarray
    ratio: np.ndarray


def ground_penetration(
    positions: np.ndarray, roles: JointRoles, ground_height: float = 0.0
) -> GroundPenetration:
    """How far the heels (ankles) and toes go below the ground ``y = ground_height``.

    ``d = max(0, ground_height - y)`` for the heel and toe of both feet in every frame. The
    ankle joint sits centimetres above the sole, so in practice the toes (end sites) are what
    penetrates.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
        ground_height: height of the ground plane, metres.

    Returns:
        The :class:`GroundPenetration` report.

    Raises:
        ValueError: positions are not ``(..., T, J + E, 3)``.
    """
    p = _points(positions, "positions")
    depth = np.maximum(float(ground_height) - foot_positions(p, roles)[..., 1], 0.0)
    axes = (-3, -2, -1)
    return GroundPenetration(depth.mean(axes), depth.max(axes), (depth > 0).mean(axes))


# ------------------------------------------------------------------------ path following


@dataclass(frozen=True)
class PathFollowing:
    """Deviation from a desired path, per frame.

    Attributes:
        position_deviation: ``(..., T)`` distance of the root's ``(x, z)`` from the path,
            metres.
        heading_deviation: ``(..., T)`` unsigned angle between the body's facing and the
            path's tangent at the nearest point, degrees in ``[0, 180]``.
    """

    position_deviation: np.ndarray
    heading_deviation: np.ndarray


def path_following(positions: np.ndarray, roles: JointRoles, path: np.ndarray) -> PathFollowing:
    """How closely a character follows a desired 2D polyline path.

    Position deviation is the distance from the root's ``(x, z)`` to the path
    (:func:`emotive.paths.closest_points`); heading deviation is the unsigned angle
    ``atan2(|f x u|, f . u)`` between the facing direction ``f``
    (:func:`emotive.features.movement.facing_directions`, from hips and shoulders) and the
    path's unit tangent ``u`` at that nearest point.

    Args:
        positions: ``(..., T, J + E, 3)`` world positions of joints then end sites.
        roles: resolved roles of the rig.
        path: ``(P, 2)`` ``(x, z)`` vertices in walking order, ``P >= 2``.

    Returns:
        The per-frame :class:`PathFollowing` deviations.

    Raises:
        ValueError: bad shapes or a degenerate path.
    """
    p = _points(positions, "positions")
    root = p[..., role_indices(roles, ("root",))[0], :][..., [0, 2]]
    distance, _, tangent, _ = closest_points(root, path)
    facing = facing_directions(p.reshape(-1, *p.shape[-2:]), roles).reshape(*p.shape[:-2], 2)
    cross = facing[..., 0] * tangent[..., 1] - facing[..., 1] * tangent[..., 0]
    dot = (facing * tangent).sum(-1)
    return PathFollowing(distance, np.degrees(np.arctan2(np.abs(cross), dot)))


# ---------------------------------------------------------------------------- smoothness


def jerk(positions: np.ndarray, fps: float, per_joint: bool = False) -> np.ndarray:
    """Magnitude of the jerk (third time derivative) of joint positions.

    ``j_i = | x_{i+3} - 3 x_{i+2} + 3 x_{i+1} - x_i | * fps^3``, the third finite difference,
    exact for cubic motion; sample ``i`` is centred between frames ``i + 1`` and ``i + 2``.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres, ``T >= 4``.
        fps: frames per second.
        per_joint: keep joints apart instead of averaging them.

    Returns:
        ``(..., T - 3)`` mean over joints (``(..., T - 3, J)`` with ``per_joint``), m/s^3.

    Raises:
        ValueError: fewer than 4 frames, bad shapes, or a non-positive ``fps``.
    """
    p = _points(positions, "positions", min_frames=4)
    fps = _positive(fps, "fps")
    magnitude = np.linalg.norm(np.diff(p, n=3, axis=-3), axis=-1) * fps**3
    return magnitude if per_joint else magnitude.mean(-1)


def _window_frames(window_s: float, fps: float) -> int:
    return max(1, round(_positive(window_s, "window_s") * fps))


def windowed_jerk(positions: np.ndarray, fps: float, window_s: float = 0.5) -> np.ndarray:
    """Mean :func:`jerk` over every window of ``round(window_s * fps)`` consecutive samples.

    This is the statistic :func:`transition_smoothness` measures around emotion changes;
    computed on real clips it gives the reference distribution to compare against.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.
        fps: frames per second.
        window_s: window length in seconds.

    Returns:
        ``(..., T - 3 - n + 1)`` window means, m/s^3 (``n`` the window length in samples).

    Raises:
        ValueError: the clip is shorter than one window (plus the 3 frames a jerk needs).
    """
    j = jerk(positions, fps)
    n = _window_frames(window_s, fps)
    if j.shape[-1] < n:
        raise ValueError(f"a clip of {j.shape[-1] + 3} frames is shorter than one window of "
                         f"{n} jerk samples ({window_s} s) plus 3 frames")
    return np.lib.stride_tricks.sliding_window_view(j, n, axis=-1).mean(-1)


@dataclass(frozen=True)
class TransitionSmoothness:
    """Jerk around emotion changes compared with a reference distribution.

    Attributes:
        jerk: ``(K,)`` mean jerk in the window around each change, m/s^3.
        percentile: ``(K,)`` share of reference values at or below it, in ``[0, 100]``.
        exceeds: ``(K,)`` bool, whether it is above the reference's ``level`` percentile.
        threshold: that percentile of the reference, m/s^3.
    """

    jerk: np.ndarray
    percentile: np.ndarray
    exceeds: np.ndarray
    threshold: float


def transition_smoothness(
    positions: np.ndarray,
    fps: float,
    change_frames: np.ndarray,
    reference: np.ndarray,
    window_s: float = 0.5,
    level: float = 99.0,
) -> TransitionSmoothness:
    """Whether the motion jerks where the emotion changes, judged against real data.

    For a change at frame ``c`` (the first frame of the new emotion) the window holds the
    ``n = round(window_s * fps)`` jerk samples centred on the boundary between frames ``c - 1``
    and ``c`` (moved inwards near the clip's ends); its mean jerk is ranked within
    ``reference``. For a fair
    ranking the reference should be the same statistic on real clips,
    ``windowed_jerk(real, fps, window_s)`` (per-sample :func:`jerk` values, which vary more
    than window means, would make transitions look smoother than they are).

    Args:
        positions: ``(T, J, 3)`` joint positions of one clip, metres, ``T >= 4``.
        fps: frames per second.
        change_frames: ``(K,)`` frames where the emotion changes, in ``[0, T)``.
        reference: any-shaped array of reference jerk values (finite, at least one), m/s^3.
        window_s: window length in seconds.
        level: percentile of the reference that a transition must not exceed.

    Returns:
        The :class:`TransitionSmoothness` report.

    Raises:
        ValueError: bad shapes, frames out of range, an empty or non-finite reference, or a
            level outside ``[0, 100]``.
    """
    p = _points(positions, "positions", min_frames=4)
    if p.ndim != 3:
        raise ValueError(f"positions must be one clip (T, J, 3), got {p.shape}")
    frames = np.asarray(change_frames)
    integral = np.issubdtype(frames.dtype, np.integer) or frames.size == 0
    if frames.ndim != 1 or not integral:
        raise ValueError(f"change_frames must be a (K,) integer array, got shape {frames.shape} "
                         f"of {frames.dtype}")
    frames = frames.astype(np.int64)
    if np.any((frames < 0) | (frames >= len(p))):
        raise ValueError(f"change_frames must lie in [0, {len(p)}), got {frames.tolist()}")
    ref = np.sort(np.asarray(reference, dtype=np.float64).ravel())
    if not ref.size or not np.all(np.isfinite(ref)):
        raise ValueError("reference must hold at least one value, all finite")
    if not 0 <= level <= 100:
        raise ValueError(f"level must lie in [0, 100], got {level}")
    j = jerk(p, fps)
    n = min(_window_frames(window_s, fps), len(j))
    # Samples i..i+3 straddle the boundary c - 1 | c for i in [c - 3, c - 1]: centre on c - 2.
    # Near the clip's ends the window slides inwards, so every window has n samples like those
    # of windowed_jerk.
    start = np.clip(frames - 2 - n // 2, 0, len(j) - n)
    window_mean = j[start[:, None] + np.arange(n)].mean(-1)
    threshold = float(np.percentile(ref, level))
    return TransitionSmoothness(
        jerk=window_mean,
        percentile=100.0 * np.searchsorted(ref, window_mean, side="right") / ref.size,
        exceeds=window_mean > threshold,
        threshold=threshold,
    )


# --------------------------------------------------------------- long-horizon stability


def _joint_speed(p: np.ndarray, fps: float, root_index: int | None) -> np.ndarray:
    """``(..., T - 1, J')`` speed of every (root-relative) joint between consecutive frames."""
    with np.errstate(invalid="ignore", over="ignore"):
        rel = _root_relative(p, root_index)
        return np.linalg.norm(np.diff(rel, axis=-3), axis=-1) * fps


def motion_energy(
    positions: np.ndarray, fps: float, window_s: float = 1.0, root_index: int | None = 0
) -> np.ndarray:
    """Mean joint speed in consecutive windows, over time.

    ``E_w = mean over the speed samples i in window w and joints j of |x_{i+1,j} - x_{ij}| fps``
    on windows of ``n = round(window_s * fps)`` samples (frame pairs); a last, partial window
    is dropped. Positions are root-relative by default, so a character gliding with a frozen
    pose has no energy.

    Args:
        positions: ``(..., T, J, 3)`` joint positions, metres.
        fps: frames per second.
        window_s: window length in seconds.
        root_index: joint subtracted from the others and left out; ``None`` keeps world
            positions.

    Returns:
        ``(..., W)`` energies in m/s, ``W = (T - 1) // n``; NaN or inf where the input is.

    Raises:
        ValueError: the clip is shorter than one window, or bad shapes.
    """
    p = _points(positions, "positions", min_frames=2)
    fps = _positive(fps, "fps")
    speed = _joint_speed(p, fps, root_index).mean(-1)
    n = _window_frames(window_s, fps)
    count = speed.shape[-1] // n
    if count == 0:
        raise ValueError(f"a clip of {p.shape[-3]} frames is shorter than one window of "
                         f"{window_s} s ({n + 1} frames)")
    return speed[..., : count * n].reshape(*speed.shape[:-1], count, n).mean(-1)


@dataclass(frozen=True)
class StabilityReport:
    """Long-horizon stability of one clip.

    Attributes:
        energy: ``(W,)`` :func:`motion_energy` per window, m/s.
        window_s: window length, seconds (window ``w`` starts at ``w * window_s``).
        reference_energy: the level collapse and explosion are measured against, m/s.
        collapsed: some window's energy fell below the collapse fraction of the reference, or
            under the freeze speed.
        collapse_time: start of the first such window, seconds (``None`` if none).
        exploded: non-finite positions, a window above the explosion factor times the
            reference, or a bone stretched beyond the bone factor.
        explosion_time: first frame or window start at which that happened, seconds.
        non_finite: some position is NaN or infinite.
        max_bone_ratio: largest bone length over its first-frame length (NaN without
            ``parents``).
    """

    energy: np.ndarray
    window_s: float
    reference_energy: float
    collapsed: bool
    collapse_time: float | None
    exploded: bool
    explosion_time: float | None
    non_finite: bool
    max_bone_ratio: float

    @property
    def stable(self) -> bool:
        """Neither collapsed nor exploded."""
        return not (self.collapsed or self.exploded)


def _first_time(mask: np.ndarray, seconds_per_step: float) -> float | None:
    hits = np.flatnonzero(mask)
    return float(hits[0] * seconds_per_step) if hits.size else None


def stability_report(
    positions: np.ndarray,
    fps: float,
    parents: Sequence[int] | None = None,
    reference_energy: float | None = None,
    window_s: float = 1.0,
    root_index: int | None = 0,
    collapse_fraction: float = COLLAPSE_FRACTION,
    freeze_speed: float = FREEZE_SPEED,
    explosion_factor: float = EXPLOSION_FACTOR,
    bone_factor: float = BONE_FACTOR,
) -> StabilityReport:
    """Detect collapse (the motion dies out or freezes) and explosion (it blows up).

    * Collapse: a window of :func:`motion_energy` below ``collapse_fraction`` times the
      reference, or below ``freeze_speed`` (a frozen pose, whatever the reference).
    * Explosion: a NaN or infinite position; a window above ``explosion_factor`` times the
      reference; or, with ``parents``, a bone longer than ``bone_factor`` times its length in
      the first frame (bones of forward kinematics never stretch; this catches models that
      output positions).

    The reference defaults to the first window's energy, which suits autoregressive
    continuations of a real seed; pass the energy of real clips of the same kind otherwise.
    Without a finite positive reference only freezes, non-finite values and bones are judged.

    Args:
        positions: ``(T, J, 3)`` joint positions of one clip, metres.
        fps: frames per second.
        parents: ``(J,)`` parent of each joint (``-1`` for roots), for the bone check.
        reference_energy: reference mean joint speed, m/s.
        window_s: window length in seconds.
        root_index: as in :func:`motion_energy`.
        collapse_fraction: share of the reference below which a window has collapsed.
        freeze_speed: energy (m/s) below which a window is frozen.
        explosion_factor: multiple of the reference above which a window has exploded.
        bone_factor: bone stretch above which the skeleton has exploded.

    Returns:
        The :class:`StabilityReport`.

    Raises:
        ValueError: bad shapes, a clip shorter than one window, ``parents`` of the wrong
            length or a negative given reference.
    """
    p = _points(positions, "positions", min_frames=2)
    if p.ndim != 3:
        raise ValueError(f"positions must be one clip (T, J, 3), got {p.shape}")
    fps = _positive(fps, "fps")
    energy = motion_energy(p, fps, window_s, root_index)
    n = _window_frames(window_s, fps)
    window_time = n / fps
    if reference_energy is None:
        ref = float(energy[0])
    else:
        ref = float(reference_energy)
        if not ref >= 0:
            raise ValueError(f"reference_energy must be non-negative, got {ref}")
    judged = bool(np.isfinite(ref) and ref > 0)

    collapsed_windows = energy < freeze_speed
    if judged:
        collapsed_windows |= energy < collapse_fraction * ref
    finite_frames = np.isfinite(p).all((-2, -1))
    times = [_first_time(~finite_frames, 1.0 / fps)]
    if judged:
        times.append(_first_time(energy > explosion_factor * ref, window_time))

    max_ratio = float("nan")
    if parents is not None:
        par = np.asarray(parents, dtype=np.int64)
        if par.shape != (p.shape[1],):
            raise ValueError(f"parents must have one entry per joint ({p.shape[1]}), got "
                             f"{par.shape}")
        child = np.flatnonzero(par >= 0)
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            length = np.linalg.norm(p[:, child] - p[:, par[child]], axis=-1)
            ratio = length / length[:1]
        # Bones of zero rest length (coincident joints) have no scale to stretch against.
        ratio = np.where(length[:1] > 0, ratio, 1.0)
        if ratio.size and np.isfinite(ratio).any():
            max_ratio = float(np.nanmax(np.where(np.isfinite(ratio), ratio, np.nan)))
        times.append(_first_time((ratio > bone_factor).any(-1), 1.0 / fps))

    hits = [t for t in times if t is not None]
    return StabilityReport(
        energy=energy,
        window_s=window_time,
        reference_energy=ref,
        collapsed=bool(collapsed_windows.any()),
        collapse_time=_first_time(collapsed_windows, window_time),
        exploded=bool(hits),
        explosion_time=min(hits) if hits else None,
        non_finite=not bool(finite_frames.all()),
        max_bone_ratio=max_ratio,
    )


# -------------------------------------------------------------------------- distributions


def _trace_sqrt_product(s1: np.ndarray, s2: np.ndarray) -> float:
    """``Tr((S1 S2)^(1/2))`` for symmetric positive semi-definite ``(C, C)`` matrices."""
    product = s1 @ s2
    with warnings.catch_warnings():
        warnings.simplefilter("error", LinAlgWarning)
        try:
            root = sqrtm(product)
        except (LinAlgWarning, LinAlgError):
            root = None
    if root is not None and np.all(np.isfinite(root)):
        size = max(float(np.abs(root).max()), 1e-300)
        # S1 S2 has real non-negative eigenvalues: an imaginary part above rounding, or a root
        # that does not square back to the product, means sqrtm went wrong on a (near-)singular
        # product rather than found a real answer.
        imaginary = float(np.abs(np.imag(root)).max()) if np.iscomplexobj(root) else 0.0
        residual = np.linalg.norm(root @ root - product)
        if imaginary <= 1e-6 * size and residual <= 1e-8 * max(np.linalg.norm(product), 1e-300):
            return float(np.trace(root).real)
    # (S1 S2)^(1/2) has the eigenvalues of (R S2 R)^(1/2) with R = S1^(1/2): a symmetric form
    # whose eigenvalues are real and which stays exact when a covariance is singular.
    w, v = np.linalg.eigh(s1)
    r = (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T
    inner = r @ s2 @ r
    return float(np.sqrt(np.clip(np.linalg.eigvalsh(0.5 * (inner + inner.T)), 0.0, None)).sum())


def gaussian_frechet_distance(
    mu1: np.ndarray,
    sigma1: np.ndarray,
    mu2: np.ndarray,
    sigma2: np.ndarray,
) -> float:
    """Fréchet (2-Wasserstein squared) distance between two Gaussians.

    ``d = |mu1 - mu2|^2 + Tr(S1 + S2 - 2 (S1 S2)^(1/2))`` with the matrix square root from
    :func:`scipy.linalg.sqrtm`, whose imaginary part from rounding is dropped. When the
    product is (near-)singular and the root is non-finite, has a non-negligible imaginary part
    or does not square back to the product, the trace is taken instead from the symmetric form
    ``Tr((R S2 R)^(1/2))``, ``R = S1^(1/2)``, through eigenvalue decompositions with negative
    rounding errors clipped to 0 (exact for singular covariances, where adding a ridge would
    bias the result by ``O(sqrt(ridge))``). The result is clipped at 0.

    Args:
        mu1: ``(C,)`` mean of the first distribution.
        sigma1: ``(C, C)`` covariance of the first distribution.
        mu2: ``(C,)`` mean of the second distribution.
        sigma2: ``(C, C)`` covariance of the second distribution.

    Returns:
        The squared distance, in squared feature units.

    Raises:
        ValueError: shapes do not agree or values are not finite.
    """
    m1, m2 = (np.atleast_1d(np.asarray(m, dtype=np.float64)) for m in (mu1, mu2))
    s1, s2 = (np.atleast_2d(np.asarray(s, dtype=np.float64)) for s in (sigma1, sigma2))
    c = m1.shape[0]
    if m1.shape != (c,) or m2.shape != (c,) or s1.shape != (c, c) or s2.shape != (c, c):
        raise ValueError(f"means must be (C,) and covariances (C, C) with one C, got "
                         f"{m1.shape}, {s1.shape}, {m2.shape}, {s2.shape}")
    if not all(np.all(np.isfinite(a)) for a in (m1, m2, s1, s2)):
        raise ValueError("means and covariances must be finite")
    s1, s2 = 0.5 * (s1 + s1.T), 0.5 * (s2 + s2.T)
    diff = m1 - m2
    d = diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * _trace_sqrt_product(s1, s2)
    return max(float(d), 0.0)


def _feature_set(x: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] < 2 or a.shape[1] < 1:
        raise ValueError(f"{name} must have shape (N, C) with N >= 2 samples, got {a.shape}")
    return a


def frechet_distance(features_a: np.ndarray, features_b: np.ndarray) -> float:
    """Fréchet distance between two sets of feature vectors (as FID, on motion features).

    Each set is summarized by its mean and covariance (``ddof = 1``) and compared with
    :func:`gaussian_frechet_distance`. With fewer samples than channels the covariances are
    singular (handled exactly), but such estimates are biased, so compare distances computed
    from equal sample counts.

    Args:
        features_a: ``(N, C)`` feature vectors, ``N >= 2``.
        features_b: ``(M, C)`` feature vectors, ``M >= 2``.

    Returns:
        The squared distance, in squared feature units.

    Raises:
        ValueError: bad shapes, different ``C``, or non-finite features.
    """
    a, b = _feature_set(features_a, "features_a"), _feature_set(features_b, "features_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"the sets have different channel counts: {a.shape[1]} and "
                         f"{b.shape[1]}")
    return gaussian_frechet_distance(
        a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False)
    )


def diversity(samples: np.ndarray, points: bool = False) -> float:
    """Mean distance between every pair of samples.

    ``div = 2 / (N (N - 1)) sum_{a < b} d(x_a, x_b)`` with ``d`` the Euclidean distance of the
    flattened samples (feature vectors); with ``points``, samples are arrays of 3D points and
    ``d`` is the mean distance between corresponding points (metres for positions).

    Args:
        samples: ``(N, C)`` feature vectors, or any ``(N, ...)`` array (flattened per sample);
            with ``points``, ``(N, ..., 3)`` such as positions ``(N, T, J, 3)``. ``N >= 2``.
        points: measure distances point by point instead of on the flattened samples.

    Returns:
        The mean pairwise distance.

    Raises:
        ValueError: fewer than two samples, or the last axis is not 3 with ``points``.
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim < 2 or x.shape[0] < 2:
        raise ValueError(f"samples must have shape (N, ...) with N >= 2, got {x.shape}")
    if not points:
        return float(pdist(x.reshape(len(x), -1)).mean())
    if x.ndim < 3 or x.shape[-1] != 3:
        raise ValueError(f"with points=True samples must have shape (N, ..., 3), got {x.shape}")
    flat = x.reshape(len(x), -1, 3)
    # One row of pairs per sample keeps memory at N x points instead of N^2 x points.
    total = sum(
        np.linalg.norm(flat[a + 1 :] - flat[a], axis=-1).mean(-1).sum() for a in range(len(x) - 1)
    )
    return float(total / (len(x) * (len(x) - 1) / 2))
