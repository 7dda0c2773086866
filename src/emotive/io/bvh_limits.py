"""The BVH reader's own limits and the length-unit detection.

A BVH file is text anyone can write, so the reader refuses what no capture produces before
it allocates or computes anything large. The limits every motion format shares (file size,
joints, frames, values, frame rate, lengths) are those of :mod:`emotive.io.input_limits`,
named here too for the BVH reader's modules; this module adds BVH's own: a line longer than
:data:`MAX_LINE_CHARS` or a header word longer than :data:`MAX_TOKEN_CHARS` characters, an
angle beyond :data:`MAX_ANGLE_DEG` degrees and, when the unit is detected, a figure outside
:data:`PLAUSIBLE_HEIGHT_M`. Messages quote at most :data:`QUOTE_CHARS` characters of the file
(:func:`quote`). ``docs/limits.md`` states every limit and why.

The length unit is detected from the figure's standing height (:func:`standing_height`: from
its joint roles when they resolve, else the rest pose's extent, :func:`figure_height`), in
file units, see :func:`detect_unit`. Lengths are in metres unless named ``*_file`` (file
units). ``J`` = joints, ``E`` = end sites.
"""

from __future__ import annotations

import numpy as np

from emotive.core.roles import match_roles
from emotive.core.skeleton import Skeleton
from emotive.io import input_limits

# The limits every format shares, named here for the BVH reader's modules (one definition).
from emotive.io.input_limits import MAX_FILE_BYTES as MAX_FILE_BYTES
from emotive.io.input_limits import MAX_FPS as MAX_FPS
from emotive.io.input_limits import MAX_FRAMES as MAX_FRAMES
from emotive.io.input_limits import MAX_JOINTS as MAX_JOINTS
from emotive.io.input_limits import MAX_LENGTH_M as MAX_LENGTH_M
from emotive.io.input_limits import MAX_VALUES as MAX_VALUES
from emotive.io.input_limits import MIN_FPS as MIN_FPS
from emotive.io.input_limits import QUOTE_CHARS as QUOTE_CHARS
from emotive.io.input_limits import length_problem as length_problem
from emotive.io.input_limits import quote as quote
from emotive.io.input_limits import size_problem as size_problem

#: Metres per file unit for the units a BVH file may use. ``"cmu"`` is the length unit of the
#: CMU motion-capture ASF files (and the BVH files converted from them): 1/0.45 inches, so a
#: 1.7 m actor stands about 30 units tall.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254, "cmu": 0.0254 / 0.45}

#: Longest line, in characters (1 MiB): a frame row of the widest rig (:data:`MAX_JOINTS`
#: joints x 6 channels) with 170 characters per value. Lines are read at most this long, so
#: a file of one huge line is refused after 1 MiB, not read whole.
MAX_LINE_CHARS = 1 << 20
#: Longest word of the hierarchy and motion header (joint names, numbers, keywords), in
#: characters: rig names run to a few dozen, a float64 written in full to 24.
MAX_TOKEN_CHARS = 256
#: Largest absolute rotation channel value in degrees (about 278 turns): exporters unwrap
#: angles, but beyond this an angle has lost its fractional degrees in float64 noise.
MAX_ANGLE_DEG = 1e5
#: Standing height of a humanoid, in metres; the detected unit puts the figure in it.
HUMAN_HEIGHT_M = (1.2, 2.2)
#: Heights, in metres, that a figure read with a detected unit may have: from a doll to a
#: giant, well beyond what :func:`detect_unit` aims at; outside them the unit guess is
#: wrong or the numbers are, and the file's unit must be given.
PLAUSIBLE_HEIGHT_M = (0.05, 10.0)
#: Share of the foot (ankle to toe) that stands for the ankle's height above the ground.
ANKLE_HEIGHT_PER_FOOT = 0.5
#: Least share of the legs-and-torso length that the skull adds above the head joint (the
#: Bandai rig's head joint sits at the top of the neck and has no head-top joint).
HEAD_TOP_PER_BODY = 0.15


