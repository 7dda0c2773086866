"""The check that the novel trajectories are not the data's root paths, and drawing them so.

The main paper's augmented data set walks trajectories "not present in the dataset"
(Bhattacharya et al. 2020, section 5.2). When the Bandai Namco data is there
(:func:`emotive.data.dataset_dir`), every trajectory is compared with the root path of every
locomotion clip of both data sets, over the trajectory's own length (drawn for the walk's
``--seconds``, :mod:`emotive.synth.trajectories`):

* a root path is the hips' ``(x, z)`` smoothed over one second (the sway of the steps
  removed); both it and the trajectory are resampled every :data:`STEP` metres of arc;
* the shorter of the two slides along the longer, and at each place is laid onto it by the
  rotation and translation that fit it best (2D Procrustes); the gap is the mean distance
  of the points after that fit, the least over places;
* the *relative gap* is that gap over the length compared (the shorter's): a copy of a path
  scaled to any size has the same relative gap, so the threshold means the same shape
  difference for a 3 s walk as for a 10 s one (a straight walk of the data fits any straight
  stretch, so a small gap alone says little);
* the *coverage* is the share of the trajectory's length that the compared stretch spans:
  ``(min(n, M) - 1) / (M - 1)``, 1 when the clip is as long as the trajectory or longer;
* a trajectory *coincides* with a clip when the relative gap is under :data:`MATCH_FRACTION`
  and the coverage at least :data:`MIN_COVERAGE`: most of the trajectory is the clip's path.

Long walks cannot coincide (the data's paths are under 10 m, a 10 s walk's trajectory over
20 m); a short walk's trajectory, 8-9.5 m for 3 s, often does on its first draw.
:func:`novel_trajectories` therefore draws a trajectory that coincides again (draw ``k`` of
trajectory ``p`` from the seed ``[seed, 1, p, k]``), up to :data:`MAX_DRAWS` draws, and
raises :class:`NoveltyError` if none is novel. The draws taken are part of the report
(``novelty.json``), which the workers are given. Without the data nothing is drawn again
(the first draws are kept, unchecked) and the card says the check was skipped; a later run
with the data checks that folder's trajectories without drawing them again.

Legend: ``M`` points of a trajectory, ``n`` points of a root path, ``W`` places, ``D`` paths.
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
from emotive.synth.trajectories import Trajectory, trajectory

#: Data sets whose locomotion clips' root paths are compared.
DATASETS = ("bandai-namco-1", "bandai-namco-2-locomotion")
#: Resampling step along the arc, metres.
STEP = 0.25
#: Seconds of the moving average that removes the steps' sway from a root path.
SMOOTH_SECONDS = 1.0
#: Root paths shorter than this (metres) are left out: walking on the spot has no path.
MIN_DATA_LENGTH = 2.0
#: Relative gap (mean gap over the length compared) under which two paths have the same
#: shape: 0.3 m over the data's longest paths (10 m), 0.15 m over 5 m.
MATCH_FRACTION = 0.03
#: Least share of the trajectory's length a clip must span for the two to coincide.
MIN_COVERAGE = 0.8
#: Draws of one trajectory at most before :func:`novel_trajectories` gives up.
MAX_DRAWS = 50


class NoveltyError(SynthError):
    """A novel trajectory that coincides with a root path of the data."""


@dataclass(frozen=True)
class PathCheck:
    """One trajectory against the data.

    Attributes:
        path_id: trajectory index.
        nearest_clip: the clip that comes closest to coinciding with it.
        distance_m: mean gap of that clip's best fit, metres.
        coverage: share of the trajectory's length the compared stretch spans.
        coincides: whether the two coincide (module docstring).
        relative_gap: ``distance_m`` over the length compared.
        draw: which draw of the trajectory this is (0: the first).
    """

    path_id: int
    nearest_clip: str
    distance_m: float
    coverage: float
    coincides: bool
    relative_gap: float = float("nan")
    draw: int = 0


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
                "datasets": list(DATASETS), "match_fraction": MATCH_FRACTION,
                "min_coverage": MIN_COVERAGE, "max_draws": MAX_DRAWS, "step_m": STEP,
                "paths": [asdict(p) for p in self.paths]}

    def draws(self, count: int) -> tuple[int, ...]:
        """The draw of each of ``count`` trajectories (0 for one the report does not name)."""
        taken = {p.path_id: p.draw for p in self.paths}
        return tuple(taken.get(p, 0) for p in range(count))

    @classmethod
    def from_dict(cls, values: dict) -> NoveltyReport:
        """The report of :meth:`to_dict`'s output."""
        return cls(values["checked"], values["reason"], values["clips"],
                   tuple(PathCheck(**p) for p in values["paths"]))


