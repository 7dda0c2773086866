"""Building the MAR database: registering, annotating and indexing labelled examples.

Paper section 4; the layout of the result is :mod:`emotive.models.mar.database`'s. Each group
(one action of one data set) is registered onto its reference example: by gait cycles for
walks (:class:`~emotive.models.mar.registration.GaitCycle`), by dynamic time warping of the
whole clip otherwise; each class's track is then its mean cycle or its representative example.

Legend: ``N`` frames, ``D`` pose dimensions, ``P`` points, ``C`` classes, ``G`` groups,
``L`` track rows (the reference lengths of all classes' groups), ``d`` reduced dimensions.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence

import numpy as np
from rich.console import Console
from rich.progress import track

from emotive.core.ops import resample
from emotive.core.roles import resolve_roles
from emotive.data.emotion import style_to_label
from emotive.features.contacts import foot_contacts
from emotive.models.mar.config import MARConfig, TransferError
from emotive.models.mar.database import (
    ARRAYS,
    Example,
    MARDatabase,
    canonical_windows,
    point_weights,
)
from emotive.models.mar.registration import (
    RATE_BOUNDS,
    GaitCycle,
    body_features,
    frame_at,
    register,
    strike_events,
    time_rate,
    unwrapped_rate,
)
from emotive.models.mar.representation import (
    RigCodec,
    heading_of_points,
    rebase,
    reference_rotations,
    slot_quaternions,
)

__all__ = ["FRAGMENT", "MIN_STD", "OUTSIDE_STRIKES", "REST_FRAMES", "build_database"]

#: Frames of the reference clip kept for retargeting.
REST_FRAMES = 120
#: Examples shorter than this share of their group's median length are left out (fragments).
FRAGMENT = 0.4
#: Stored pose dimensions whose spread is below this are standardized with unit scale.
MIN_STD = 1e-3


def _pick_reference(members: list[int], examples: Sequence[Example]) -> int:
    """The group's reference example.

    The group's longest neutral example; when that is a fragment (under half the group's
    median length) or missing, the example nearest the median length, neutral first.
    """
    lengths = {i: examples[i].motion.num_frames for i in members}
    median = float(np.median(list(lengths.values())))
    neutral = [i for i in members if examples[i].style == "neutral"]
    if neutral:
        best = max(neutral, key=lambda i: (lengths[i], -i))
        if lengths[best] >= 0.5 * median:
            return best
    return min(members, key=lambda i: (abs(lengths[i] - median),
                                       examples[i].style != "neutral", i))


def _select_examples(examples: Sequence[Example], config: MARConfig) -> list[int]:
    """Indices of the examples to index, class by class (see :func:`build_database`).

    Args:
        examples: the labelled clips.
        config: settings (``min_styles``, ``max_takes``).

    Raises:
        TransferError: nothing left to index.
    """
    by_class: dict[tuple[str, str, str], list[int]] = defaultdict(list)
    for i, ex in enumerate(examples):
        by_class[(ex.dataset, ex.action, style_to_label(ex.style))].append(i)
    styles_of: dict[tuple[str, str], set[str]] = defaultdict(set)
    for d, a, s in by_class:
        styles_of[(d, a)].add(s)
    lengths: dict[tuple[str, str], list[int]] = defaultdict(list)
    for (d, a, _), members in by_class.items():
        lengths[(d, a)] += [examples[i].motion.num_frames for i in members]
    kept: list[int] = []
    for key, members in sorted(by_class.items()):
        if len(styles_of[key[:2]]) < config.min_styles:
            continue
        # Fragments cannot be warped onto a whole take; they would distort the timeline.
        floor = FRAGMENT * float(np.median(lengths[key[:2]]))
        whole = [i for i in members if examples[i].motion.num_frames >= floor]
        kept += sorted(whole, key=lambda i: examples[i].name)[:config.max_takes]
    if not kept:
        raise TransferError("no action with at least two styles to index; give more examples")
    return kept


def build_database(
    examples: Sequence[Example], config: MARConfig | None = None, progress: bool = False,
) -> MARDatabase:
    """Register, annotate and index labelled examples.

    Groups (data set, action) recorded in fewer than ``config.min_styles`` styles are left out;
    each group's reference is its longest neutral example (see :func:`_pick_reference` for
    fragments). Examples shorter than :data:`FRAGMENT` times their group's median length are
    left out, and at most ``config.max_takes`` examples per class are kept.

    Args:
        examples: the labelled clips.
        config: settings (defaults when None).
        progress: show a progress bar on stderr.

    Raises:
        TransferError: nothing left to index, or an example shorter than two frames.
    """
    config = config or MARConfig()
    examples = [examples[i] for i in _select_examples(examples, config)]
    examples = [Example(e.motion if e.motion.fps == config.fps else resample(e.motion, config.fps),
                        e.dataset, e.action, style_to_label(e.style), e.name) for e in examples]

    encoded = []
    console = Console(stderr=True)
    for ex in track(examples, description="MAR index: encoding clips", disable=not progress,
                    console=console, transient=True):
        if ex.motion.num_frames < 2:
            raise TransferError(f"{ex.name}: an example needs at least 2 frames")
        codec = RigCodec.for_motion(ex.motion, name=ex.name)
        vectors, points = codec.encode_motion(ex.motion)
        roles = resolve_roles(ex.motion.skeleton)
        contacts = foot_contacts(ex.motion.positions_with_end_sites(), roles, ex.motion.fps)
        slot = codec.role_slots
        yaws = heading_of_points(points, (slot["l_hip"], slot["r_hip"]),
                                 (slot["l_shoulder"], slot["r_shoulder"]))
        encoded.append((vectors, points, contacts, yaws, body_features(points, yaws)))
    # Exponential maps relative to each slot's mean rotation (see the representation module).
    reference = reference_rotations([slot_quaternions(e[0]) for e in encoded])
    encoded = [(rebase(e[0], reference), *e[1:]) for e in encoded]

    groups = sorted({f"{e.dataset}/{e.action}" for e in examples})
    members: dict[str, list[int]] = defaultdict(list)
    for i, e in enumerate(examples):
        members[f"{e.dataset}/{e.action}"].append(i)
    taus: list[np.ndarray] = [np.zeros(0)] * len(examples)
    rates: list[np.ndarray] = [np.zeros(0)] * len(examples)
    costs = np.zeros(len(examples))
    refs: dict[str, int] = {}
    cycles: dict[str, GaitCycle | None] = {}
    for g in track(groups, description="MAR index: registering", disable=not progress,
                   console=console, transient=True):
        ref = _pick_reference(members[g], examples)
        refs[g] = ref
        cycles[g] = _gait_cycle(members[g], ref, encoded)
        for i in members[g]:
            unwrapped = cycles[g].unwrapped(encoded[i][2]) if cycles[g] else None
            if unwrapped is not None:
                taus[i], rates[i] = cycles[g].wrap(unwrapped), unwrapped_rate(unwrapped)
            elif i == ref:
                taus[i] = np.arange(examples[i].motion.num_frames, dtype=np.float64)
                rates[i] = time_rate(taus[i])
            else:
                taus[i], costs[i] = register(encoded[i][4], encoded[ref][4])
                rates[i] = time_rate(taus[i])

    class_keys = sorted({(groups.index(f"{e.dataset}/{e.action}"), e.style) for e in examples})
    class_index = {k: c for c, k in enumerate(class_keys)}
    track_pose, track_rate, track_contacts, track_start = [], [], [], [0]
    for g_index, style in class_keys:
        g = groups[g_index]
        cands = [i for i in members[g] if examples[i].style == style]
        if cycles[g] is not None:
            pose, per, contact = _cycle_track(cands, cycles[g], encoded, taus, rates)
        else:
            rep = refs[g] if refs[g] in cands else min(cands, key=lambda i: (costs[i], i))
            length = examples[refs[g]].motion.num_frames
            frames = frame_at(taus[rep], np.arange(length, dtype=np.float64))
            pose = _interp_rows(encoded[rep][0], frames)
            per = _frames_per_canonical(frames)
            contact = _interp_rows(encoded[rep][2].astype(np.float64), frames)
        track_pose.append(pose)
        track_rate.append(per)
        track_contacts.append(contact)
        track_start.append(track_start[-1] + len(pose))

    vectors = np.concatenate([e[0] for e in encoded])
    points = np.concatenate([e[1] for e in encoded])
    lengths = np.array([len(e[0]) for e in encoded])
    clip_start = np.concatenate(([0], np.cumsum(lengths)))
    prev = np.arange(len(vectors)) - 1
    prev[clip_start[:-1]] = clip_start[:-1]
    frame_class = np.concatenate([
        np.full(len(encoded[i][0]),
                class_index[(groups.index(f"{e.dataset}/{e.action}"), e.style)])
        for i, e in enumerate(examples)
    ])
    tau = np.concatenate(taus)
    rate = np.concatenate(rates)
    contacts = np.concatenate([e[2] for e in encoded])
    yaws = np.concatenate([e[3] for e in encoded])
    mean = vectors.mean(0)
    std = vectors.std(0)
    std = np.where(std < MIN_STD, 1.0, std)

    db_config = config
    partial = MARDatabase(
        config=db_config, vectors=vectors.astype(np.float32), points=points.astype(np.float32),
        prev=prev, frame_class=frame_class.astype(np.int64), tau=tau, rate=rate,
        contacts=contacts, features=np.zeros((len(vectors), 0), np.float32),
        pca_mean=np.zeros(0), pca_basis=np.zeros((0, 0)), mean=mean, std=std,
        groups=tuple(groups), class_group=np.array([k[0] for k in class_keys]),
        class_style=tuple(k[1] for k in class_keys),
        track_start=np.array(track_start), track_pose=np.concatenate(track_pose),
        track_rate=np.concatenate(track_rate), track_contacts=np.concatenate(track_contacts),
        clip_names=tuple(e.name for e in examples), clip_start=clip_start,
        skeleton=examples[refs[groups[0]]].motion.skeleton,
        rest=examples[refs[groups[0]]].motion.rotations[:REST_FRAMES].copy(),
        rest_positions=examples[refs[groups[0]]].motion.positions[:REST_FRAMES].copy(),
        reference=reference,
    )
    features, pca_mean, basis = _reduce_windows(partial, yaws)
    return MARDatabase(**{**{k: getattr(partial, k) for k in _FIELDS},
                          "features": features, "pca_mean": pca_mean, "pca_basis": basis})


_FIELDS = (*ARRAYS, "config", "groups", "class_style", "clip_names", "skeleton")


#: Weight, in a cycle track, of frames before a clip's first or after its last foot strike
#: (starting and stopping rather than walking).
OUTSIDE_STRIKES = 0.05


def _gait_cycle(members: list[int], ref: int, encoded: list) -> GaitCycle | None:
    """The group's canonical gait cycle, or None for actions that are not gaits.

    The group's canonical gait cycle (from its reference's contacts) when every member
    has at least two foot strikes; None for actions that are not gaits (their examples are
    warped onto the whole reference instead).

    Turning walks are registered by cycles too, so their class track is a mean step that
    holds the average turn (warping whole turning takes of different step counts onto each
    other was tried and gave worse pose and timing errors).
    """
    cycle = GaitCycle.of(encoded[ref][2])
    if cycle is None:
        return None
    if any(len(strike_events(encoded[i][2])[0]) < 2 for i in members):
        return None
    return cycle


def _cycle_track(cands: list[int], cycle: GaitCycle, encoded: list, taus: list[np.ndarray],
                 rates: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean cycle of a class's examples on the canonical cycle.

    Pose vectors ``(L + 1, D)``, example frames per canonical frame ``(L + 1,)`` and contacts ``(L +
    1, 2)``, ``L`` the cycle length (the last row repeats the first, so that linear interpolation at
    any canonical time in ``[0, L)`` needs no wrap).

    The track is the mean of the examples' own mean cycles, every example (take) weighing
    the same. Within an example, every frame is splatted linearly onto the two canonical
    frames around its canonical time; frames outside the clip's foot strikes weigh
    :data:`OUTSIDE_STRIKES`. Pooling the frames of all examples instead weighed each take by
    its frames per canonical frame times its cycles, so the style's pose and timing leaned
    towards its slowest takes: of dataset 1's two angry walks (2.5 and 1.7 steps per second,
    arm swing ranges 1.58 and 0.47 database spreads) the pooled track kept a range of 0.76
    (0.90 now).
    """
    length = round(cycle.length)
    dim = encoded[cands[0]][0].shape[1]
    grid = np.arange(length)
    mean = np.zeros((length, dim + 3))
    for i in cands:
        vectors, _, contacts = encoded[i][:3]
        frames, _ = strike_events(contacts)
        t = np.arange(len(vectors))
        w = np.where((t >= frames[0]) & (t <= frames[-1]), 1.0, OUTSIDE_STRIKES)
        rows = np.concatenate((vectors, (1.0 / rates[i])[:, None],
                               contacts.astype(np.float64)), 1)
        lo = np.floor(taus[i]).astype(np.int64)
        a = taus[i] - lo
        total = np.zeros((length, dim + 3))
        weight = np.zeros(length)
        for shift, share in ((0, 1.0 - a), (1, a)):
            idx = (lo + shift) % length
            np.add.at(total, idx, (w * share)[:, None] * rows)
            np.add.at(weight, idx, w * share)
        filled = weight > 1e-9
        for col in range(total.shape[1]):
            mean[:, col] += np.interp(grid, grid[filled], total[filled, col] / weight[filled],
                                      period=length)
    mean /= len(cands)
    mean = np.concatenate((mean, mean[:1]))
    return mean[:, :dim], mean[:, dim], mean[:, dim + 1:]


