"""Nearest neighbours under the paper's point-cloud distance (section 5.1, equation 1).

The distance between a query window and a database window of ``s`` frames is the weighted sum
of squared distances of their points after the best rigid transform of the ground plane (a
rotation about the vertical and a translation in ``x, z``) is applied to the database window.
With the weights summing to one and both windows centred on their weighted ground centroids
(``a`` the query, ``b`` the candidate), the minimum over the transform is, in closed form
(Kovar et al. 2002):

``D = sum w |a|^2 + sum w |b|^2 - 2 sqrt(C^2 + S^2) + sum w (y_a - y_b)^2``, with
``C = sum w (a_x b_x + a_z b_z)`` and ``S = sum w (a_x b_z - a_z b_x)`` over ground
coordinates, the optimal rotation being ``atan2(S, C)``.

Search. Exact distances to every frame (:meth:`PointCloudSearch.brute_force`) cost ``N``
window evaluations per query. The fast path ranks candidates with k-d trees
(:class:`scipy.spatial.cKDTree`) over reduced window features (windows centred, turned to the
newest frame's heading, projected on their principal axes; see
:func:`emotive.models.mar.database.canonical_windows`) and evaluates the exact distance only on
those: per class, the ``candidates * K`` tree neighbours. For unlabeled input a global tree
over the allowed classes' frames first picks the ``max_classes`` classes with the nearest
frames; classes outside them get no
mixture weight (their distance to the input is larger, and the mixture weight decays as
``exp(-D_j / (delta min D))``).

Legend: ``s`` window frames, ``P`` points, ``M`` candidates, ``K`` neighbours, ``d`` reduced
dimensions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from emotive.core.roles import ROLES
from emotive.models.mar.database import MARDatabase, canonical_windows, point_weights
from emotive.models.mar.representation import LOWER_BODY_ROLES


def rigid_distance(query: np.ndarray, candidates: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Equation 1: weighted squared distance after the best ground-plane rigid transform.

    In float64: the neighbours are the order of these distances, and in float32 the BLAS
    kernel that OpenBLAS picks for the CPU (summing in its own order) moved them by 2e-7,
    enough to swap two neighbours 2.4e-7 apart and change the whole output on another
    machine. In float64 kernels differ by 1e-16 relative, far below the gaps between
    neighbours; equal distances are ordered by database frame (see :class:`PointCloudSearch`).

    Args:
        query: ``(s, P, 3)`` query window.
        candidates: ``(M, s, P, 3)`` database windows.
        weights: ``(s, P)`` non-negative weights.

    Returns:
        ``(M,)`` distances (non-negative).
    """
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    w = w / w.sum()
    q = np.asarray(query, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(candidates, dtype=np.float64).reshape(len(candidates), -1, 3)
    ax, ay, az = q[:, 0] - w @ q[:, 0], q[:, 1], q[:, 2] - w @ q[:, 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    mx, mz = bx @ w, bz @ w
    wax, waz = w * ax, w * az
    # The query is centred (sum w a = 0), so the candidates' centring drops out of C and S.
    c = bx @ wax + bz @ waz
    s = bz @ wax - bx @ waz
    own = w @ (ax * ax + az * az + ay * ay)
    other = (bx * bx + bz * bz + by * by) @ w - mx * mx - mz * mz
    cross = by @ (w * ay)
    return np.maximum(own + other - 2.0 * np.sqrt(c * c + s * s) - 2.0 * cross, 0.0)


def best_rotation(query: np.ndarray, candidate: np.ndarray, weights: np.ndarray) -> float:
    """The rotation about +Y (radians) of equation 1's optimum for one candidate ``(s, P, 3)``."""
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    w = w / w.sum()
    q = np.asarray(query, dtype=np.float64).reshape(-1, 3)
    b = np.asarray(candidate, dtype=np.float64).reshape(-1, 3)
    ax, az = q[:, 0] - w @ q[:, 0], q[:, 2] - w @ q[:, 2]
    bx, bz = b[:, 0] - w @ b[:, 0], b[:, 2] - w @ b[:, 2]
    return float(np.arctan2(w @ (ax * bz - az * bx), w @ (ax * bx + az * bz)))


@dataclass(frozen=True)
class Neighbours:
    """The K nearest frames of each searched class.

    Attributes:
        classes: ``(c,)`` searched classes.
        frames: ``(c, K)`` database frames, nearest first (per class).
        distances: ``(c, K)`` their equation-1 distances.
        pool: ``(M,)`` every candidate that got an exact distance.
        pool_distances: ``(M,)`` their distances.
        foot_distances: ``(M,)`` their distances under the footplant weights (upper body
            zero).
    """

    classes: np.ndarray
    frames: np.ndarray
    distances: np.ndarray
    pool: np.ndarray
    pool_distances: np.ndarray
    foot_distances: np.ndarray


class PointCloudSearch:
    """KNN of query windows in a :class:`MARDatabase`, fast (trees) or brute force.

    Args:
        db: the database.
    """

    def __init__(self, db: MARDatabase) -> None:
        self.db = db
        self.config = db.config
        self.index = db.window_index()
        num_points = db.points.shape[1]
        self.weights = point_weights(db.config, num_points)
        lower = np.isin(np.array(ROLES), LOWER_BODY_ROLES).astype(np.float64)
        foot = point_weights(db.config, num_points) * lower
        self.foot_weights = foot / foot.sum()
        order = np.argsort(db.frame_class, kind="stable")
        bounds = np.searchsorted(db.frame_class[order], np.arange(db.num_classes + 1))
        self.class_frames = [order[bounds[c]:bounds[c + 1]] for c in range(db.num_classes)]
        feats = db.features.astype(np.float64)
        self.trees = [cKDTree(feats[f]) for f in self.class_frames]
        self._feats = feats
        self._screens: dict[bytes, tuple[cKDTree, np.ndarray]] = {}

    def _screen_tree(self, allowed: np.ndarray) -> tuple[cKDTree, np.ndarray]:
        """A tree over the frames of the allowed classes (one per set of classes, cached)."""
        key = np.sort(allowed).tobytes()
        if key not in self._screens:
            frames = np.flatnonzero(np.isin(self.db.frame_class, allowed))
            self._screens[key] = (cKDTree(self._feats[frames]), frames)
        return self._screens[key]

    def windows(self, frames: np.ndarray) -> np.ndarray:
        """``(M, s, P, 3)`` database windows of frames ``(M,)``."""
        return self.db.points[self.index[frames]]

    def reduce(self, window: np.ndarray, yaw: float) -> np.ndarray:
        """``(d,)`` reduced features of a query window.

        ``(d,)`` reduced features of a query window ``(s, P, 3)`` whose newest frame has
        heading ``yaw``.
        """
        full = canonical_windows(window[None], np.array([yaw]), self.weights)[0]
        return (full - self.db.pca_mean) @ self.db.pca_basis

    def _screen(self, feature: np.ndarray, allowed: np.ndarray) -> np.ndarray:
        """The ``max_classes`` classes among ``allowed`` whose frames come nearest.

        The ``max_classes`` classes among ``allowed`` whose frames come nearest in a tree
        over all their frames.
        """
        cfg = self.config
        if len(allowed) <= cfg.max_classes:
            return allowed
        tree, frames = self._screen_tree(allowed)
        _, idx = tree.query(feature, k=min(cfg.screen, len(frames)))
        hits = self.db.frame_class[frames[np.atleast_1d(idx)]]
        _, first = np.unique(hits, return_index=True)
        return hits[np.sort(first)][:cfg.max_classes].astype(np.int64)

    def search(self, window: np.ndarray, yaw: float, allowed: np.ndarray,
               k: int | None = None) -> Neighbours:
        """The ``k`` nearest frames of each (screened) allowed class, by exact distance.

        Args:
            window: ``(s, P, 3)`` query window, oldest frame first.
            yaw: heading of its newest frame.
            allowed: ``(c,)`` classes to search (labels restrict them).
            k: neighbours per class (``config.k`` when None).
        """
        k = k or self.config.k
        feature = self.reduce(window, yaw)
        classes = self._screen(feature, np.asarray(allowed, dtype=np.int64))
        parts = []
        for c in classes:
            size = len(self.class_frames[c])
            count = min(self.config.candidates * k, size)
            _, loc = self.trees[c].query(feature, k=count)
            parts.append(self.class_frames[c][np.atleast_1d(loc)])
        return self._finish(window, classes, parts, k)

    def brute_force(self, window: np.ndarray, allowed: np.ndarray,
                    k: int | None = None) -> Neighbours:
        """The same as :meth:`search` with exact distances (the benchmark's baseline).

        The same as :meth:`search` with exact distances to every frame of every allowed
        class (the baseline of the speed benchmark).
        """
        k = k or self.config.k
        classes = np.asarray(allowed, dtype=np.int64)
        return self._finish(window, classes, [self.class_frames[c] for c in classes], k)

    def _finish(self, window: np.ndarray, classes: np.ndarray, parts: list[np.ndarray],
                k: int) -> Neighbours:
        pool = np.concatenate(parts)
        windows = self.windows(pool)
        dist = rigid_distance(window, windows, self.weights)
        foot = rigid_distance(window, windows, self.foot_weights)
        frames = np.empty((len(classes), k), dtype=np.int64)
        dists = np.empty((len(classes), k))
        start = 0
        for i, part in enumerate(parts):
            d = dist[start:start + len(part)]
            take = min(k, len(part))
            # Nearest first, equal distances by database order (a choice the same on any CPU).
            best = np.lexsort((part, d))[:take]
            # Classes smaller than K repeat their farthest neighbour (keeps arrays rectangular).
            best = np.concatenate((best, np.full(k - take, best[-1])))
            frames[i], dists[i] = part[best], d[best]
            start += len(part)
        return Neighbours(classes, frames, dists, pool, dist, foot)

    def footplants(self, nb: Neighbours, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` nearest candidates of a search under lower-body weights (paper section 6).

        Returns:
            ``(k,)`` frames and their footplant distances.
        """
        k = min(k or self.config.k, len(nb.pool))
        dist = nb.foot_distances
        best = np.lexsort((nb.pool, dist))[:k]
        return nb.pool[best], dist[best]