def frame_time_problem(frame_time: float) -> str | None:
    """What is wrong with a ``Frame Time:`` value, or ``None`` when it is plausible.

    Args:
        frame_time: seconds per frame as written in the file.

    Returns:
        A message naming the value and the allowed range, or ``None``.
    """
    low_fps, high_fps = input_limits.MIN_FPS, input_limits.MAX_FPS
    low, high = 1.0 / high_fps, 1.0 / low_fps
    if np.isfinite(frame_time) and low <= frame_time <= high:
        return None
    return (
        f"'Frame Time:' is {frame_time:g} s: it must be between {low:g} and {high:g} s "
        f"({low_fps:g}-{high_fps:g} frames per second); fix the frame time"
    )


def height_problem(height_m: float, unit: str) -> str | None:
    """What is implausible about a figure's height in a detected unit, or ``None``.

    Args:
        height_m: standing height in metres (:func:`standing_height` times the unit's scale).
        unit: the detected unit, a key of :data:`UNITS`.

    Returns:
        A message naming the height, the range and the way around (the file's unit), or
        ``None`` when the height is in :data:`PLAUSIBLE_HEIGHT_M`.
    """
    low, high = PLAUSIBLE_HEIGHT_M
    if low <= height_m <= high:
        return None
    return (
        f"the figure stands {height_m:.3g} m tall with its unit detected as '{unit}': "
        f"{low:g}-{high:g} m is plausible, so the unit or the offsets are wrong; check them or "
        "give the file's unit (--unit on the command line, unit= to read_bvh: m, cm, mm, in, cmu)"
    )


def angle_problem(degrees: np.ndarray) -> str | None:
    """What is out of range in rotation channel values, or ``None``.

    Args:
        degrees: any-shaped rotation channel values in degrees.

    Returns:
        A message naming the largest value and the limit, or ``None``.
    """
    if degrees.size == 0:
        return None
    biggest = float(np.abs(degrees).max())
    if biggest <= MAX_ANGLE_DEG:
        return None
    return f"a rotation of {biggest:.3g} degrees: at most {MAX_ANGLE_DEG:g} is plausible"


def _placement_chain(parents: np.ndarray) -> np.ndarray:
    """``(J,)`` mask of the root and the single-child joints down to the first branching one.

    Their offsets place the figure in the world (Bandai Namco's ``Hips`` offset holds where
    the actor stood); they say nothing about its size.
    """
    n = len(parents)
    counts = np.bincount(parents[parents >= 0], minlength=n)
    mask = np.zeros(n, dtype=bool)
    j = 0
    while j < n:
        mask[j] = True
        kids = np.flatnonzero(parents == j)
        if counts[j] != 1:
            break
        j = int(kids[0])
    return mask


def figure_height(
    offsets_file: np.ndarray, parents: np.ndarray,
    end_parents: np.ndarray, end_offsets_file: np.ndarray,
) -> float:
    """The figure's standing height in file units, from its rest pose.

    The rest pose (offsets only) is built without the placement offsets (the root and the
    single-child joints above the first branching joint); the height is its extent along its
    longest axis, end sites included. A rest pose that stands (T- or A-pose) gives head to
    toe; a rest pose laid along the bone axes (Maya-style rigs such as Bandai Namco's) gives
    head to toe along X.

    Args:
        offsets_file: ``(J, 3)`` joint offsets in file units, parents first.
        parents: ``(J,)`` parent indices, ``-1`` for the root.
        end_parents: ``(E,)`` joint of each end site.
        end_offsets_file: ``(E, 3)`` end-site offsets in file units.

    Returns:
        The height, ``0.0`` for a single joint without end sites.
    """
    offsets = np.where(_placement_chain(parents)[:, None], 0.0, offsets_file)
    pos = np.zeros_like(offsets)
    for j, p in enumerate(parents):
        pos[j] = offsets[j] + (pos[p] if p >= 0 else 0.0)
    points = np.concatenate([pos, pos[end_parents] + end_offsets_file]) if len(end_parents) \
        else pos
    return float(np.ptp(points, axis=0).max()) if len(points) > 1 else 0.0


