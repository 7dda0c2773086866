"""Operations on whole motion clips: timing, cutting, mirroring, placement and facing.

Every function takes a :class:`~emotive.core.Motion` and returns a new one (or arrays); none
loops over frames in Python. World conventions are the toolkit's: metres, Y up, ground = XZ.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``K`` frames after resampling.

Mirroring rule
--------------
:func:`mirror` reflects the world across the ``X = 0`` plane (``M = diag(-1, 1, 1)``) and swaps
left and right joints (``sigma``). Reflecting a joint's world frame ``R`` gives ``M R``, which
is not a rotation; each joint ``j`` therefore gets a local reflection ``D_j`` with
``det(D_j) = -1``, chosen from ``-I`` (point reflection) and the three axis-plane reflections
``diag(-1, 1, 1)``, ``diag(1, -1, 1)``, ``diag(1, 1, -1)``, and the mirrored world frame is
``M R_sigma(j) D_j``. Forward kinematics then forces:

* local rotations ``q'_j = conj(d_p) * q_sigma(j) * d_j``, where ``d`` is the unit quaternion of
  the rotation part of ``-D`` (``1``, ``i``, ``j`` or ``k``) and ``p`` the parent (the world's
  ``d`` is ``i``, the quaternion of ``-M``);
* local translations, rest offsets and end-site offsets ``t'_j = D_p t_sigma(j)`` (for roots,
  ``M t``).

With these, mirrored world positions equal the reflected original positions exactly, for any
choice of ``D_j``. The choice only decides whether the mirrored rig keeps the original rest
offsets and whether mirrored local rotations look like the rig's own: ``D_j`` is the candidate
that maps the mirrored children's offsets onto the joint's own children's offsets (within 5% of
the bone length); ties go to the parent's ``D``, then to ``-I``. On a rig at rest in a T-pose
with identity rotations (CMU style) every joint gets ``diag(-1, 1, 1)``, the familiar
``(w, x, y, z) -> (w, x, -y, -z)``. On the Bandai Namco rig (bones along local X, right-side
offsets negated) the limbs get ``-I`` (their local rotations are copied across unchanged), the
hips ``diag(1, -1, 1)`` and spine, chest, neck and head ``diag(1, 1, -1)``, and the mirrored rig
has the original offsets up to the rig's own asymmetry (below half a millimetre).

Because the maps are signed permutations, mirroring twice gives back rotations, translations and
offsets bit for bit, except that a joint whose ``D`` differs in kind from its parent's (point
versus plane reflection, e.g. Bandai's shoulders and upper legs) comes back as ``-q``: the same
rotation, as ``q`` and ``-q`` always are.
"""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.errors import EmotiveError, RigError
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_slerp,
    yaw_quaternion,
)

__all__ = [
    "MirrorMap",
    "MotionError",
    "canonicalize_facing",
    "concatenate",
    "crop",
    "facing_directions",
    "heading",
    "mirror",
    "mirror_map",
    "mirror_skeleton",
    "place_on_ground",
    "resample",
    "root_trajectory",
]

RoleMap = str | Path | dict[str, str] | None


class MotionError(EmotiveError):
    """A motion operation asked for something the clip cannot give (bad range, rate, mix)."""


# ---------------------------------------------------------------------------------------------
# Timing and cutting


def resample(motion: Motion, fps: float) -> Motion:
    """Resample a clip to another frame rate.

    Frame ``k`` of the result samples the original at time ``k / fps``: rotations by slerp
    between the two nearest frames, translations linearly. The first frame is kept exactly.
    The result has ``K = round(T * fps / motion.fps)`` frames (at least one), so its
    :attr:`~emotive.core.Motion.duration` ``K / fps`` is the original's as closely as the new
    frame grid allows; samples past the last original frame hold it.

    Args:
        motion: the clip, ``T`` frames at ``motion.fps``.
        fps: the new frame rate, positive.

    Returns:
        A motion with rotations ``(K, J, 4)`` and positions ``(K, J, 3)`` at ``fps``.

    Raises:
        MotionError: ``fps`` is not a positive finite number.
    """
    if not (isinstance(fps, numbers.Real) and math.isfinite(fps) and fps > 0):
        raise MotionError(f"resample needs a positive frame rate, got fps={fps!r}")
    fps = float(fps)
    n = motion.num_frames
    if fps == motion.fps or n == 0:
        return motion.replace(
            rotations=motion.rotations.copy(), positions=motion.positions.copy(), fps=fps
        )
    k = max(1, math.floor(n * fps / motion.fps + 0.5))
    src = np.arange(k) * (motion.fps / fps)
    # Times that land on an original frame up to rounding take that frame exactly.
    near = np.round(src)
    src = np.where(np.abs(src - near) < 1e-9, near, src)
    src = np.minimum(src, n - 1)
    i0 = np.floor(src).astype(np.int64)
    i1 = np.minimum(i0 + 1, n - 1)
    alpha = src - i0
    rot = quaternion_slerp(motion.rotations[i0], motion.rotations[i1], alpha[:, None])
    exact = alpha == 0.0
    rot[exact] = motion.rotations[i0[exact]]
    a = alpha[:, None, None]
    pos = (1.0 - a) * motion.positions[i0] + a * motion.positions[i1]
    return motion.replace(rotations=rot, positions=pos, fps=fps)


