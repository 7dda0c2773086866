"""BVH reading and writing.

The reader accepts any rotation channel order, 3 or 6 channels per joint, End Sites, CRLF
line ends, tabs, scientific notation and zero-frame files. Every problem raises
:class:`~emotive.errors.BVHError` naming the file, the line and the fix; no partial
:class:`~emotive.core.Motion` is ever returned. Lengths are converted to metres on reading
(``unit``, detected from the figure's height by default) and back to the file's unit on
writing; rotations become unit quaternions ``w, x, y, z``. Only regular files are read (a
pipe or device is refused at once), a line at a time within the size budget of
:mod:`emotive.io.bvh_text` (so a huge line or row is refused after at most 1 MiB), and
implausible numbers and sizes are refused before anything large is allocated: the limits are
in :mod:`emotive.io.input_limits` (shared by every format), :mod:`emotive.io.bvh_limits` and
``docs/limits.md``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton
from emotive.errors import BVHError
from emotive.io import input_limits
from emotive.io.atomic import atomic_output
from emotive.io.bvh_limits import (
    UNITS,
    angle_problem,
    detect_unit,
    frame_time_problem,
    height_problem,
    standing_height,
)
from emotive.io.bvh_text import BVHLines, HierarchyWords, open_bvh_text
from emotive.io.input_limits import length_problem, quote, size_problem
from emotive.transforms.np_rotations import euler_to_quaternion, quaternion_to_euler

_VALID_CHANNELS = set(POSITION_CHANNELS) | set(ROTATION_CHANNELS)


@dataclass
class _Joint:
    name: str
    parent: int
    line: int
    offset: np.ndarray | None = None
    channels: tuple[str, ...] = ()
    end_sites: list[np.ndarray] = field(default_factory=list)


def _parse_channels(tokens: HierarchyWords, name: str) -> tuple[str, ...]:
    """The channels of joint ``name``, read after its ``CHANNELS`` keyword."""
    chan_line = tokens.last_line
    count_tok = tokens.next("the channel count")
    if count_tok not in ("3", "6"):
        raise tokens.error_at_last(
            f"joint {quote(name)} has {quote('CHANNELS ' + count_tok)}: only 3 (rotations) or "
            "6 (positions and rotations) channels per joint are supported"
        )
    chans = tuple(tokens.next("a channel name") for _ in range(int(count_tok)))
    bad = [c for c in chans if c not in _VALID_CHANNELS]
    rot = [c for c in chans if c in ROTATION_CHANNELS]
    if bad or len(set(chans)) != len(chans) or len(set(rot)) != 3:
        raise BVHError(
            tokens.path, chan_line,
            f"joint {quote(name)} has invalid channels {quote(' '.join(chans))}: use three "
            "distinct rotation channels (and optionally the three position channels)"
        )
    return chans


def _parse_end_site(tokens: HierarchyWords, name: str) -> np.ndarray:
    """The ``(3,)`` offset of an end site of joint ``name``, read after its ``End`` keyword."""
    tokens.expect("Site")
    tokens.expect("{")
    tokens.expect("OFFSET")
    offset = np.array([tokens.number(f"End Site OFFSET of {quote(name)}") for _ in range(3)])
    tokens.expect("}")
    return offset


def _unexpected_in_joint(tokens: HierarchyWords, tok: str, name: str) -> BVHError:
    """The error for word ``tok``, just read, where joint ``name``'s body expects a keyword."""
    if tok in ("MOTION", "ROOT"):
        return tokens.error_at_last(
            f"joint {quote(name)} is not closed: a '}}' is missing before {tok} "
            "(unbalanced braces)"
        )
    return tokens.error_at_last(f"unexpected {quote(tok)} in joint {quote(name)}")


def _expect_motion(tokens: HierarchyWords) -> None:
    """Check that the ``MOTION`` part follows the (single) hierarchy."""
    nxt = tokens.peek()
    if nxt == "ROOT":
        raise tokens.error("several ROOT joints: only one hierarchy per file is supported")
    if nxt != "MOTION":
        if nxt is None:
            raise tokens.error("the MOTION part is missing: the file ends after the hierarchy")
        raise tokens.error(f"expected 'MOTION' after the hierarchy but found {quote(nxt)}")