def same_thresholds(values: dict) -> bool:
    """Whether a stored report (:meth:`NoveltyReport.to_dict`) used this module's thresholds."""
    return all(values.get(key) == value for key, value in (
        ("match_fraction", MATCH_FRACTION), ("min_coverage", MIN_COVERAGE), ("step_m", STEP)))


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


def coverage(n: int, m: int) -> float:
    """Share of a trajectory of ``m`` points that a root path of ``n`` points spans.

    The compared stretch is the shorter of the two, ``min(n, m)`` points, ``min(n, m) - 1``
    steps of the trajectory's ``m - 1``.
    """
    return (min(n, m) - 1) / (m - 1)


def fits(mine: np.ndarray, data: Sequence[np.ndarray]) -> tuple[np.ndarray, ...]:
    """Best fits of a trajectory ``(M, 2)`` with each root path ``(n, 2)`` of ``data``.

    Returns:
        ``(D,)`` gap (metres), ``(D,)`` relative gap and ``(D,)`` coverage (module docstring).
    """
    gap, cover, span = np.empty(len(data)), np.empty(len(data)), np.empty(len(data))
    by_length: dict[int, list[int]] = {}
    for k, other in enumerate(data):
        by_length.setdefault(len(other), []).append(k)
    for n, members in by_length.items():
        cover[members] = coverage(n, len(mine))
        span[members] = (min(n, len(mine)) - 1) * STEP
        if n <= len(mine):
            gap[members] = best_fits(np.stack([data[k] for k in members]), mine)
        else:
            gap[members] = [best_fits(mine[None], data[k])[0] for k in members]
    return gap, gap / span, cover


def check_one(t: Trajectory, names: Sequence[str], data: Sequence[np.ndarray]) -> PathCheck:
    """One trajectory against the root paths ``data`` of the clips ``names``.

    The check names the clip that comes closest to coinciding: among the clips whose
    relative gap is under :data:`MATCH_FRACTION`, the one covering most of the trajectory;
    when none is, the one of the least relative gap.
    """
    gap, relative, cover = fits(resample(t.path.points), data)
    close = relative < MATCH_FRACTION
    k = int(np.argmax(np.where(close, cover, -1.0))) if close.any() else int(relative.argmin())
    return PathCheck(t.index, names[k], round(float(gap[k]), 4), round(float(cover[k]), 3),
                     bool(close[k] and cover[k] >= MIN_COVERAGE),
                     round(float(relative[k]), 4), t.draw)


def check_trajectories(trajectories: Sequence[Trajectory]) -> NoveltyReport:
    """Compare every trajectory with the data's root paths (module docstring).

    Returns:
        The report; ``checked`` is ``False`` (with the reason) when the data is absent.
    """
    found = data_root_paths()
    if isinstance(found, str):
        return NoveltyReport(False, found, 0, ())
    names, data = found
    return NoveltyReport(True, "", len(names), tuple(check_one(t, names, data)
                                                    for t in trajectories))


def novel_trajectories(seed: int, count: int, seconds: float
                       ) -> tuple[list[Trajectory], NoveltyReport]:
    """The ``count`` trajectories of a recipe, each drawn again while it coincides with a clip.

    Args:
        seed: the recipe's seed.
        count: trajectories ``P``.
        seconds: length of the walks, seconds.

    Returns:
        The trajectories and their report (each check names its draw); without the data, the
        first draws and a report that says why the check was skipped.

    Raises:
        NoveltyError: a trajectory whose :data:`MAX_DRAWS` draws all coincide with the data.
    """
    found = data_root_paths()
    if isinstance(found, str):
        return ([trajectory(seed, p, seconds) for p in range(count)],
                NoveltyReport(False, found, 0, ()))
    names, data = found
    paths, checks = [], []
    for p in range(count):
        for draw in range(MAX_DRAWS):
            t = trajectory(seed, p, seconds, draw)
            check = check_one(t, names, data)
            if not check.coincides:
                break
        else:
            raise NoveltyError(
                f"--seconds {seconds:g}: all {MAX_DRAWS} draws of trajectory {p} (seed {seed}) "
                f"follow a clip of the data (the last {check.nearest_clip}); walks this short "
                "are not novel: give longer --seconds")
        paths.append(t)
        checks.append(check)
    return paths, NoveltyReport(True, "", len(names), tuple(checks))


def raise_if_coinciding(report: NoveltyReport) -> None:
    """Raise :class:`NoveltyError` for the first trajectory that coincides with a clip.

    Only a folder made without the data (or checked by an earlier version) can hold one: a
    folder keeps the trajectories it was made with, so the fix is a new folder.
    """
    for check in report.paths:
        if check.coincides:
            raise NoveltyError(
                f"trajectory {check.path_id} follows the data's clip {check.nearest_clip} "
                f"(mean gap {check.relative_gap:.1%} of the length compared, under "
                f"{MATCH_FRACTION:.0%}): it is not novel, and this folder keeps the "
                "trajectories it was made with; give a new --out to draw them again")