def crop(
    motion: Motion, start: float = 0, stop: float | None = None, *, seconds: bool = False
) -> Motion:
    """Frames ``start`` (inclusive) to ``stop`` (exclusive) of a clip.

    Args:
        motion: the clip, ``T`` frames.
        start: first frame kept, or its time in seconds when ``seconds`` is true.
        stop: frame after the last one kept (``None``: the end of the clip), or its time.
        seconds: read ``start`` and ``stop`` as seconds, rounded to the nearest frame
            (``crop(m, 1.0, 2.0, seconds=True)`` keeps one second).

    Returns:
        A motion with rotations ``(stop - start, J, 4)`` and positions ``(stop - start, J, 3)``.

    Raises:
        MotionError: the range is empty or reaches outside ``[0, T]``.
    """
    n = motion.num_frames
    unit = "s" if seconds else ""
    if seconds:
        first = math.floor(start * motion.fps + 0.5)
        last = n if stop is None else math.floor(stop * motion.fps + 0.5)
    else:
        if start != int(start) or (stop is not None and stop != int(stop)):
            raise MotionError(
                f"crop takes whole frame numbers, got start={start}, stop={stop}: "
                "pass seconds=True for times"
            )
        first, last = int(start), (n if stop is None else int(stop))
    if not 0 <= first < last <= n:
        raise MotionError(
            f"cannot crop {start}{unit}..{'end' if stop is None else f'{stop}{unit}'} "
            f"(frames {first}..{last}) from a clip of {n} frames ({motion.duration:.3f} s): "
            f"use 0 <= start < stop <= {n} frames"
        )
    return motion.replace(
        rotations=motion.rotations[first:last].copy(),
        positions=motion.positions[first:last].copy(),
    )


def _rig_difference(a: Skeleton, b: Skeleton, atol: float) -> str | None:
    if a.names != b.names:
        return "joint names differ"
    if not np.array_equal(a.parents, b.parents):
        return "hierarchies differ"
    if a.channels != b.channels:
        return "channel layouts differ"
    # Joints with position channels carry their translation in every frame; only the others
    # use the rest offset (Bandai clips differ in the Hips offset, a mere start position).
    fixed = ~a.animated_translation
    gap = np.abs(a.offsets - b.offsets)[fixed]
    if gap.size and gap.max() > atol:
        return f"rest offsets of joints without position channels differ by up to {gap.max():.3g} m"
    if not np.array_equal(a.end_site_parents, b.end_site_parents) or not np.allclose(
        a.end_site_offsets, b.end_site_offsets, atol=atol, rtol=0.0
    ):
        return "end sites differ"
    return None


def concatenate(motions: Sequence[Motion], atol: float = 1e-6) -> Motion:
    """Join clips of one rig end to end (no blending at the seams).

    Args:
        motions: clips with rotations ``(T_i, J, 4)`` and positions ``(T_i, J, 3)``, all on the
            same rig and at the same frame rate.
        atol: largest difference (metres) in the rest offsets of joints without position
            channels, and of end sites, still counted as the same rig.

    Returns:
        A motion with ``sum(T_i)`` frames, the first clip's skeleton and metadata.

    Raises:
        MotionError: no clips, or the frame rates differ.
        RigError: the rigs differ (names, hierarchy, channels, or offsets the frames use).
    """
    motions = list(motions)
    if not motions:
        raise MotionError("concatenate needs at least one motion")
    first = motions[0]
    for n, m in enumerate(motions[1:], start=1):
        if m.fps != first.fps:
            raise MotionError(
                f"cannot concatenate clips at different frame rates: clip 0 is {first.fps:g} fps, "
                f"clip {n} is {m.fps:g} fps; resample them to one rate first"
            )
        diff = _rig_difference(first.skeleton, m.skeleton, atol)
        if diff is not None:
            raise RigError(
                f"cannot concatenate clip {n} with clip 0: {diff}; concatenate clips of one rig "
                "(or raise atol if the offsets differ only by rounding)"
            )
    return first.replace(
        rotations=np.concatenate([m.rotations for m in motions]),
        positions=np.concatenate([m.positions for m in motions]),
    )