def _open_joint(
    tokens: HierarchyWords, joints: list[_Joint], seen: dict[str, int], parent: int
) -> None:
    """Read a joint's name and ``{`` and append it to ``joints``."""
    line = tokens.line
    name = tokens.next("a joint name")
    if name in ("{", "}"):
        raise tokens.error_at_last("a joint needs a name before '{'")
    if name in seen:
        raise BVHError(
            tokens.path, line,
            f"duplicate joint name {quote(name)} (first on line {joints[seen[name]].line}): "
            "rename one of them",
        )
    if len(joints) >= input_limits.MAX_JOINTS:
        raise BVHError(
            tokens.path, line,
            f"more than {input_limits.MAX_JOINTS} joints: at most {input_limits.MAX_JOINTS} are "
            "read; simplify the rig",
        )
    seen[name] = len(joints)
    joints.append(_Joint(name, parent, line))
    tokens.expect("{")


def _close_joint(tokens: HierarchyWords, joint: _Joint) -> None:
    """Check a joint whose ``}`` was just read."""
    if joint.offset is None:
        raise BVHError(tokens.path, joint.line, f"joint {quote(joint.name)} has no OFFSET")
    if not joint.channels:
        raise BVHError(tokens.path, joint.line, f"joint {quote(joint.name)} has no CHANNELS")


def _parse_hierarchy(tokens: HierarchyWords) -> list[_Joint]:
    if tokens.peek() is None:
        raise tokens.error("the file is empty: a BVH file starts with HIERARCHY")
    tokens.expect("HIERARCHY")
    joints: list[_Joint] = []
    seen: dict[str, int] = {}
    tok = tokens.next("the ROOT joint")
    if tok != "ROOT":
        raise tokens.error_at_last(
            f"expected 'ROOT' after HIERARCHY but found {quote(tok)}: empty hierarchy"
        )
    _open_joint(tokens, joints, seen, -1)
    # An explicit stack of open joints: nesting depth is bounded by MAX_JOINTS, not by
    # Python's recursion limit. A second OFFSET or CHANNELS and end sites beyond MAX_JOINTS
    # are refused, so the hierarchy stays small however long the file.
    open_joints = [0]
    end_sites = 0
    while open_joints:
        joint = joints[open_joints[-1]]
        tok = tokens.next(f"the body of joint {quote(joint.name)}")
        if (tok == "OFFSET" and joint.offset is not None) or (tok == "CHANNELS" and joint.channels):
            raise tokens.error_at_last(f"joint {quote(joint.name)} has a second {tok}: remove one")
        if tok == "OFFSET":
            joint.offset = np.array([tokens.number(f"OFFSET of {quote(joint.name)}")
                                     for _ in range(3)])
        elif tok == "CHANNELS":
            joint.channels = _parse_channels(tokens, joint.name)
        elif tok == "JOINT":
            _open_joint(tokens, joints, seen, open_joints[-1])
            open_joints.append(len(joints) - 1)
        elif tok == "End":
            if end_sites >= input_limits.MAX_JOINTS:
                raise tokens.error_at_last(
                    f"more than {input_limits.MAX_JOINTS} end sites: at most "
                    f"{input_limits.MAX_JOINTS} are read; simplify the rig"
                )
            joint.end_sites.append(_parse_end_site(tokens, joint.name))
            end_sites += 1
        elif tok == "}":
            _close_joint(tokens, joint)
            open_joints.pop()
        else:
            raise _unexpected_in_joint(tokens, tok, joint.name)
    _expect_motion(tokens)
    return joints


