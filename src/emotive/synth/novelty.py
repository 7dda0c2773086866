"""The check that the novel trajectories are not the data's root paths.

The main paper's augmented data set walks trajectories "not present in the dataset"
(Bhattacharya et al. 2020, section 5.2). When the Bandai Namco data is there
(:func:`emotive.data.dataset_dir`), every trajectory is compared with the root path of every
locomotion clip of both data sets:

* a root path is the hips' ``(x, z)`` smoothed over one second (the sway of the steps
  removed); both it and the trajectory are resampled every :data:`STEP` metres of arc;
* the shorter of the two slides along the longer, and at each place is laid onto it by the
  rotation and translation that fit it best (2D Procrustes); the gap is the mean distance
  of the points after that fit, the least over places (a straight walk of the data fits any
  straight stretch, so a small gap alone says little);
* the coverage is the shorter's length over the longer's;
* a trajectory *coincides* with a clip when the gap is under :data:`MATCH_DISTANCE` and the
  coverage at least :data:`MIN_COVERAGE`: the two are mostly the same path.

A trajectory that coincides with a clip is an error (:class:`NoveltyError`, naming both)
before any walk is made; the data set never depends on whether the data is there (nothing
is drawn again), only the card's statement does: when the data is absent the check is
skipped and the card says so.

Legend: ``M`` points of a trajectory, ``n`` points of a root path, ``W`` places.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.errors import DataError
from emotive.synth.recipe import SynthError
from emotive.synth.trajectories import Trajectory

#: Data sets whose locomotion clips' root paths are compared.
DATASETS = ("bandai-namco-1", "bandai-namco-2-locomotion")
#: Resampling step along the arc, metres.
STEP = 0.25
#: Seconds of the moving average that removes the steps' sway from a root path.
SMOOTH_SECONDS = 1.0
#: Root paths shorter than this (metres) are left out: walking on the spot has no path.
MIN_DATA_LENGTH = 2.0
#: Mean gap under which two paths have the same shape, metres.
MATCH_DISTANCE = 0.3
#: Least ratio of the shorter path's length to the longer's for them to coincide.
MIN_COVERAGE = 0.8


class NoveltyError(SynthError):
    """A novel trajectory that coincides with a root path of the data."""


@dataclass(frozen=True)
class PathCheck:
    """One trajectory against the data.

    Attributes:
        path_id: trajectory index.
        nearest_clip: the clip whose root path fits it best.
        distance_m: mean gap of that best fit, metres.
        coverage: length of the shorter of the two over the longer's.
        coincides: whether the two coincide (module docstring).
    """

    path_id: int
    nearest_clip: str
    distance_m: float
    coverage: float
    coincides: bool


@dataclass(frozen=True)
class NoveltyReport:
    """The check of every trajectory, or why it was skipped.

    Attributes:
        checked: whether the data was there and the check ran.
        reason: why it was skipped (empty when it ran).
        clips: root paths compared.
        paths: one :class:`PathCheck` per trajectory.
    """

    checked: bool
    reason: str
    clips: int
    paths: tuple[PathCheck, ...]

    def to_dict(self) -> dict:
        """JSON-able form, with the thresholds."""
        return {"checked": self.checked, "reason": self.reason, "clips": self.clips,
                "datasets": list(DATASETS), "match_distance_m": MATCH_DISTANCE,
                "min_coverage": MIN_COVERAGE, "step_m": STEP,
                "paths": [asdict(p) for p in self.paths]}

    @classmethod
    def from_dict(cls, values: dict) -> NoveltyReport:
        """The report of :meth:`to_dict`'s output."""
        return cls(values["checked"], values["reason"], values["clips"],
                   tuple(PathCheck(**p) for p in values["paths"]))


@functools.cache
def data_root_paths() -> tuple[list[str], list[np.ndarray]] | str:
    """Names and ``(n, 2)`` resampled root paths of the data's locomotion clips (kept).

    Returns:
        The names and paths, or the reason the data cannot be read (a string).
    """
    names, paths = [], []
    for dataset in DATASETS:
        try:
            clips = load_clips(dataset, locomotion=True)
        except DataError as exc:
            return f"the data set {dataset} is not available ({exc})"
        roles: dict[int, int] = {}
        for clip in clips:
            motion = clip.motion
            key = id(motion.skeleton)
            if key not in roles:
                roles[key] = resolve_roles(motion.skeleton).index["root"]
            xz = motion.positions_with_end_sites()[:, roles[key]][:, [0, 2]]
            width = max(1, round(SMOOTH_SECONDS * motion.fps))
            if len(xz) <= width:
                continue
            kernel = np.ones(width) / width
            smooth = np.stack([np.convolve(xz[:, k], kernel, "valid") for k in (0, 1)], 1)
            resampled = resample(smooth)
            if resampled is not None and (len(resampled) - 1) * STEP >= MIN_DATA_LENGTH:
                names.append(clip.name)
                paths.append(resampled)
    return names, paths


