"""Many agents' paths packed into flat arrays, queried for every agent in one operation.

A :class:`PathBank` holds the dense polylines of many :class:`~emotive.paths.GroundPath`
objects end to end in one growable table, each path's arc lengths shifted by a base so that
the whole key column rises monotonically. A query for ``B`` agents, each on its own slot at
its own arc length, is then one :func:`numpy.searchsorted` over the table plus a linear
interpolation: no Python loop over paths. The queries reproduce
:meth:`GroundPath.position <emotive.paths.GroundPath.position>`, ``heading`` and
``curvature`` exactly (same wrapping, same central differences), so an agent walks the same
way whether the bank holds one path or a thousand.

Adding a path costs ``O(N)`` for its ``N`` samples (amortized: the table doubles when full);
:meth:`PathBank.add_many` adds many paths with the same few array operations as one (their
rows and uniform grids made in one batch), and :meth:`PathBank.nearest` finds, for many
agents, the nearest point of each one's own path in one batch over their segments (a crowd
sends hundreds of agents along new paths every frame). Releasing a path marks its rows dead,
and the table is compacted once dead rows outnumber live ones. Slots are reference counted,
so agents sharing one path share its rows.

Legend: ``B`` queries, ``N`` polyline samples.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.paths import SAMPLE_SPACING, GroundPath

#: Space left between two paths' keys (metres of arc), so a key never reaches the next path.
_GAP = 1.0
#: Default curvature window of :meth:`GroundPath.curvature`, metres.
CURVATURE_WINDOW = 0.2


#: Arc spacing (metres) of the uniform grid :meth:`PathBank.ahead` interpolates.
GRID_SPACING = 0.01
#: Path segments :meth:`PathBank.nearest` measures at once (bounds its tables).
NEAREST_CHUNK = 1 << 18


@dataclass
class _Slot:
    path: GroundPath
    first: int
    count: int
    base: float
    grid: np.ndarray
    spacing: float
    ends: np.ndarray
    users: int = 1


def _wrapped(s: np.ndarray, length: np.ndarray, closed: np.ndarray) -> np.ndarray:
    """Arc lengths ``s`` wrapped onto loops and clamped to open paths' ends (broadcasting)."""
    return np.where(closed, np.mod(s, length), np.clip(s, 0.0, length))


def _grids(bank: PathBank, first: np.ndarray, last: np.ndarray, base: np.ndarray,
           length: np.ndarray, closed: np.ndarray) -> tuple[list[np.ndarray], np.ndarray,
                                                         np.ndarray]:
    """Many paths, already in the table, on uniform arc grids of about :data:`GRID_SPACING`.

    Each path gets a whole number of steps; the points are interpolated from its rows, as
    :meth:`PathBank.position` does, for every path in one search.

    Args:
        bank: the bank holding the paths' rows.
        first: ``(P,)`` each path's first row.
        last: ``(P,)`` each path's last row.
        base: ``(P,)`` each path's key base.
        length: ``(P,)`` arc lengths, metres.
        closed: ``(P,)`` which paths are loops.

    Returns:
        The ``(N_p + 1, 2)`` grid of each path, ``(P,)`` grid spacings (metres) and
        ``(P, 2, 2)`` unit tangents at each path's start and end (as
        :meth:`GroundPath.tangent <emotive.paths.GroundPath.tangent>`: central differences
        over one sample spacing, wrapped on loops, clamped at open ends).
    """
    steps = np.maximum(np.round(length / GRID_SPACING), 1.0)
    spacing = length / steps
    # One search for all: each path's grid, then the 4 ends of its two tangents (wrapped on
    # loops and clamped on open paths below, as GroundPath.tangent does).
    sizes = steps.astype(np.int64) + 5
    first_query = np.cumsum(sizes) - sizes
    which = np.repeat(np.arange(len(steps)), sizes)
    s = (np.arange(sizes.sum()) - first_query[which]) * spacing[which]
    tips = first_query[:, None] + sizes[:, None] - np.arange(4, 0, -1)          # (P, 4)
    h = np.minimum(SAMPLE_SPACING, 0.25 * length)
    end = np.where(closed, 0.0, length)
    s[tips] = np.stack((h, end + h, -h, end - h), -1)
    points = bank._interpolate(first[which], last[which],
                               _wrapped(s, length[which], closed[which]) + base[which])
    d = points[tips[:, :2]] - points[tips[:, 2:]]                               # (P, 2, 2)
    tangents = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    bounds = np.stack((first_query, tips[:, 0]), -1).tolist()
    return [points[a:b] for a, b in bounds], spacing, tangents