def _header_value(lines: BVHLines, key: str) -> tuple[str, int]:
    """The text after ``key`` on the next non-blank line, and that line's number."""
    while (line := lines.next()) is not None and not line.strip():
        pass
    if line is None:
        raise BVHError(
            lines.path, lines.number, f"the MOTION part ends before '{key}': the file is truncated"
        )
    text = " ".join(line.split())  # "Frame\tTime:" is "Frame Time:"
    if not text.startswith(key):
        raise BVHError(lines.path, lines.number, f"expected '{key}' but found {quote(text)}")
    return text[len(key):].strip(), lines.number


def _motion_header(lines: BVHLines) -> tuple[int, float, int]:
    """Parse ``Frames:`` and ``Frame Time:``; return frames, frame time and the Frames line."""
    found, frames_line = _header_value(lines, "Frames:")
    try:
        frames = int(found)
        if frames < 0:
            raise ValueError
    except ValueError:
        raise BVHError(
            lines.path, frames_line, f"'Frames:' must be a whole number >= 0, found {quote(found)}"
        ) from None
    if frames > input_limits.MAX_FRAMES:
        raise BVHError(
            lines.path, frames_line,
            f"'Frames:' is {quote(found)}: at most {input_limits.MAX_FRAMES:,} frames are read; "
            "split the clip",
        )
    found, time_line = _header_value(lines, "Frame Time:")
    try:
        frame_time = float(found)
        if not (np.isfinite(frame_time) and frame_time > 0):
            raise ValueError
    except ValueError:
        raise BVHError(
            lines.path, time_line, f"'Frame Time:' must be a positive number, found {quote(found)}"
        ) from None
    problem = frame_time_problem(frame_time)
    if problem:
        raise BVHError(lines.path, time_line, problem)
    return frames, frame_time, frames_line


_ROW_RE = re.compile(r"at row (\d+)")
_COLUMN_RE = re.compile(r"column (\d+)")
#: Rows parsed at a time: the text held at once is at most this many rows and
#: :data:`_BLOCK_CHARS` characters (plus one line).
_BLOCK_ROWS = 4096
_BLOCK_CHARS = 1 << 22


def _parse_rows(path: str, rows: list[str], numbers: list[int], width: int) -> np.ndarray:
    """``(R, width)`` values of frame rows ``rows`` (file lines ``numbers``)."""
    try:
        values = np.loadtxt(rows, dtype=np.float64, ndmin=2, comments=None)
    except ValueError as exc:
        text = str(exc).split("\n")[0]
        match = _ROW_RE.search(text)
        row = line = None
        if match:
            # NumPy numbers rows from 0 in conversion errors and from 1 in column-count errors.
            row = int(match.group(1)) - (0 if "could not convert" in text else 1)
            row = row if 0 <= row < len(rows) else None
            line = None if row is None else numbers[row]
        problem = text.split(";")[0].rstrip(".")
        if "could not convert" in problem:
            # NumPy cuts the value it quotes at 100 characters: quote it from the row.
            column = _COLUMN_RE.search(text)
            words = rows[row].split() if row is not None else []
            at = int(column.group(1)) - 1 if column else -1
            value = quote(words[at]) if 0 <= at < len(words) else "a value"
            problem = f"non-numeric value {value} in the frame data"
        raise BVHError(path, line, f"{problem}: every frame must hold {width} numbers") from None
    if values.shape[1] != width:
        raise BVHError(
            path, numbers[0],
            f"each frame has {values.shape[1]} values but the hierarchy declares {width} "
            "channels: the channel count does not match",
        )
    bad = ~np.isfinite(values)
    if bad.any():
        row = int(np.argmax(bad.any(axis=1)))
        raise BVHError(path, numbers[row], "NaN or infinite value in the frame data")
    return values