# ---------------------------------------------------------------------------------------------
# Mirroring

# Sided name patterns: (regex, replacement for left, replacement for right). "Strong" patterns
# make a joint without a counterpart an error; the bare one-letter prefix is too easily part of
# a word ("Root") and only pairs joints when the counterpart exists.
_STRONG_SIDES: tuple[tuple[str, str, str], ...] = (
    (r"(?<=[_.\-])([LR])$", "L", "R"),
    (r"(?<=[_.\-])([lr])$", "l", "r"),
    (r"(Left|Right)", "Left", "Right"),
    (r"(left|right)", "left", "right"),
    (r"(LEFT|RIGHT)", "LEFT", "RIGHT"),
    (r"^([LR])(?=[_.\-])", "L", "R"),
    (r"^([lr])(?=[_.\-])", "l", "r"),
)
_WEAK_SIDES: tuple[tuple[str, str, str], ...] = ((r"^([LR])(?=[A-Z0-9])", "L", "R"),)

# Candidate reflections D: sign vectors (D = diag(s)) and the unit quaternion d of -D.
_REFLECTION_NAMES = ("-I", "x", "y", "z")
_REFLECTION_SIGNS = np.array(
    [[-1.0, -1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, -1.0]]
)
_REFLECTION_QUATS = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
_WORLD = 1  # the world mirror M = diag(-1, 1, 1)
_TIE = 0.05  # relative offset error under which two reflections count as equally good


def _swap_side(name: str, patterns: tuple[tuple[str, str, str], ...]) -> list[str]:
    out = []
    for pattern, left, right in patterns:
        swapped = re.sub(
            pattern,
            lambda m, left=left, right=right: right if m.group(1) == left else left,
            name,
        )
        if swapped != name:
            out.append(swapped)
    return out


def _pair_joints(skeleton: Skeleton, pairs: Mapping[str, str] | None) -> np.ndarray:
    names = skeleton.names
    where = {n: i for i, n in enumerate(names)}
    sigma = np.arange(len(names))
    if pairs is not None:
        for a, b in pairs.items():
            for x in (a, b):
                if x not in where:
                    raise RigError(
                        f"mirror pair {a!r} <-> {b!r} names {x!r}, which is not in the rig"
                    )
            sigma[where[a]], sigma[where[b]] = where[b], where[a]
    else:
        unpaired = []
        for j, name in enumerate(names):
            strong = _swap_side(name, _STRONG_SIDES)
            found = [c for c in strong + _swap_side(name, _WEAK_SIDES) if c in where]
            if found:
                sigma[j] = where[found[0]]
            elif strong:
                unpaired.append(f"{name} (no {strong[0]})")
        if unpaired:
            raise RigError(
                f"cannot mirror: sided joints without a counterpart: {', '.join(unpaired)}; "
                "pass pairs={'LeftName': 'RightName', ...} to mirror()"
            )
    bad = [names[j] for j in range(len(names)) if sigma[sigma[j]] != j]
    if bad:
        raise RigError(
            f"cannot mirror: left/right pairing is not one-to-one at {bad}; "
            "pass explicit pairs={'LeftName': 'RightName', ...}"
        )
    parents = skeleton.parents
    mapped = np.where(parents >= 0, sigma[np.maximum(parents, 0)], -1)
    bad = [names[j] for j in range(len(names)) if parents[sigma[j]] != mapped[j]]
    if bad:
        raise RigError(
            f"cannot mirror: joints {bad} and their mirror counterparts hang from joints that "
            "are not mirror images of each other; fix the pairs or the hierarchy"
        )
    return sigma


