"""Ground paths for agents to follow: built-in shapes, waypoint splines, arc length.

A :class:`GroundPath` is a smooth curve on the ground plane, stored as a dense polyline in
``(x, z)`` metres and parameterised by arc length ``s``. Positions, unit tangents, headings
and curvatures are looked up at any ``s``; closed paths (circle, figure-8) wrap around, open
ones hold their end points beyond ``[0, length]``. The heading convention is the one of
:func:`emotive.core.ops.heading`: yaw ``a`` faces ``(sin a, cos a)`` in ``(x, z)``, so ``0``
faces +Z.

Built-in shapes (:data:`SHAPES`), each starting at the origin heading +Z:

* ``line``: straight, ``length`` metres (default 10).
* ``circle``: ``radius`` metres (default 2), turning left (counter-clockwise seen from above).
* ``figure8``: two loops of about ``radius`` metres (default 2) crossing at the origin, left
  loop first, with continuous curvature.
* ``zigzag``: a run-up, then ``count`` legs (default 6) of ``leg`` metres (default 2.5)
  alternating ``angle`` degrees (default 35) left and right of +Z, corners rounded by a spline.

Waypoints (a JSON file, ``[[x, z], ...]`` or ``{"points": [[x, z], ...], "closed": false}``, in
metres) are smoothed by a cubic spline through the points, parameterised by chord length.

Legend: ``N`` polyline samples, ``...`` any query shape.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from emotive.errors import PathError

#: Spacing of the dense polyline, metres.
SAMPLE_SPACING = 0.01
#: Coordinates beyond this many metres from the origin are refused (a likely unit mistake).
MAX_COORDINATE = 1.0e5
#: Waypoints closer than this are merged (metres).
MIN_WAYPOINT_GAP = 1.0e-6


@dataclass(frozen=True, eq=False)
class GroundPath:
    """A smooth ground curve parameterised by arc length.

    Attributes:
        points: ``(N, 2)`` dense polyline ``(x, z)`` in metres, samples about
            :data:`SAMPLE_SPACING` apart; for a closed path the last sample equals the first.
        arc: ``(N,)`` arc length at each sample, from 0 to :attr:`length`.
        closed: whether the path is a loop.
        name: where it came from (a shape name or a file).
    """

    points: np.ndarray
    arc: np.ndarray
    closed: bool
    name: str = "path"

    @classmethod
    def from_polyline(cls, points: np.ndarray, closed: bool = False, name: str = "path"
                      ) -> GroundPath:
        """A path through a dense polyline (consecutive duplicates dropped).

        Args:
            points: ``(N, 2)`` ``(x, z)`` samples, N >= 2, dense enough that straight pieces
                between them are a fair approximation.
            closed: join the last point back to the first.
            name: a label for messages.

        Raises:
            PathError: fewer than two distinct points, non-finite or huge coordinates.
        """
        pts = _check_points(points, name)
        if closed and np.linalg.norm(pts[-1] - pts[0]) > MIN_WAYPOINT_GAP:
            pts = np.vstack((pts, pts[:1]))
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        arc = np.concatenate(([0.0], np.cumsum(seg)))
        if not arc[-1] > MIN_WAYPOINT_GAP:
            raise PathError(f"path {name} has zero length: give points that are apart")
        pts.setflags(write=False)
        arc.setflags(write=False)
        return cls(pts, arc, closed, name)

    @property
    def length(self) -> float:
        """Total arc length in metres."""
        return float(self.arc[-1])

    def _wrap(self, s: np.ndarray | float) -> np.ndarray:
        s = np.asarray(s, dtype=np.float64)
        if self.closed:
            return np.mod(s, self.length)
        return np.clip(s, 0.0, self.length)

    def position(self, s: np.ndarray | float) -> np.ndarray:
        """``(..., 2)`` ``(x, z)`` at arc lengths ``s`` ``(...)``."""
        s = self._wrap(s)
        return np.stack(
            (np.interp(s, self.arc, self.points[:, 0]), np.interp(s, self.arc, self.points[:, 1])),
            axis=-1,
        )

    def tangent(self, s: np.ndarray | float) -> np.ndarray:
        """``(..., 2)`` unit direction of travel at ``s``.

        From a central difference over about one sample spacing either side.
        """
        h = min(SAMPLE_SPACING, 0.25 * self.length)
        s = self._wrap(s)
        lo = s - h if self.closed else np.maximum(s - h, 0.0)
        hi = s + h if self.closed else np.minimum(s + h, self.length)
        d = self.position(hi) - self.position(lo)
        return d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)

    def heading(self, s: np.ndarray | float) -> np.ndarray:
        """``(...)`` yaw in ``(-pi, pi]`` of the tangent at ``s`` (0 faces +Z)."""
        t = self.tangent(s)
        return np.arctan2(t[..., 0], t[..., 1])

    def curvature(self, s: np.ndarray | float, window: float = 0.2) -> np.ndarray:
        """``(...)`` signed curvature in 1/m at ``s`` (positive turning left).

        From the change of heading over ``window`` metres of arc.
        """
        h = 0.5 * min(window, 0.5 * self.length)
        s = np.asarray(s, dtype=np.float64)
        a = self.heading(s - h)
        b = self.heading(s + h)
        span = self._wrap(s + h) - self._wrap(s - h) if not self.closed else np.full_like(s, 2 * h)
        turn = np.angle(np.exp(1j * (b - a)))
        return np.where(span > 1e-9, turn / np.maximum(span, 1e-9), 0.0)

    def nearest(self, xz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest point of the path to each query point.

        Args:
            xz: ``(..., 2)`` ground positions.

        Returns:
            ``(arc length (...), distance (...))`` of the closest point on the polyline.
        """
        distance, _, _, arc = closest_points(xz, self.points)
        return arc, distance