def _frames_per_canonical(frames: np.ndarray) -> np.ndarray:
    """``(L,)`` example frames per canonical frame of a track's ``(L,)`` fractional frames."""
    if len(frames) < 2:
        return np.ones(len(frames))
    return np.clip(np.gradient(frames), 1.0 / RATE_BOUNDS[1], 1.0 / RATE_BOUNDS[0])


def _interp_rows(rows: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """``rows`` ``(T, F)`` linearly interpolated at fractional frames ``(L,)``."""
    lo = np.clip(np.floor(frames).astype(np.int64), 0, len(rows) - 1)
    hi = np.minimum(lo + 1, len(rows) - 1)
    a = (frames - lo)[:, None]
    return (1.0 - a) * rows[lo] + a * rows[hi]


def _reduce_windows(db: MARDatabase, yaws: np.ndarray, sample: int = 20000,
                    chunk: int = 8192) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reduced window features ``(N, d)``, their mean and principal axes."""
    idx = db.window_index()
    weights = point_weights(db.config, db.points.shape[1])
    rng = np.random.default_rng(0)
    pick = rng.choice(db.num_frames, size=min(sample, db.num_frames), replace=False)
    full = canonical_windows(db.points[idx[pick]].astype(np.float64), yaws[pick], weights)
    pca_mean = full.mean(0)
    _, _, vt = np.linalg.svd(full - pca_mean, full_matrices=False)
    basis = vt[:db.config.pca_dims].T
    # An axis's sign is arbitrary, and LAPACK's choice differs between BLAS kernels: each axis
    # is turned to make its largest component positive, so the features agree across CPUs.
    top = np.abs(basis).argmax(0)
    basis = basis * np.where(basis[top, np.arange(basis.shape[1])] < 0, -1.0, 1.0)
    out = np.empty((db.num_frames, basis.shape[1]), dtype=np.float32)
    for start in range(0, db.num_frames, chunk):
        part = slice(start, start + chunk)
        win = canonical_windows(db.points[idx[part]].astype(np.float64), yaws[part], weights)
        out[part] = (win - pca_mean) @ basis
    return out, pca_mean, basis
