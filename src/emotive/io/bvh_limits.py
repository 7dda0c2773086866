"""Plausibility limits of the BVH reader and the length-unit detection.

A BVH file is text anyone can write, so the reader refuses what no capture produces before
it allocates or computes anything large: a file bigger than :data:`MAX_FILE_BYTES`, more
than :data:`MAX_JOINTS` joints or :data:`MAX_FRAMES` frames, a frame rate outside
:data:`MIN_FPS`-:data:`MAX_FPS`, a length beyond :data:`MAX_LENGTH_M` metres or an angle
beyond :data:`MAX_ANGLE_DEG` degrees. ``docs/limits.md`` states every limit and why.

The length unit is detected from the figure's standing height (:func:`figure_height`), in
file units, see :func:`detect_unit`. Lengths are in metres unless named ``*_file`` (file
units). ``J`` = joints, ``E`` = end sites.
"""

from __future__ import annotations

import numpy as np

#: Metres per file unit for the units a BVH file may use.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}

#: Largest file read (1 GiB): 60 million channel values written with 9 digits fit in it.
MAX_FILE_BYTES = 1 << 30
#: Most joints in one hierarchy; full-body rigs with fingers and a face have a few hundred.
MAX_JOINTS = 1024
#: Most frames in one file: over 9 hours at 30 fps, over 16 minutes at 1,000 fps.
MAX_FRAMES = 1_000_000
#: Most channel values (frames x channels) in one file, checked before any array is made:
#: 60 million float64 values are 480 MB; the quaternions and positions made from them
#: stay within a few GB.
MAX_VALUES = 60_000_000
#: Lowest and highest frame rate (frames per second); ``Frame Time`` is their inverse.
MIN_FPS = 1.0
MAX_FPS = 1000.0
#: Largest absolute offset or position coordinate, in metres after unit conversion: a
#: capture volume or game level spans at most a few hundred metres, and float32 (the GPU's
#: type) still resolves 0.1 mm at 1 km.
MAX_LENGTH_M = 1000.0
#: Largest absolute rotation channel value in degrees (about 278 turns): exporters unwrap
#: angles, but beyond this an angle has lost its fractional degrees in float64 noise.
MAX_ANGLE_DEG = 1e5
#: Standing height of a humanoid, in metres; the detected unit puts the figure in it.
HUMAN_HEIGHT_M = (1.2, 2.2)


def frame_time_problem(frame_time: float) -> str | None:
    """What is wrong with a ``Frame Time:`` value, or ``None`` when it is plausible.

    Args:
        frame_time: seconds per frame as written in the file.

    Returns:
        A message naming the value and the allowed range, or ``None``.
    """
    low, high = 1.0 / MAX_FPS, 1.0 / MIN_FPS
    if np.isfinite(frame_time) and low <= frame_time <= high:
        return None
    return (
        f"'Frame Time:' is {frame_time:g} s: it must be between {low:g} and {high:g} s "
        f"({MIN_FPS:g}-{MAX_FPS:g} frames per second); fix the frame time"
    )


def size_problem(frames: int, width: int, n_joints: int) -> str | None:
    """What is too large about a file's declared size, or ``None``.

    Args:
        frames: frame count from ``Frames:``.
        width: channel values per frame.
        n_joints: joints in the hierarchy.

    Returns:
        A message naming the count and the limit, or ``None``.
    """
    if n_joints > MAX_JOINTS:
        return f"{n_joints} joints: at most {MAX_JOINTS} are read; split or simplify the rig"
    if frames > MAX_FRAMES:
        return f"'Frames:' is {frames}: at most {MAX_FRAMES:,} frames are read; split the clip"
    if frames * width > MAX_VALUES:
        return (
            f"{frames} frames x {width} channels = {frames * width:,} values: at most "
            f"{MAX_VALUES:,} are read; split the clip"
        )
    return None


def length_problem(values_m: np.ndarray, what: str) -> str | None:
    """What is out of range in lengths already converted to metres, or ``None``.

    Args:
        values_m: any-shaped lengths in metres.
        what: what they are, for the message (``"joint offsets"``).

    Returns:
        A message naming the largest value and the limit, or ``None``.
    """
    if values_m.size == 0:
        return None
    biggest = float(np.abs(values_m).max())
    if biggest <= MAX_LENGTH_M:
        return None
    return (
        f"{what} reach {biggest:.3g} m: at most {MAX_LENGTH_M:g} m is plausible; check the "
        "numbers or pass the file's unit (unit='mm', 'cm', 'm' or 'in')"
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


def detect_unit(height_file: float) -> str:
    """The length unit that makes a figure ``height_file`` file units tall a humanoid.

    The unit whose :data:`HUMAN_HEIGHT_M` range holds the height; between two ranges the
    nearer one (by ratio), except that the gap between the inch range (47-87 units) and the
    centimetre range (120-220 units) goes to centimetres: small centimetre rigs are far more
    common than giant inch ones, and it keeps every file read before inches were detected.

    Args:
        height_file: standing height from :func:`figure_height`, in file units.

    Returns:
        One of ``"m"``, ``"in"``, ``"cm"``, ``"mm"``.
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