def _parse_frames(lines: BVHLines, frames: int, width: int) -> np.ndarray:
    """``(frames, width)`` channel values of the rows that follow the motion header.

    Rows are read and parsed a block at a time, each row at most ``MAX_LINE_CHARS`` long and
    refused as soon as it holds more than ``width`` values, so no more text than one block
    is ever held.
    """
    blocks: list[np.ndarray] = []
    rows: list[str] = []
    numbers: list[int] = []
    count = chars = 0
    while (line := lines.next(width)) is not None:
        if not line.strip():
            continue
        if count == frames:
            raise BVHError(
                lines.path, lines.number,
                f"more frame lines than the {frames} that 'Frames:' declares: fix the count",
            )
        rows.append(line)
        numbers.append(lines.number)
        count += 1
        chars += len(line)
        if len(rows) == _BLOCK_ROWS or chars >= _BLOCK_CHARS:
            blocks.append(_parse_rows(lines.path, rows, numbers, width))
            rows, numbers, chars = [], [], 0
    if count < frames:
        raise BVHError(
            lines.path, lines.number,
            f"the header says {frames} frames but only {count} follow: the file is truncated",
        )
    if rows:
        blocks.append(_parse_rows(lines.path, rows, numbers, width))
    if not blocks:
        return np.zeros((0, width))
    return blocks[0] if len(blocks) == 1 else np.concatenate(blocks)


def _resolve_unit(unit: str, skeleton_file: Skeleton) -> tuple[str, float]:
    """The file's unit (``unit``, or detected when ``"auto"``) and the figure's height in it."""
    if unit != "auto" and unit not in UNITS:
        raise ValueError(f"unit must be 'auto' or one of {sorted(UNITS)}, got {unit!r}")
    height_file = standing_height(skeleton_file)
    return (detect_unit(height_file) if unit == "auto" else unit), height_file


def _check_values(path: str, joints: list[_Joint], values: np.ndarray, scale: float) -> None:
    """Refuse implausible lengths and angles (see :mod:`emotive.io.input_limits`)."""
    offsets = np.stack([j.offset for j in joints] + [o for j in joints for o in j.end_sites])
    chans = [c for j in joints for c in j.channels]
    is_pos = np.array([c in POSITION_CHANNELS for c in chans], dtype=bool)
    problem = (
        length_problem(offsets * scale, "joint offsets")
        or length_problem(values[:, is_pos] * scale, "position channels")
        or angle_problem(values[:, ~is_pos])
    )
    if problem:
        raise BVHError(path, None, problem)


#: Frames turned into quaternions at a time by :func:`_channels_to_pose`.
_POSE_FRAMES = 4096