def _pair_end_sites(skeleton: Skeleton, sigma: np.ndarray) -> np.ndarray:
    esp = skeleton.end_site_parents
    # The k-th end site of joint j pairs with the k-th end site of sigma(j).
    rank = np.zeros(len(esp), dtype=np.int64)
    slot: dict[tuple[int, int], int] = {}
    for e, p in enumerate(esp):
        rank[e] = sum(1 for q in esp[:e] if q == p)
        slot[(int(p), int(rank[e]))] = e
    out = np.empty(len(esp), dtype=np.int64)
    for e, p in enumerate(esp):
        key = (int(sigma[p]), int(rank[e]))
        if key not in slot:
            raise RigError(
                f"cannot mirror: joint {skeleton.names[p]!r} has more end sites than "
                f"{skeleton.names[sigma[p]]!r}; give mirror images the same end sites"
            )
        out[e] = slot[key]
    return out


@dataclass(frozen=True)
class MirrorMap:
    """How a rig maps onto its mirror image (see the module docstring for the math).

    Attributes:
        pairs: ``(J,)`` index of each joint's mirror counterpart (itself on the midline).
        end_site_pairs: ``(E,)`` the same for end sites.
        reflections: ``(J,)`` index into ``("-I", "x", "y", "z")``: the local reflection ``D_j``
            (point reflection, or the plane normal to that local axis).
    """

    pairs: np.ndarray
    end_site_pairs: np.ndarray
    reflections: np.ndarray

    @property
    def reflection_names(self) -> tuple[str, ...]:
        """``(J,)`` reflection of every joint as ``"-I"``, ``"x"``, ``"y"`` or ``"z"``."""
        return tuple(_REFLECTION_NAMES[r] for r in self.reflections)


def mirror_map(skeleton: Skeleton, pairs: Mapping[str, str] | None = None) -> MirrorMap:
    """Pair left and right joints and pick each joint's local reflection.

    Joints pair by name: ``_L``/``_R`` (also ``.L``, ``-L``, lower case), ``Left``/``Right``
    anywhere in the name (also ``left``, ``LEFT``), and ``L``/``R`` prefixes (``L_Hip``,
    ``LThigh``). The reflection rule is the module docstring's.

    Args:
        skeleton: the rig, ``J`` joints and ``E`` end sites.
        pairs: explicit ``{left name: right name}`` pairs instead of the name patterns;
            joints not named are on the midline.

    Raises:
        RigError: a sided joint has no counterpart, the pairing is not one-to-one, or mirror
            images hang from joints that are not mirror images.
    """
    sigma = _pair_joints(skeleton, pairs)
    end_sigma = _pair_end_sites(skeleton, sigma)
    n = skeleton.num_joints
    # Children of every joint as (own offset, counterpart's offset) pairs, end sites included.
    kids: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in range(n)]
    for j in range(n):
        p = skeleton.parents[j]
        if p >= 0:
            kids[p].append((skeleton.offsets[j], skeleton.offsets[sigma[j]]))
    for e, p in enumerate(skeleton.end_site_parents):
        kids[p].append((skeleton.end_site_offsets[e], skeleton.end_site_offsets[end_sigma[e]]))
    reflections = np.empty(n, dtype=np.int64)
    for j in range(n):
        p = skeleton.parents[j]
        inherited = _WORLD if p < 0 else int(reflections[p])
        if not skeleton.rotation_order(j) or not kids[j]:
            # No rotation channel to absorb a change of frame, or nothing to tell frames apart.
            reflections[j] = inherited
            continue
        own = np.stack([k[0] for k in kids[j]])
        other = np.stack([k[1] for k in kids[j]])
        scale = np.maximum(np.linalg.norm(own, axis=-1), np.linalg.norm(other, axis=-1))
        err = np.linalg.norm(_REFLECTION_SIGNS[:, None] * other - own, axis=-1)
        err = np.where(scale > 0, err / np.where(scale > 0, scale, 1.0), 0.0).max(axis=1)
        tied = np.flatnonzero(err <= err.min() + _TIE)
        reflections[j] = inherited if inherited in tied else (0 if 0 in tied else tied[0])
    return MirrorMap(sigma, end_sigma, reflections)


def _parent_reflections(skeleton: Skeleton, mm: MirrorMap) -> np.ndarray:
    parents = skeleton.parents
    return np.where(parents >= 0, mm.reflections[np.maximum(parents, 0)], _WORLD)