#: Query points handled at once by :func:`closest_points` (bounds its points x segments table).
_CHUNK = 256


def closest_points(
    points: np.ndarray, polyline: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest point of a 2D polyline to each of a set of 2D points.

    Each point is projected on every segment (clamped to its ends) and the nearest projection
    is kept; at equal distance (a shared vertex) the earlier segment wins. Points are handled
    in chunks, so memory stays bounded for long inputs.

    Args:
        points: ``(..., 2)`` ground-plane ``(x, z)`` points.
        polyline: ``(P, 2)`` vertices ``(x, z)`` in walking order, ``P >= 2``; zero-length
            segments (repeated vertices) are ignored.

    Returns:
        ``(...)`` distances, ``(..., 2)`` nearest points, ``(..., 2)`` unit tangents there
        (pointing from the first vertex towards the last) and ``(...)`` arc lengths of the
        nearest points along the polyline.

    Raises:
        ValueError: bad shapes, a non-finite polyline, or one without a segment of non-zero
            length.
    """
    pts = np.asarray(points, dtype=np.float64)
    verts = np.asarray(polyline, dtype=np.float64)
    if pts.ndim < 1 or pts.shape[-1] != 2:
        raise ValueError(f"points must have shape (..., 2), got {pts.shape}")
    if verts.ndim != 2 or verts.shape[1] != 2 or len(verts) < 2:
        raise ValueError(f"polyline must have shape (P, 2) with P >= 2, got {verts.shape}")
    if not np.all(np.isfinite(verts)):
        raise ValueError("polyline has non-finite vertices")
    seg = np.diff(verts, axis=0)
    length2 = (seg * seg).sum(-1)
    keep = length2 > 0
    if not keep.any():
        raise ValueError("polyline has no segment of non-zero length")
    seg_arc = np.concatenate(([0.0], np.cumsum(np.sqrt(length2))))[:-1][keep]
    start, seg, length2 = verts[:-1][keep], seg[keep], length2[keep]
    unit = seg / np.sqrt(length2)[:, None]
    flat = pts.reshape(-1, 2)
    distance = np.empty(len(flat))
    nearest = np.empty((len(flat), 2))
    tangent = np.empty((len(flat), 2))
    arc = np.empty(len(flat))
    for lo in range(0, len(flat), _CHUNK):
        q = flat[lo:lo + _CHUNK, None, :]
        along = np.clip(((q - start) * seg).sum(-1) / length2, 0.0, 1.0)
        foot = start + along[..., None] * seg
        dist = np.linalg.norm(q - foot, axis=-1)
        k = dist.argmin(-1)
        rows = np.arange(len(k))
        distance[lo:lo + _CHUNK] = dist[rows, k]
        nearest[lo:lo + _CHUNK] = foot[rows, k]
        tangent[lo:lo + _CHUNK] = unit[k]
        arc[lo:lo + _CHUNK] = seg_arc[k] + along[rows, k] * np.sqrt(length2[k])
    shape = pts.shape[:-1]
    return (distance.reshape(shape), nearest.reshape(*shape, 2), tangent.reshape(*shape, 2),
            arc.reshape(shape))


def _check_points(points: np.ndarray, name: str) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise PathError(f"path {name}: points must be pairs [x, z], got shape {pts.shape}")
    if not np.isfinite(pts).all():
        raise PathError(f"path {name}: points must be finite numbers (found NaN or inf)")
    if np.abs(pts).max(initial=0.0) > MAX_COORDINATE:
        raise PathError(
            f"path {name}: a coordinate exceeds {MAX_COORDINATE:g} m; paths are in metres "
            "(convert centimetres or other units first)"
        )
    keep = np.concatenate(([True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > MIN_WAYPOINT_GAP))
    pts = pts[keep]
    if len(pts) < 2:
        raise PathError(f"path {name} needs at least two distinct points, got {len(pts)}")
    return pts


def _sample_count(approx_length: float) -> int:
    return max(int(np.ceil(approx_length / SAMPLE_SPACING)) + 1, 16)


def _positive(value: float, what: str) -> None:
    if not (np.isfinite(value) and 0 < value <= MAX_COORDINATE):
        raise PathError(f"{what} must be a positive number of metres, got {value}")


def _start_at_origin_heading_z(pts: np.ndarray) -> np.ndarray:
    """Move and turn ``(N, 2)`` points so they start at the origin heading +Z."""
    pts = pts - pts[0]
    d = pts[min(3, len(pts) - 1)]
    a = np.arctan2(d[0], d[1])
    c, s = np.cos(a), np.sin(a)
    # Rotating by -a about Y maps direction (sin a, cos a) onto (0, 1).
    return np.stack((c * pts[:, 0] - s * pts[:, 1], s * pts[:, 0] + c * pts[:, 1]), axis=1)


def line(length: float = 10.0) -> GroundPath:
    """Straight ahead along +Z for ``length`` metres."""
    _positive(length, "length")
    z = np.linspace(0.0, length, _sample_count(length))
    return GroundPath.from_polyline(np.stack((np.zeros_like(z), z), axis=1), name="line")


def circle(radius: float = 2.0) -> GroundPath:
    """A closed circle of ``radius`` metres, turning to the agent's left.

    A closed circle of ``radius`` metres, starting at the origin heading +Z and turning to
    the agent's left (towards +X: facing +Z with Y up, the left hand points to +X).
    """
    _positive(radius, "radius")
    t = np.linspace(0.0, 2.0 * np.pi, _sample_count(2.0 * np.pi * radius))
    pts = np.stack((radius * (1.0 - np.cos(t)), radius * np.sin(t)), axis=1)
    return GroundPath.from_polyline(pts, closed=True, name="circle")


def figure8(radius: float = 2.0) -> GroundPath:
    """A closed figure-8 of two loops of about ``radius`` metres.

    Crossing itself at the origin, where it starts heading +Z; the left loop comes first.

    Made by a periodic cubic spline through eight points on each of two circles that touch at
    the origin, so the curvature is continuous: about ``1 / radius`` along the loops, changing
    sign smoothly through the crossing.
    """
    _positive(radius, "radius")
    t = np.arange(8) * (2.0 * np.pi / 8)
    left = np.stack((radius * (1.0 - np.cos(t)), radius * np.sin(t)), axis=1)
    right = np.stack((-radius * (1.0 - np.cos(t)), radius * np.sin(t)), axis=1)
    pts = _spline(np.vstack((left, right)), closed=True, name="figure8")
    return GroundPath.from_polyline(_start_at_origin_heading_z(pts), closed=True, name="figure8")


def zigzag(leg: float = 2.5, angle: float = 35.0, count: int = 6) -> GroundPath:
    """A zigzag path: a straight run-up, then legs turning left and right.

    A straight run-up of ``leg / 2`` metres along +Z, then ``count`` legs of ``leg`` metres
    turning ``angle`` degrees left then right of +Z, corners rounded by a cubic spline; starts
    at the origin heading +Z.
    """
    _positive(leg, "leg")
    if not (0 < angle < 90 and int(count) == count and count >= 1):
        raise PathError(f"zigzag needs 0 < angle < 90 degrees and count >= 1, got {angle}, {count}")
    a = np.radians(angle) * np.where(np.arange(count) % 2 == 0, 1.0, -1.0)
    steps = leg * np.stack((np.sin(a), np.cos(a)), axis=1)
    run_up = np.array([0.0, 0.5 * leg])
    corners = np.vstack(([0.0, 0.0], run_up, run_up + np.cumsum(steps, axis=0)))
    pts = _spline(corners, closed=False, name="zigzag")
    return GroundPath.from_polyline(_start_at_origin_heading_z(pts), name="zigzag")


def _spline(points: np.ndarray, closed: bool, name: str) -> np.ndarray:
    """Dense ``(N, 2)`` samples of a cubic spline through ``points`` by chord length."""
    pts = _check_points(points, name)
    if closed:
        if len(pts) < 3:
            raise PathError(f"closed path {name} needs at least three distinct points")
        if np.linalg.norm(pts[-1] - pts[0]) > MIN_WAYPOINT_GAP:
            pts = np.vstack((pts, pts[:1]))
    chord = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    if len(pts) == 2:
        u = np.linspace(0.0, chord[-1], _sample_count(chord[-1]))
        return pts[0] + (u / chord[-1])[:, None] * (pts[1] - pts[0])
    spline = CubicSpline(chord, pts, axis=0, bc_type="periodic" if closed else "natural")
    u = np.linspace(0.0, chord[-1], _sample_count(1.5 * chord[-1]))
    return spline(u)


def waypoints(points: np.ndarray, closed: bool = False, name: str = "waypoints") -> GroundPath:
    """A smooth path through ``(K, 2)`` waypoints ``(x, z)`` in metres.

    A smooth path through ``(K, 2)`` waypoints ``(x, z)`` in metres (K >= 2), by a cubic
    spline over chord length (natural ends, or periodic when ``closed``). Consecutive repeated
    points are merged.
    """
    return GroundPath.from_polyline(_spline(points, closed, name), closed=closed, name=name)


def read_waypoints(path: str | os.PathLike) -> GroundPath:
    """A path from a JSON file.

    ``[[x, z], ...]`` or ``{"points": [[x, z], ...], "closed": false}``, metres.

    Raises:
        PathError: the file is missing, not JSON, or does not hold such points.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise PathError(f"path file {path} does not exist: check the name") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PathError(f"path file {path} is not valid JSON ({exc})") from None
    closed = False
    if isinstance(data, dict):
        closed = data.get("closed", False)
        if not isinstance(closed, bool):
            raise PathError(f'path file {path}: "closed" must be true or false')
        data = data.get("points")
    try:
        pts = np.asarray(data, dtype=np.float64)
    except (TypeError, ValueError):
        pts = np.zeros((0, 0))
    if pts.ndim != 2 or pts.shape[1:] != (2,):
        raise PathError(
            f'path file {path} must hold [[x, z], ...] or {{"points": [[x, z], ...]}} in metres'
        )
    return waypoints(pts, closed=closed, name=str(path))


#: Built-in shapes by name.
SHAPES: dict[str, Callable[..., GroundPath]] = {
    "line": line, "circle": circle, "figure8": figure8, "zigzag": zigzag,
}


def load_path(spec: str | os.PathLike) -> GroundPath:
    """A built-in shape by name (:data:`SHAPES`, default sizes) or a JSON waypoint file.

    Raises:
        PathError: neither a shape name nor a readable waypoint file.
    """
    text = str(spec)
    if text in SHAPES:
        return SHAPES[text]()
    if text.endswith(".json") or Path(text).exists():
        return read_waypoints(text)
    raise PathError(
        f"unknown path {text!r}: use one of {', '.join(SHAPES)} or a JSON file of [x, z] "
        "waypoints in metres"
    )