def resample(points: np.ndarray) -> np.ndarray | None:
    """``(n, 2)`` points every :data:`STEP` metres along a polyline ``(P, 2)``, or ``None``.

    ``None`` for a polyline shorter than two steps.
    """
    arc = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))))
    if arc[-1] < 2 * STEP:
        return None
    s = np.arange(0.0, arc[-1] + 1e-9, STEP)
    return np.stack((np.interp(s, arc, points[:, 0]), np.interp(s, arc, points[:, 1])), 1)


def best_fits(short: np.ndarray, long: np.ndarray) -> np.ndarray:
    """``(D,)`` least mean gap (metres) of each of ``short`` laid onto any stretch of ``long``.

    Args:
        short: ``(D, n, 2)`` paths of ``n`` points.
        long: ``(M, 2)``, ``M >= n``; each of its stretches of ``n`` points is fitted to each
            path by the best rotation and translation (2D Procrustes).
    """
    n = short.shape[1]
    windows = np.lib.stride_tricks.sliding_window_view(long, (n, 2))[:, 0]     # (W, n, 2)
    a = (short - short.mean(1, keepdims=True))[:, None]                         # (D, 1, n, 2)
    b = (windows - windows.mean(1, keepdims=True))[None]                        # (1, W, n, 2)
    dot = (a * b).sum((2, 3))
    cross = (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]).sum(2)
    angle = np.arctan2(cross, dot)[..., None]                                   # (D, W, 1)
    c, s = np.cos(angle), np.sin(angle)
    turned = np.stack((c * a[..., 0] - s * a[..., 1], s * a[..., 0] + c * a[..., 1]), -1)
    return np.linalg.norm(turned - b, axis=-1).mean(-1).min(1)


def _fits(mine: np.ndarray, data: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(D,)`` best-fit gap and coverage of a trajectory ``(M, 2)`` with each root path."""
    gap, coverage = np.empty(len(data)), np.empty(len(data))
    by_length: dict[int, list[int]] = {}
    for k, other in enumerate(data):
        by_length.setdefault(len(other), []).append(k)
    for n, members in by_length.items():
        coverage[members] = (min(n, len(mine)) - 1) / (max(n, len(mine)) - 1)
        if n <= len(mine):
            gap[members] = best_fits(np.stack([data[k] for k in members]), mine)
        else:
            gap[members] = [best_fits(mine[None], data[k])[0] for k in members]
    return gap, coverage


def check_trajectories(trajectories: Sequence[Trajectory]) -> NoveltyReport:
    """Compare every trajectory with the data's root paths (module docstring).

    For each trajectory the report names the clip that comes closest to coinciding: among
    the clips that fit a stretch within :data:`MATCH_DISTANCE`, the one covering most of the
    longer path; when none fits, the one of the least gap.

    Returns:
        The report; ``checked`` is ``False`` (with the reason) when the data is absent.
    """
    found = data_root_paths()
    if isinstance(found, str):
        return NoveltyReport(False, found, 0, ())
    names, data = found
    checks = []
    for t in trajectories:
        gap, coverage = _fits(resample(t.path.points), data)
        close = gap < MATCH_DISTANCE
        k = int(np.argmax(np.where(close, coverage, -1.0))) if close.any() else int(gap.argmin())
        checks.append(PathCheck(t.index, names[k], round(float(gap[k]), 4),
                                round(float(coverage[k]), 3),
                                bool(close[k] and coverage[k] >= MIN_COVERAGE)))
    return NoveltyReport(True, "", len(names), tuple(checks))


def raise_if_coinciding(report: NoveltyReport) -> None:
    """Raise :class:`NoveltyError` for the first trajectory that coincides with a clip."""
    for check in report.paths:
        if check.coincides:
            raise NoveltyError(
                f"trajectory {check.path_id} follows the data's clip {check.nearest_clip} "
                f"(mean gap {check.distance_m:.2f} m, under {MATCH_DISTANCE} m): it is not "
                "novel; give another --seed or longer --seconds")