def mirror_skeleton(skeleton: Skeleton, mm: MirrorMap | None = None) -> Skeleton:
    """The rig whose rest offsets are the mirror images of ``skeleton``'s.

    Offsets become ``D_parent * offsets[pair]`` (module docstring). On a left/right symmetric
    rig this is the same rig.

    Args:
        skeleton: the rig, offsets ``(J, 3)`` and end-site offsets ``(E, 3)``.
        mm: its :func:`mirror_map` (computed when ``None``).
    """
    mm = mirror_map(skeleton) if mm is None else mm
    signs = _REFLECTION_SIGNS[_parent_reflections(skeleton, mm)]
    end_signs = _REFLECTION_SIGNS[mm.reflections[skeleton.end_site_parents]]
    return Skeleton(
        skeleton.names,
        skeleton.parents,
        signs * skeleton.offsets[mm.pairs],
        skeleton.channels,
        skeleton.end_site_parents,
        end_signs * skeleton.end_site_offsets[mm.end_site_pairs],
    )


def mirror(motion: Motion, pairs: Mapping[str, str] | None = None) -> Motion:
    """Mirror a clip left to right across the world's ``X = 0`` plane.

    Left and right joints swap; world positions of joints and end sites become exactly the
    reflections ``(-x, y, z)`` of the originals' counterparts. The rig is mirrored with the same
    rule (:func:`mirror_skeleton`); it equals the original rig when that is symmetric. See the
    module docstring for the rule and for why mirroring twice returns the clip.

    Args:
        motion: the clip, rotations ``(T, J, 4)`` and positions ``(T, J, 3)``.
        pairs: explicit ``{left name: right name}`` pairs instead of the name patterns.

    Returns:
        The mirrored clip, same shapes, with ``metadata["mirrored"]`` toggled.

    Raises:
        RigError: the rig cannot be paired left to right (see :func:`mirror_map`).
    """
    sk = motion.skeleton
    mm = mirror_map(sk, pairs)
    parent_ref = _parent_reflections(sk, mm)
    mirrored = mirror_skeleton(sk, mm)
    if mirrored.same_as(sk, atol=0.0) and np.array_equal(
        mirrored.end_site_offsets, sk.end_site_offsets
    ):
        mirrored = sk
    left = quaternion_conjugate(_REFLECTION_QUATS[parent_ref])
    right = _REFLECTION_QUATS[mm.reflections]
    rot = quaternion_multiply(quaternion_multiply(left, motion.rotations[:, mm.pairs]), right)
    pos = _REFLECTION_SIGNS[parent_ref] * motion.positions[:, mm.pairs]
    meta = dict(motion.metadata)
    meta["mirrored"] = not meta.get("mirrored", False)
    return Motion(mirrored, rot, pos, motion.fps, meta)


# ---------------------------------------------------------------------------------------------
# Placement and facing


def _move_roots(motion: Motion, yaw: np.ndarray | None, shift: np.ndarray) -> Motion:
    """Apply the world transform ``x -> yaw * (x + shift)`` to every root joint."""
    roots = np.flatnonzero(motion.skeleton.parents < 0)
    rot = motion.rotations.copy()
    pos = motion.positions.copy()
    moved = pos[:, roots] + shift
    if yaw is not None:
        moved = quaternion_apply(yaw, moved)
        rot[:, roots] = quaternion_multiply(yaw, rot[:, roots])
    pos[:, roots] = moved
    return motion.replace(rotations=rot, positions=pos)


def place_on_ground(motion: Motion) -> Motion:
    """Shift a clip vertically so its lowest point over all frames lies on ``y = 0``.

    The lowest point is taken over joints and end sites
    (:meth:`~emotive.core.Motion.positions_with_end_sites`, ``(T, J + E, 3)``).

    Args:
        motion: the clip, ``T >= 1`` frames.

    Returns:
        The clip with every root joint's translation ``(T, 3)`` moved along Y.

    Raises:
        MotionError: the clip has no frames.
    """
    if motion.num_frames == 0:
        raise MotionError("cannot place an empty clip (0 frames) on the ground")
    lowest = motion.positions_with_end_sites()[..., 1].min()
    return _move_roots(motion, None, np.array([0.0, -lowest, 0.0]))


def _role_positions(motion: Motion, role_map: RoleMap, roles: tuple[str, ...]) -> np.ndarray:
    """``(T, len(roles), 3)`` world positions of the given roles."""
    resolved = resolve_roles(motion.skeleton, role_map)
    idx = resolved.indices(roles)
    if np.all(idx < motion.skeleton.num_joints):
        return motion.global_positions()[:, idx]
    return motion.positions_with_end_sites()[:, idx]


