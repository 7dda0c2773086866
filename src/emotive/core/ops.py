"""Operations on whole motion clips: timing, cutting, mirroring, placement and facing.

Every function takes a :class:`~emotive.core.Motion` and returns a new one (or arrays); none
loops over frames in Python. World conventions are the toolkit's: metres, Y up, ground = XZ.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``K`` frames after resampling.

Mirroring follows the rule in :mod:`emotive.core.mirroring`, which pairs the joints and picks
their reflections.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from emotive.core.mirroring import (
    REFLECTION_QUATS,
    REFLECTION_SIGNS,
    mirror_map,
    mirror_skeleton,
    parent_reflections,
)
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
    "MotionError",
    "canonicalize_facing",
    "concatenate",
    "crop",
    "facing_directions",
    "heading",
    "mirror",
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


def mirror(motion: Motion, pairs: Mapping[str, str] | None = None) -> Motion:
    """Mirror a clip left to right across the world's ``X = 0`` plane.

    Left and right joints swap; world positions of joints and end sites become exactly the
    reflections ``(-x, y, z)`` of the originals' counterparts. The rig is mirrored with the same
    rule (:func:`mirror_skeleton`); it equals the original rig when that is symmetric. See
    :mod:`emotive.core.mirroring` for the rule and for why mirroring twice returns the clip.

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
    parent_ref = parent_reflections(sk, mm)
    mirrored = mirror_skeleton(sk, mm)
    if mirrored.same_as(sk, atol=0.0) and np.array_equal(
        mirrored.end_site_offsets, sk.end_site_offsets
    ):
        mirrored = sk
    left = quaternion_conjugate(REFLECTION_QUATS[parent_ref])
    right = REFLECTION_QUATS[mm.reflections]
    rot = quaternion_multiply(quaternion_multiply(left, motion.rotations[:, mm.pairs]), right)
    pos = REFLECTION_SIGNS[parent_ref] * motion.positions[:, mm.pairs]
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
    """Place the clip so that, at ``frame``, the root stands over the origin facing +Z.

    Rotate about Y and slide along the ground so that, at ``frame``, the root role stands
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