def _channels_to_pose(
    joints: list[_Joint], values: np.ndarray, offsets_m: np.ndarray, scale: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 4)`` rotations and ``(T, J, 3)`` positions from ``(T, C)`` channel values.

    Joints are converted in one batch per rotation order, not one call per joint, and
    :data:`_POSE_FRAMES` frames at a time: the conversion's temporaries stay a few MB
    however long the clip.
    """
    frames, n_joints = len(values), len(joints)
    rotations = np.zeros((frames, n_joints, 4))
    positions = np.broadcast_to(offsets_m, (frames, n_joints, 3)).copy()
    by_order: dict[str, tuple[list[int], list[list[int]]]] = {}
    col = 0
    for j, joint in enumerate(joints):
        rot_cols = [col + k for k, c in enumerate(joint.channels) if c in ROTATION_CHANNELS]
        order = "".join(joint.channels[k - col][0] for k in rot_cols)
        group = by_order.setdefault(order, ([], []))
        group[0].append(j)
        group[1].append(rot_cols)
        for k, c in enumerate(joint.channels):
            if c in POSITION_CHANNELS:
                positions[:, j, POSITION_CHANNELS.index(c)] = values[:, col + k] * scale
        col += len(joint.channels)
    for order, (js, cols) in by_order.items():
        for start in range(0, frames, _POSE_FRAMES):
            part = values[start:start + _POSE_FRAMES, cols]
            rotations[start:start + _POSE_FRAMES, js] = euler_to_quaternion(np.deg2rad(part),
                                                                            order)
    return rotations, positions


def read_bvh(path: str | os.PathLike, unit: str = "auto") -> Motion:
    """Read a BVH file into a :class:`Motion` in metres.

    Args:
        path: the ``.bvh`` file.
        unit: the file's length unit, one of ``"m"``, ``"cm"``, ``"mm"``, ``"in"``, ``"cmu"``
            (CMU's 1/0.45 inch), or ``"auto"``: the unit that makes the figure's standing
            height 1.2-2.2 m (:func:`emotive.io.bvh_limits.standing_height`,
            :func:`emotive.io.bvh_limits.detect_unit`); a figure that is still not 0.05-10 m
            tall in it (``PLAUSIBLE_HEIGHT_M``) is refused. A unit given is honoured.

    Returns:
        The motion, with ``metadata`` holding ``name``, ``source``, ``file_unit`` and
        ``height_m`` (the figure's standing height in metres).

    Raises:
        BVHError: the file is missing, not a regular BVH text file, malformed or beyond
            the limits of :mod:`emotive.io.input_limits` and :mod:`emotive.io.bvh_limits`;
            the message names the line and the problem, and quotes at most ``QUOTE_CHARS``
            characters of the file.
    """
    path = Path(path)
    with open_bvh_text(path) as fh:
        lines = BVHLines(str(path), fh)
        tokens = HierarchyWords(lines)
        joints = _parse_hierarchy(tokens)
        if tokens.motion_line is None:
            raise BVHError(path, tokens.line, "'MOTION' must stand alone on its line")
        frames, frame_time, frames_line = _motion_header(lines)
        width = sum(len(j.channels) for j in joints)
        problem = size_problem(frames, width, len(joints))
        if problem:
            raise BVHError(path, frames_line, problem)
        values = _parse_frames(lines, frames, width)

    names = tuple(j.name for j in joints)
    parents = np.array([j.parent for j in joints], dtype=np.int64)
    offsets = np.stack([j.offset for j in joints])
    esp = np.array([n for n, j in enumerate(joints) for _ in j.end_sites], dtype=np.int64)
    eso = np.array([o for j in joints for o in j.end_sites]).reshape(-1, 3)
    skeleton_file = Skeleton(names, parents, offsets, tuple(j.channels for j in joints), esp, eso)
    file_unit, height_file = _resolve_unit(unit, skeleton_file)
    scale = UNITS[file_unit]
    _check_values(str(path), joints, values, scale)
    # A detected unit must make the figure plausible; a unit the caller gives is honoured.
    problem = height_problem(height_file * scale, file_unit) if unit == "auto" else None
    if problem:
        raise BVHError(path, None, problem)
    skeleton = skeleton_file.scaled(scale)

    rotations, positions = _channels_to_pose(joints, values, skeleton.offsets, scale)
    fps = 1.0 / frame_time
    # Files store the frame time rounded (0.0333333); snap to the whole rate it stands for.
    if abs(fps - round(fps)) < 1e-4 * fps:
        fps = float(round(fps))
    return Motion(
        skeleton, rotations, positions, fps,
        metadata={"name": path.stem, "source": str(path), "file_unit": file_unit,
                  "height_m": height_file * scale},
    )


def _format_offset(values: np.ndarray) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def _written_channels(skeleton: Skeleton, joint: int) -> tuple[str, ...]:
    """The channels a joint is written with: its own, plus rotations if it has none.

    BVH readers (this one included) expect three rotation channels on every joint; a joint
    fixed at the identity is written with rotation channels that hold zeros.
    """
    chans = tuple(skeleton.channels[joint])
    if any(c in ROTATION_CHANNELS for c in chans):
        return chans
    return (*chans, "Zrotation", "Xrotation", "Yrotation")


def depth_first_order(skeleton: Skeleton) -> list[int]:
    """Joint indices in the order a BVH file lists them: depth first, children in index order.

    The hierarchy and the frame data of a written file both follow it, so a rig whose joints
    are listed breadth first (SMPL's own order) is written correctly.
    """
    kids = skeleton.children
    order: list[int] = []
    stack = [j for j, p in enumerate(skeleton.parents) if p < 0][::-1]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(kids[j]))
    return order


def _header_lines(skeleton: Skeleton, scale: float) -> list[str]:
    out = ["HIERARCHY"]
    kids = skeleton.children
    ends: dict[int, list[np.ndarray]] = {}
    for p, o in zip(skeleton.end_site_parents, skeleton.end_site_offsets, strict=True):
        ends.setdefault(int(p), []).append(o)

    def emit(j: int, depth: int) -> None:
        pad = "  " * depth
        kind = "ROOT" if skeleton.parents[j] < 0 else "JOINT"
        out.append(f"{pad}{kind} {skeleton.names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}  OFFSET {_format_offset(skeleton.offsets[j] / scale)}")
        chans = _written_channels(skeleton, j)
        out.append(f"{pad}  CHANNELS {len(chans)} {' '.join(chans)}")
        for c in kids[j]:
            emit(c, depth + 1)
        for o in ends.get(j, []):
            out.extend((
                f"{pad}  End Site", f"{pad}  {{",
                f"{pad}    OFFSET {_format_offset(o / scale)}", f"{pad}  }}",
            ))
        out.append(f"{pad}}}")

    roots = [j for j, p in enumerate(skeleton.parents) if p < 0]
    if len(roots) != 1:
        raise BVHError(
            "<motion>", None, f"BVH holds one hierarchy; this rig has {len(roots)} roots"
        )
    emit(roots[0], 0)
    return out


def _frame_values(motion: Motion, scale: float) -> np.ndarray:
    sk = motion.skeleton
    columns = []
    for j in depth_first_order(sk):
        chans = _written_channels(sk, j)
        order = "".join(c[0] for c in chans if c in ROTATION_CHANNELS)
        euler = np.rad2deg(quaternion_to_euler(motion.rotations[:, j], order))
        for c in chans:
            if c in POSITION_CHANNELS:
                columns.append(motion.positions[:, j, POSITION_CHANNELS.index(c)] / scale)
            else:
                columns.append(euler[:, order.index(c[0])])
    return np.stack(columns, axis=1) if columns else np.zeros((motion.num_frames, 0))


def _detectable_unit(skeleton: Skeleton, preferred: str) -> str:
    """``preferred`` if :func:`read_bvh` detects it back from a file in it, else one it does."""
    if preferred not in UNITS:
        return preferred
    height_m = standing_height(skeleton)
    for unit in (preferred, "m", "mm"):
        if detect_unit(height_m / UNITS[unit]) == unit:
            return unit
    return preferred  # pragma: no cover - metres or millimetres always detect back


def write_bvh(motion: Motion, path: str | os.PathLike, unit: str | None = None) -> Path:
    """Write a motion to a BVH file atomically (a temporary file renamed into place).

    Rotations are written as Euler angles in each joint's channel order, with the middle angle
    in [-90, 90] degrees. Joints that do not animate translation are not written with position
    channels; their rest offset is used.

    Args:
        motion: the motion to write.
        path: destination ``.bvh`` path; its folder must exist.
        unit: length unit of the file; by default the unit the motion was read from
            (``motion.metadata["file_unit"]``), else centimetres, unless :func:`read_bvh`
            would detect another unit in that file (a figure outside 1.2-2.2 m, read with an
            explicit ``unit``): then the unit it detects back (metres or millimetres). A
            figure outside 0.05-10 m is read back only with that unit given.

    Returns:
        The written path.
    """
    path = Path(path)
    if unit is None:
        unit = _detectable_unit(motion.skeleton, motion.metadata.get("file_unit", "cm"))
    if unit not in UNITS:
        raise ValueError(f"unit must be one of {sorted(UNITS)}, got {unit!r}")
    scale = UNITS[unit]
    if not path.parent.is_dir():
        raise BVHError(path, None, "the output folder does not exist: create it first")
    lines = _header_lines(motion.skeleton, scale)
    lines += ["MOTION", f"Frames: {motion.num_frames}", f"Frame Time: {1.0 / motion.fps:.9g}"]
    values = _frame_values(motion, scale)
    with atomic_output(path) as tmp, open(tmp, "w", newline="\n") as fh:
        fh.write("\n".join(lines) + "\n")
        if len(values):
            np.savetxt(fh, values, fmt="%.9g", delimiter=" ")
    return path