def _bone_lengths(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """Parents and bone lengths of the ``(J + E)`` joints then end sites (roots: 0)."""
    parents = np.concatenate((skeleton.parents, skeleton.end_site_parents)).astype(np.int64)
    lengths = np.linalg.norm(np.concatenate((skeleton.offsets, skeleton.end_site_offsets)),
                             axis=1)
    lengths[: skeleton.num_joints][skeleton.parents < 0] = 0.0
    return parents, lengths


def _chain_length(parents: np.ndarray, lengths: np.ndarray, top: int, bottom: int) -> float:
    """Summed bone length from ``top`` down to its descendant ``bottom`` (NaN if it is not)."""
    total, k = 0.0, bottom
    while k != top:
        if k < 0:
            return float("nan")
        total += float(lengths[k])
        k = int(parents[k])
    return total


def _reach(parents: np.ndarray, lengths: np.ndarray, top: int) -> float:
    """The longest summed bone length from ``top`` down to any point below it."""
    best = 0.0
    for k in range(len(parents)):
        length = _chain_length(parents, lengths, top, k)
        if length == length:
            best = max(best, length)
    return best


def role_height(skeleton: Skeleton, index: dict[str, int]) -> float:
    """Standing height from the bone lengths between joint roles, whatever the rest pose.

    Legs (hip to knee to ankle, the longer side), the ankle's height
    (:data:`ANKLE_HEIGHT_PER_FOOT` of the foot), the torso and neck (root to head) and the
    skull above the head joint (its longest chain of bones and end sites, at least
    :data:`HEAD_TOP_PER_BODY` of the rest). Bone lengths do not change with the rest pose,
    so T-pose, A-pose and rigs laid along their bone axes measure alike, and arm span and
    extra joints (fingers, twist bones, ``LHipJoint``) do not count.

    Args:
        skeleton: the rig, lengths in any unit.
        index: role -> index into the ``(J + E)`` array (every role of
            :data:`emotive.core.roles.ROLES`).

    Returns:
        The height in the rig's unit, NaN when the roles do not lie on one tree path.
    """
    parents, lengths = _bone_lengths(skeleton)

    def chain(top: str, bottom: str) -> float:
        return _chain_length(parents, lengths, index[top], index[bottom])

    legs = max(chain(f"{s}_hip", f"{s}_knee") + chain(f"{s}_knee", f"{s}_ankle")
               for s in "lr")
    ankle = ANKLE_HEIGHT_PER_FOOT * max(chain(f"{s}_ankle", f"{s}_toe") for s in "lr")
    torso = chain("root", "head")
    skull = max(_reach(parents, lengths, index["head"]), HEAD_TOP_PER_BODY * (legs + torso))
    return legs + ankle + torso + skull


def standing_height(skeleton: Skeleton) -> float:
    """The figure's standing height in its own unit.

    From the joint roles (:func:`role_height`) when the rig's names or shape resolve every
    role, else from the rest pose's extent (:func:`figure_height`).

    Args:
        skeleton: the rig, lengths in any unit.

    Returns:
        The height, ``0.0`` for a single joint without end sites.
    """
    # Absurd offsets (refused later by :func:`length_problem`) must not warn here.
    with np.errstate(all="ignore"):
        _, index, missing = match_roles(skeleton)
        height = role_height(skeleton, index) if not missing else float("nan")
    if np.isfinite(height) and height > 0:
        return height
    return figure_height(skeleton.offsets, skeleton.parents, skeleton.end_site_parents,
                         skeleton.end_site_offsets)


def detect_unit(height_file: float) -> str:
    """The length unit that makes a figure ``height_file`` file units tall a humanoid.

    The unit whose :data:`HUMAN_HEIGHT_M` range holds the height (metres 1.2-2.2, CMU units
    21-39, inches 47-87, centimetres 120-220, millimetres 1200-2200); between two ranges the
    nearer one (by ratio), except that the gap between the inch range and the centimetre
    range goes to centimetres: small centimetre rigs are far more common than giant inch
    ones, and it keeps every file read before inches were detected.

    Args:
        height_file: standing height from :func:`standing_height`, in file units.

    Returns:
        A key of :data:`UNITS`: ``"m"``, ``"cmu"``, ``"in"``, ``"cm"`` or ``"mm"``.
    """
    low, high = HUMAN_HEIGHT_M
    inch_top = high / UNITS["in"]
    if low / UNITS["cm"] > height_file > inch_top:
        return "cm"
    best, best_gap = "cm", np.inf
    for unit, scale in UNITS.items():
        metres = height_file * scale
        gap = 0.0 if low <= metres <= high else abs(np.log(max(metres, 1e-300) / (
            low if metres < low else high)))
        if gap < best_gap:
            best, best_gap = unit, gap
    return best