class PathBank:
    """Paths packed for batched queries, by slot number.

    Example::

        bank = PathBank()
        a, b = bank.add(circle(2.0)), bank.add(line(5.0))
        xz = bank.position(np.array([a, b, a]), np.array([0.0, 1.0, 3.0]))   # (3, 2)
    """

    def __init__(self) -> None:
        self._key = np.zeros(1024)
        self._pts = np.zeros((1024, 2))
        self._used = 0
        self._dead = 0
        self._slots: dict[int, _Slot] = {}
        self._by_path: dict[int, int] = {}
        self._next = 0
        self._top = 0.0
        self._table_dirty = True
        self._length = np.zeros(0)
        self._closed = np.zeros(0, dtype=bool)
        self._base = np.zeros(0)
        self._first = np.zeros(0, dtype=np.int64)
        self._last = np.zeros(0, dtype=np.int64)

    def __len__(self) -> int:
        return len(self._slots)

    def path(self, slot: int) -> GroundPath:
        """The path held in ``slot``."""
        return self._slots[slot].path

    def add(self, path: GroundPath) -> int:
        """Hold ``path`` (again, if it is already held) and return its slot."""
        return self.add_many([path])[0]

    def add_many(self, paths: Sequence[GroundPath]) -> list[int]:
        """Hold each of ``paths`` (as :meth:`add`, in order); returns their slots.

        The new paths' rows and uniform grids are made in one batch: a few array operations
        for any number of paths (a crowd gives hundreds of agents a new path every frame).
        """
        slots: list[int] = []
        fresh: dict[int, int] = {}       # id of a new path -> its slot
        new: list[GroundPath] = []
        users: dict[int, int] = {}
        for path in paths:
            slot = self._by_path.get(id(path), fresh.get(id(path)))
            if slot is None:
                slot = fresh[id(path)] = self._next + len(new)
                new.append(path)
            users[slot] = users.get(slot, 0) + 1
            slots.append(slot)
        if new:
            self._insert(new, list(fresh.values()), users)
        for slot in set(users) - set(fresh.values()):
            self._slots[slot].users += users[slot]
        return slots

    def _insert(self, paths: list[GroundPath], slots: list[int], users: dict[int, int]
                ) -> None:
        """Write new ``paths`` into the table as ``slots`` (numbered from ``self._next``)."""
        counts = np.array([len(p.arc) for p in paths], dtype=np.int64)
        length = np.array([p.length for p in paths])
        closed = np.array([p.closed for p in paths], dtype=bool)
        base = self._top + np.concatenate(([0.0], np.cumsum(length + _GAP)[:-1]))
        first = self._used + np.cumsum(counts) - counts
        total = int(counts.sum())
        self._reserve(self._used + total)
        rows = slice(self._used, self._used + total)
        self._key[rows] = np.concatenate([p.arc for p in paths]) + np.repeat(base, counts)
        self._pts[rows] = np.concatenate([p.points for p in paths])
        self._used += total
        grids, spacing, ends = _grids(self, first, first + counts - 1, base, length, closed)
        for k, (path, slot) in enumerate(zip(paths, slots, strict=True)):
            self._slots[slot] = _Slot(path, int(first[k]), int(counts[k]), float(base[k]),
                                      grids[k], float(spacing[k]), ends[k], users[slot])
            self._by_path[id(path)] = slot
        self._next += len(paths)
        self._top = float(base[-1] + length[-1] + _GAP)
        self._table_dirty = True

    def release(self, slot: int) -> None:
        """Drop one hold on ``slot``; its rows are freed when nobody holds it.

        Raises:
            KeyError: no such slot.
        """
        info = self._slots[slot]
        info.users -= 1
        if info.users > 0:
            return
        del self._slots[slot]
        del self._by_path[id(info.path)]
        self._dead += info.count
        self._table_dirty = True
        if self._dead > self._used - self._dead:
            self._compact()

    def _reserve(self, rows: int) -> None:
        if rows <= len(self._key):
            return
        size = max(rows, 2 * len(self._key))
        key, pts = np.zeros(size), np.zeros((size, 2))
        key[:self._used], pts[:self._used] = self._key[:self._used], self._pts[:self._used]
        self._key, self._pts = key, pts

    def _compact(self) -> None:
        """Rewrite the table with the live paths only (``O(total live samples)``)."""
        slots = sorted(self._slots.items(), key=lambda kv: kv[1].first)
        self._used, self._dead, self._top = 0, 0, 0.0
        for _, info in slots:
            n = info.count
            rows = slice(self._used, self._used + n)
            self._key[rows] = info.path.arc + self._top
            self._pts[rows] = info.path.points
            info.first, info.base = self._used, self._top
            self._used += n
            self._top += info.path.length + _GAP
        self._table_dirty = True

    def _tables(self) -> None:
        """Per-slot columns indexed by slot number (rebuilt after adds and releases)."""
        if not self._table_dirty:
            return
        size = self._next
        self._length = np.ones(size)
        self._closed = np.zeros(size, dtype=bool)
        self._base = np.zeros(size)
        self._first = np.zeros(size, dtype=np.int64)
        self._last = np.ones(size, dtype=np.int64)
        self._grid_first = np.zeros(size, dtype=np.int64)
        self._grid_steps = np.ones(size)
        self._grid_spacing = np.ones(size)
        self._ends = np.zeros((size, 2, 2))
        grids, at = [np.zeros((2, 2))], 2
        for slot, info in self._slots.items():
            grids.append(info.grid)
            self._grid_first[slot] = at
            self._grid_steps[slot] = len(info.grid) - 1
            self._grid_spacing[slot] = info.spacing
            self._ends[slot] = info.ends
            at += len(info.grid)
            self._length[slot] = info.path.length
            self._closed[slot] = info.path.closed
            self._base[slot] = info.base
            self._first[slot] = info.first
            self._last[slot] = info.first + info.count - 1
        self._grid_flat = np.concatenate(grids).ravel()
        self._table_dirty = False

    def length(self, slots: np.ndarray) -> np.ndarray:
        """``(B,)`` total arc length of each slot's path, metres."""
        self._tables()
        return self._length[slots]

    def closed(self, slots: np.ndarray) -> np.ndarray:
        """``(B,)`` whether each slot's path is a loop."""
        self._tables()
        return self._closed[slots]

    def _wrap(self, slots: np.ndarray, s: np.ndarray) -> np.ndarray:
        return _wrapped(s, self._length[slots], self._closed[slots])

    def _interpolate(self, first: np.ndarray, last: np.ndarray, key: np.ndarray) -> np.ndarray:
        """``(..., 2)`` points at table keys ``key``, each within its path's rows."""
        i = np.searchsorted(self._key[:self._used], key, side="right") - 1
        i = np.clip(i, first, last - 1)
        k0, k1 = self._key[i], self._key[i + 1]
        t = np.clip((key - k0) / np.maximum(k1 - k0, 1e-300), 0.0, 1.0)[..., None]
        return self._pts[i] * (1.0 - t) + self._pts[i + 1] * t

    def position(self, slots: np.ndarray, s: np.ndarray) -> np.ndarray:
        """``(..., B, 2)`` ``(x, z)`` of slot ``slots[i]``'s path at arc length ``s[..., i]``.

        ``s`` may stack several queries per slot on leading axes: all are answered by one
        search.
        """
        self._tables()
        slots = np.asarray(slots, dtype=np.int64)
        key = self._wrap(slots, np.asarray(s, dtype=np.float64)) + self._base[slots]
        return self._interpolate(self._first[slots], self._last[slots], key)

    def heading(self, slots: np.ndarray, s: np.ndarray) -> np.ndarray:
        """``(..., B)`` yaw of the tangent (0 faces +Z), as :meth:`GroundPath.heading`.

        ``s`` is ``(..., B)`` as in :meth:`position`.
        """
        self._tables()
        slots = np.asarray(slots, dtype=np.int64)
        s = self._wrap(slots, np.asarray(s, dtype=np.float64))
        length, closed = self._length[slots], self._closed[slots]
        h = np.minimum(SAMPLE_SPACING, 0.25 * length)
        lo = np.where(closed, s - h, np.maximum(s - h, 0.0))
        hi = np.where(closed, s + h, np.minimum(s + h, length))
        ends = self.position(slots, np.stack((hi, lo)))
        d = ends[0] - ends[1]
        d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
        return np.arctan2(d[..., 0], d[..., 1])

    def curvature(self, slots: np.ndarray, s: np.ndarray,
                  window: float = CURVATURE_WINDOW) -> np.ndarray:
        """``(B,)`` signed curvature in 1/m (positive turning left), as ``GroundPath.curvature``."""
        self._tables()
        slots = np.asarray(slots, dtype=np.int64)
        s = np.asarray(s, dtype=np.float64)
        length, closed = self._length[slots], self._closed[slots]
        h = 0.5 * np.minimum(window, 0.5 * length)
        a, b = self.heading(slots, np.stack((s - h, s + h)))
        span = np.where(closed, 2 * h, self._wrap(slots, s + h) - self._wrap(slots, s - h))
        turn = np.angle(np.exp(1j * (b - a)))
        return np.where(span > 1e-9, turn / np.maximum(span, 1e-9), 0.0)

    def nearest(self, slots: np.ndarray, xz: np.ndarray) -> np.ndarray:
        """``(B,)`` arc length of the point of slot ``slots[i]``'s path nearest to ``xz[i]``.

        As :meth:`GroundPath.nearest <emotive.paths.GroundPath.nearest>` (every segment
        tried, zero-length ones skipped, the earlier segment at equal distance), for all the
        queries in one batch over their paths' segments (in chunks of about
        :data:`NEAREST_CHUNK` segments, so memory stays bounded for long paths).

        Args:
            slots: ``(B,)`` slots.
            xz: ``(B, 2)`` ground points ``(x, z)``, metres.
        """
        # From the slots, not the per-slot columns: those are rebuilt for all paths after
        # any change, and a query right after one path's change should not pay for that.
        held = [self._slots[int(slot)] for slot in np.asarray(slots).reshape(-1)]
        xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
        first = np.array([h.first for h in held], dtype=np.int64)
        base = np.array([h.base for h in held])
        segments = np.array([h.count - 1 for h in held], dtype=np.int64)
        done = np.cumsum(segments)
        arc = np.empty(len(held))
        lo = 0
        while lo < len(held):
            budget = (done[lo - 1] if lo else 0) + NEAREST_CHUNK
            hi = max(lo + 1, int(np.searchsorted(done, budget, side="right")))
            n = segments[lo:hi]
            owner = np.repeat(np.arange(hi - lo), n)
            start = np.cumsum(n) - n
            row = np.arange(n.sum()) - np.repeat(start, n) + np.repeat(first[lo:hi], n)
            a, d = self._pts[row], self._pts[row + 1] - self._pts[row]
            length2 = (d * d).sum(-1)
            q = xz[lo:hi][owner]
            along = np.clip(((q - a) * d).sum(-1) / np.maximum(length2, 1e-300), 0.0, 1.0)
            dist = np.where(length2 > 0, np.hypot(*(q - a - along[:, None] * d).T), np.inf)
            hits = np.flatnonzero(dist == np.minimum.reduceat(dist, start)[owner])
            k = hits[np.searchsorted(owner[hits], np.arange(hi - lo))]
            arc[lo:hi] = (self._key[row[k]] - base[lo:hi]) + along[k] * np.sqrt(length2[k])
            lo = hi
        return arc

    def ahead(self, slots: np.ndarray, arc: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        """``(B, K, 2)`` points of each slot's path at ``arc + offsets``.

        The points are interpolated on each path's uniform grid of about
        :data:`GRID_SPACING` metres (made once when the path is added), so a query is
        arithmetic and one gather, with no search. An open path is extended straight along
        its end tangents, so the points always continue the path (the path samples of the
        exported gait step, ``docs/runtime.md``); a loop wraps.

        Args:
            slots: ``(B,)`` slots.
            arc: ``(B,)`` arc lengths, metres.
            offsets: ``(K,)`` arc offsets, metres.
        """
        self._tables()
        slots = np.asarray(slots, dtype=np.int64)
        s = np.asarray(arc, dtype=np.float64)[:, None] + np.asarray(offsets)[None, :]  # (B, K)
        length, closed = self._length[slots][:, None], self._closed[slots][:, None]
        # Written with floor, minimum and maximum, and one flat take per coordinate: on
        # 1,000 agents a third of the time of mod, clip and fancy indexing.
        wrapped = s - length * np.floor(s / length)
        inside = np.where(closed, wrapped, np.minimum(np.maximum(s, 0.0), length))
        steps = self._grid_steps[slots][:, None]
        u = inside / self._grid_spacing[slots][:, None]
        i = np.minimum(np.floor(u), steps - 1)
        t = u - i
        at = 2 * (self._grid_first[slots][:, None] + i.astype(np.int64))
        flat = self._grid_flat
        x0, z0 = np.take(flat, at), np.take(flat, at + 1)
        x = x0 + (np.take(flat, at + 2) - x0) * t
        z = z0 + (np.take(flat, at + 3) - z0) * t
        past = np.where(closed, 0.0, s - inside)
        before, after = np.minimum(past, 0.0), np.maximum(past, 0.0)
        ends = self._ends[slots]
        x += before * ends[:, None, 0, 0] + after * ends[:, None, 1, 0]
        z += before * ends[:, None, 0, 1] + after * ends[:, None, 1, 1]
        return np.stack((x, z), -1)