def root_trajectory(motion: Motion, role_map: RoleMap = None) -> np.ndarray:
    """Ground-plane path of the character's root (role ``root``, Hips on the Bandai rig).

    Args:
        motion: the clip, ``T`` frames.
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).

    Returns:
        ``(T, 2)`` world ``(x, z)`` positions in metres.

    Raises:
        RigError: the rig lacks the roles.
    """
    return _role_positions(motion, role_map, ("root",))[:, 0][:, [0, 2]]


def facing_directions(motion: Motion, role_map: RoleMap = None) -> np.ndarray:
    """Unit ground-plane vectors the character faces, frame by frame.

    Facing is ``across x up`` where ``across`` is the sum of the horizontal unit vectors from
    the right hip to the left hip and from the right shoulder to the left shoulder; it uses
    world positions only, so it does not depend on the rig's rest orientations. Frames where
    both vectors vanish (a body seen exactly edge-on from above) take the nearest valid frame's
    direction.

    Args:
        motion: the clip, ``T`` frames.
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).

    Returns:
        ``(T, 3)`` unit vectors with zero Y.

    Raises:
        RigError: the rig lacks the roles.
        MotionError: no frame has a defined facing.
    """
    pts = _role_positions(motion, role_map, ("l_hip", "r_hip", "l_shoulder", "r_shoulder"))
    pairs = np.stack((pts[:, 0] - pts[:, 1], pts[:, 2] - pts[:, 3]), axis=1)[..., [0, 2]]
    norm = np.linalg.norm(pairs, axis=-1, keepdims=True)
    unit = np.where(norm > 1e-9, pairs / np.where(norm > 1e-9, norm, 1.0), 0.0)
    across = unit.sum(axis=1)
    # across x up with up = +Y, in (x, z): (x, z) -> (-z, x).
    fwd = np.stack((-across[:, 1], across[:, 0]), axis=-1)
    length = np.linalg.norm(fwd, axis=-1)
    valid = length > 1e-9
    if len(valid) and not valid.any():
        raise MotionError("cannot tell which way the character faces: hips and shoulders coincide")
    if not valid.all():
        idx = np.arange(len(valid))
        before = np.maximum.accumulate(np.where(valid, idx, -1))
        after = np.minimum.accumulate(np.where(valid, idx, len(valid))[::-1])[::-1]
        use_before = (before >= 0) & ((after >= len(valid)) | (idx - before <= after - idx))
        src = np.where(use_before, before, after)
        fwd, length = fwd[src], length[src]
    fwd = fwd / length[:, None]
    return np.stack((fwd[:, 0], np.zeros(len(fwd)), fwd[:, 1]), axis=-1)


def heading(motion: Motion, role_map: RoleMap = None) -> np.ndarray:
    """Yaw angle of the character's facing, frame by frame.

    The angle ``a`` is such that the facing direction is ``(sin a, 0, cos a)``: a rotation by
    ``a`` about +Y turns +Z onto it, and ``0`` means facing +Z. See :func:`facing_directions`.

    Args:
        motion: the clip, ``T`` frames.
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).

    Returns:
        ``(T,)`` radians in ``(-pi, pi]``.
    """
    fwd = facing_directions(motion, role_map)
    return np.arctan2(fwd[:, 0], fwd[:, 2])


def canonicalize_facing(motion: Motion, frame: int = 0, role_map: RoleMap = None) -> Motion:
    """Rotate about Y and slide along the ground so that, at ``frame``, the root role stands
    over the origin facing +Z.

    Height is unchanged. The transform is applied to the root joints' rotations ``(T, 4)`` and
    translations ``(T, 3)``, so the whole clip moves rigidly.

    Args:
        motion: the clip, ``T`` frames.
        frame: the reference frame, ``0 <= frame < T`` (negative counts from the end).
        role_map: how to find the roles (see :func:`emotive.core.roles.resolve_roles`).

    Returns:
        The moved clip.

    Raises:
        MotionError: ``frame`` is outside the clip.
        RigError: the rig lacks the roles.
    """
    n = motion.num_frames
    if not -n <= frame < n:
        raise MotionError(f"frame {frame} is outside the clip of {n} frames: use 0..{n - 1}")
    ref = crop(motion, frame % n, frame % n + 1)
    root = _role_positions(ref, role_map, ("root",))[0, 0]
    angle = heading(ref, role_map)[0]
    yaw = yaw_quaternion(np.asarray(-angle))
    return _move_roots(motion, yaw, np.array([-root[0], 0.0, -root[2]]))
