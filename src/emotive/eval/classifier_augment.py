"""Training-time augmentation of the classifier's role tracks across rigs, units and frame rates.

The classifier reads only the positions of the 21 joint roles (:data:`emotive.core.roles.ROLES`),
so another studio's rig differs from the training rig only through where its roles sit and how
long its segments are, through its unit and through its frame rate. :func:`augment` draws one
such variant of a role track ``(T, J, 3)``:

1. **Rig layout** (:func:`jitter_layout`): the spine, chest and neck role points slide along the
   spine (rigs put ``Spine``/``Chest``/``Neck`` joints at different heights), the shoulder
   points move toward the neck (a clavicle mapped as the shoulder), the toe points toward the
   ankle (a ball joint instead of a toe tip); with a small probability the chest falls back to
   the spine and the hand tips to the wrists, as for rigs lacking them
   (:data:`emotive.core.roles.FALLBACKS`).
2. **Proportions** (:func:`scale_segments`): the legs, arms, spine and the widths (hips,
   shoulders) scaled by their own factors along the role tree (:data:`ROLE_PARENT`); the root's
   path scales with the legs, so the feet stay on the ground and strides follow leg length.
3. **Height and unit** (:func:`scale_to_height`): the whole figure scaled to a standing height
   drawn from :attr:`AugmentConfig.height_m` (1.4-2.0 m).
4. **Mirror** (:func:`mirror`): left and right swapped (x negated); emotion is symmetric.
5. **Frame rate** (:func:`resample`): linear resampling to one of
   :attr:`AugmentConfig.frame_rates`, before the classifier's own resampling.

Legend: ``T`` frames, ``J`` joint roles (21, in :data:`~emotive.core.roles.ROLES` order).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.core.roles import ROLE_PARENT, ROLES

#: Segment groups scaled together, by the role at the segment's far end.
SEGMENT_GROUPS: dict[str, tuple[str, ...]] = {
    "legs": ("l_knee", "r_knee", "l_ankle", "r_ankle", "l_toe", "r_toe"),
    "arms": ("l_elbow", "r_elbow", "l_wrist", "r_wrist", "l_handtip", "r_handtip"),
    "spine": ("spine", "chest", "neck", "head"),
    "widths": ("l_hip", "r_hip", "l_shoulder", "r_shoulder"),
}

#: Role order of a mirrored track: every ``l_`` role swapped with its ``r_`` twin.
MIRROR_ORDER: np.ndarray = np.array([
    ROLES.index("r_" + r[2:] if r.startswith("l_") else "l_" + r[2:] if r.startswith("r_") else r)
    for r in ROLES
])

_I = {r: k for k, r in enumerate(ROLES)}
#: Roles in an order where every parent comes before its children.
_TREE_ORDER = tuple(r for r in ROLES if r != "root")


@dataclass(frozen=True)
class AugmentConfig:
    """Ranges of the drawn variants (saved with the classifier's config).

    Attributes:
        height_m: standing height range of the figure, metres.
        segment_scale: each segment group is scaled by a factor in ``1 +- segment_scale``.
        layout_shift: how far role points slide (fraction of the neighbouring segment).
        fallback_probability: chance that the chest falls back to the spine and, separately,
            the hand tips to the wrists.
        mirror_probability: chance of a left/right mirror.
        frame_rates: source frame rates drawn from (frames per second).
    """

    height_m: tuple[float, float] = (1.4, 2.0)
    segment_scale: float = 0.12
    layout_shift: float = 0.15
    fallback_probability: float = 0.15
    mirror_probability: float = 0.5
    frame_rates: tuple[float, ...] = (24.0, 30.0, 60.0, 120.0)

    @classmethod
    def from_dict(cls, values: dict) -> AugmentConfig:
        """The config saved as ``asdict(config)`` (lists back to tuples)."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})


def _check(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 3 or p.shape[1:] != (len(ROLES), 3):
        raise ValueError(f"role tracks must be (T, {len(ROLES)}, 3), got {p.shape}")
    return p


def mirror(points: np.ndarray) -> np.ndarray:
    """Left/right mirror image: x negated and every ``l_`` role swapped with its ``r_`` twin.

    Args:
        points: ``(T, J, 3)`` role positions, metres, Y up.

    Returns:
        ``(T, J, 3)`` mirrored positions.
    """
    p = _check(points)[:, MIRROR_ORDER].copy()
    p[..., 0] *= -1.0
    return p


def scale_segments(points: np.ndarray, scales: dict[str, float]) -> np.ndarray:
    """Rebuild the role tree with the segment groups of ``scales`` lengthened or shortened.

    Each role is placed at its parent's new position plus its old offset from the parent times
    its group's factor (1 for groups not named). The root's path (all three coordinates) is
    scaled by the legs' factor, so the figure stands on the ground and covers ground in
    proportion to its legs.

    Args:
        points: ``(T, J, 3)`` role positions, metres, Y up, ground at y = 0.
        scales: factor by group name of :data:`SEGMENT_GROUPS`.

    Returns:
        ``(T, J, 3)`` positions of the new proportions.
    """
    p = _check(points)
    unknown = sorted(set(scales) - set(SEGMENT_GROUPS))
    if unknown:
        raise ValueError(f"unknown segment groups {unknown}; known: {sorted(SEGMENT_GROUPS)}")
    factor = {r: scales.get(g, 1.0) for g, roles in SEGMENT_GROUPS.items() for r in roles}
    out = np.empty_like(p)
    out[:, 0] = p[:, 0] * scales.get("legs", 1.0)
    for role in _TREE_ORDER:
        k, parent = _I[role], _I[ROLE_PARENT[role]]
        out[:, k] = out[:, parent] + factor.get(role, 1.0) * (p[:, k] - p[:, parent])
    return out


def standing_height(points: np.ndarray) -> float:
    """About the figure's standing height: median head height over the frames / 0.93, metres.

    The head role sits at the base of the skull, about 93 % of the stature.
    """
    p = _check(points)
    ground = np.minimum(p[:, _I["l_toe"], 1], p[:, _I["r_toe"], 1]).min()
    return float(np.median(p[:, _I["head"], 1]) - ground) / 0.93


def scale_to_height(points: np.ndarray, height_m: float) -> np.ndarray:
    """The track scaled about the origin to a standing height of ``height_m`` metres.

    Args:
        points: ``(T, J, 3)`` role positions, metres, Y up, ground at y = 0.
        height_m: the wanted standing height, metres.

    Returns:
        ``(T, J, 3)`` scaled positions.
    """
    p = _check(points)
    return p * (height_m / standing_height(p))


def jitter_layout(points: np.ndarray, rng: np.random.Generator, shift: float = 0.15,
                  fallback_probability: float = 0.15) -> np.ndarray:
    """Another rig's placement of the role points (see the module docstring, step 1).

    Args:
        points: ``(T, J, 3)`` role positions, metres.
        rng: random draws.
        shift: largest slide, as a fraction of the neighbouring segment.
        fallback_probability: chance of the chest and (separately) hand-tip fallbacks.

    Returns:
        ``(T, J, 3)`` positions with the same motion and another layout.
    """
    p = _check(points)
    out = p.copy()

    def at(role: str) -> np.ndarray:
        return p[:, _I[role]]

    def slide(role: str, toward: np.ndarray, amount: float) -> None:
        out[:, _I[role]] = at(role) + amount * toward

    slide("spine", at("chest") - at("root"), rng.uniform(-shift, shift))
    slide("chest", at("neck") - at("spine"), rng.uniform(-shift, shift))
    slide("neck", at("head") - at("chest"), rng.uniform(-shift, shift))
    inward = rng.uniform(0.0, 2.0 * shift)
    toe = rng.uniform(0.0, 2.0 * shift)
    for side in ("l_", "r_"):
        slide(side + "shoulder", at("neck") - at(side + "shoulder"), inward)
        slide(side + "toe", at(side + "ankle") - at(side + "toe"), toe)
    if rng.random() < fallback_probability:
        out[:, _I["chest"]] = out[:, _I["spine"]]
    if rng.random() < fallback_probability:
        for side in ("l_", "r_"):
            out[:, _I[side + "handtip"]] = out[:, _I[side + "wrist"]]
    return out


def resample(points: np.ndarray, fps: float, new_fps: float) -> np.ndarray:
    """Linear resampling in time to ``new_fps``, over the same duration.

    Args:
        points: ``(T, J, 3)`` positions at ``fps`` frames per second.
        fps: frame rate of ``points``.
        new_fps: frame rate of the result.

    Returns:
        ``(T', J, 3)`` with ``T' = floor((T - 1) * new_fps / fps) + 1`` frames.
    """
    p = _check(points)
    if not (fps > 0 and new_fps > 0):
        raise ValueError(f"frame rates must be positive, got {fps} and {new_fps}")
    n = int(np.floor((len(p) - 1) * new_fps / fps + 1e-9)) + 1
    at = np.arange(n) * (fps / new_fps)
    i0 = np.minimum(np.floor(at).astype(np.int64), len(p) - 1)
    i1 = np.minimum(i0 + 1, len(p) - 1)
    w = (at - i0)[:, None, None]
    return (1.0 - w) * p[i0] + w * p[i1]


def augment(points: np.ndarray, fps: float, rng: np.random.Generator,
            config: AugmentConfig | None = None) -> tuple[np.ndarray, float]:
    """One random variant of a role track (see the module docstring for the steps).

    Args:
        points: ``(T, J, 3)`` role positions, metres, Y up, ground at y = 0.
        fps: its frame rate.
        rng: random draws.
        config: the ranges (default :class:`AugmentConfig`).

    Returns:
        ``(T', J, 3)`` float32 positions and their frame rate.
    """
    config = config or AugmentConfig()
    p = jitter_layout(points, rng, config.layout_shift, config.fallback_probability)
    s = config.segment_scale
    p = scale_segments(p, {g: rng.uniform(1.0 - s, 1.0 + s) for g in SEGMENT_GROUPS})
    p = scale_to_height(p, rng.uniform(*config.height_m))
    if rng.random() < config.mirror_probability:
        p = mirror(p)
    new_fps = float(rng.choice(config.frame_rates))
    return resample(p, fps, new_fps).astype(np.float32), new_fps
