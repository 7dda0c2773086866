"""The MAR database: registered, annotated example frames, saved as one index file.

Paper section 4. Examples are labelled clips; a *group* is one action of one data set (the
examples of one group share a canonical timeline), a *class* is a group and a style. For every
frame the index holds its pose vector and point cloud (:mod:`emotive.models.mar.representation`),
its class, its canonical time and time rate from the registration
(:mod:`emotive.models.mar.registration`) and its foot contacts
(:func:`emotive.features.contacts.foot_contacts`). For every class it holds the *track* on the
canonical timeline: for gaits (registered by cycles) the mean of the class's examples' cycles,
one row per canonical frame plus a closing row; for other actions the class's representative
example (the one warped most cheaply onto the reference); each row holds a pose vector,
frames per canonical frame and contacts. Pairs for the regression come from these: an
example frame of style ``s`` at canonical time ``tau`` corresponds to the track of style
``o`` at ``tau``.

Pose vectors hold exponential maps relative to per-slot reference rotations that the index
stores (:attr:`MARDatabase.reference`; see :mod:`emotive.models.mar.representation`).

The index also stores the reduced window features of the search trees
(:mod:`emotive.models.mar.search`) and the standardization of the pose vectors, so loading it
is reading arrays and building trees: seconds.

Legend: ``N`` frames, ``D`` pose dimensions, ``P`` points, ``C`` classes, ``G`` groups,
``L`` track rows (the reference lengths of all classes' groups), ``d`` reduced dimensions.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import logging
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton, skeleton_from_dict, skeleton_to_dict
from emotive.data.emotion import style_to_label
from emotive.io.atomic import atomic_output
from emotive.models.mar.config import MARConfig, TransferError
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

log = logging.getLogger(__name__)

#: Version of the index layout; part of the default file name.
INDEX_FORMAT = "emotive-mar-index/2"
#: Modules whose source determines the index (part of the default file name).
INDEX_SOURCES = (
    "emotive.models.mar.database", "emotive.models.mar.registration",
    "emotive.models.mar.representation", "emotive.features.contacts",
)
#: Frames of the reference clip kept for retargeting.
REST_FRAMES = 120
#: Examples shorter than this share of their group's median length are left out (fragments).
FRAGMENT = 0.4
#: Stored pose dimensions whose spread is below this are standardized with unit scale.
MIN_STD = 1e-3


@dataclass(frozen=True)
class Example:
    """One labelled clip for the database.

    Attributes:
        motion: the clip (any rig with joint roles).
        dataset: the data set it comes from (examples of one data set share a timeline).
        action: its content (``walk``, ``run``, ...).
        style: its style or emotion label (``neutral``, ``proud``, ...).
        name: a unique name.
    """

    motion: Motion
    dataset: str
    action: str
    style: str
    name: str


@dataclass(frozen=True, eq=False)
class MARDatabase:
    """Arrays of the index (see the module docstring).

    Attributes:
        config: the settings it was built with.
        vectors: ``(N, D)`` pose vectors.
        points: ``(N, P, 3)`` point clouds in leg lengths.
        prev: ``(N,)`` index of the previous frame of the same clip (itself at a clip start).
        frame_class: ``(N,)`` class of each frame.
        tau: ``(N,)`` canonical time.
        rate: ``(N,)`` canonical frames per example frame.
        contacts: ``(N, 2)`` left/right foot contacts.
        features: ``(N, d)`` reduced window features.
        pca_mean: ``(s * P * 3,)`` mean of the full window features.
        pca_basis: ``(s * P * 3, d)`` principal axes.
        mean: ``(D,)`` mean of the pose vectors.
        std: ``(D,)`` their standard deviation (``1`` for near-constant dimensions).
        groups: ``G`` names ``"dataset/action"``.
        class_group: ``(C,)`` group of each class.
        class_style: ``C`` style labels.
        track_start: ``(C + 1,)`` first track row of each class.
        track_pose: ``(L, D)`` pose vectors of the tracks.
        track_rate: ``(L,)`` example frames per canonical frame.
        track_contacts: ``(L, 2)`` contact of each foot (0..1).
        clip_names: names of the clips.
        clip_start: ``(n + 1,)`` first frame of each clip.
        skeleton: rig of the reference of the first group (the default output rig).
        rest: ``(R, J, 4)`` local rotations of a short clip on that rig (the reference of the
            first group), which calibrates the IK chains of retargeting.
        rest_positions: ``(R, J, 3)`` its local translations.
        reference: ``(S, 4)`` reference rotation of each exponential-map slot of the pose
            vectors (:meth:`RigCodec.with_reference`); every codec that encodes input for
            this database or decodes its output must use it (:meth:`codec`).
    """

    config: MARConfig
    vectors: np.ndarray
    points: np.ndarray
    prev: np.ndarray
    frame_class: np.ndarray
    tau: np.ndarray
    rate: np.ndarray
    contacts: np.ndarray
    features: np.ndarray
    pca_mean: np.ndarray
    pca_basis: np.ndarray
    mean: np.ndarray
    std: np.ndarray
    groups: tuple[str, ...]
    class_group: np.ndarray
    class_style: tuple[str, ...]
    track_start: np.ndarray
    track_pose: np.ndarray
    track_rate: np.ndarray
    track_contacts: np.ndarray
    clip_names: tuple[str, ...]
    clip_start: np.ndarray
    skeleton: Skeleton
    rest: np.ndarray
    rest_positions: np.ndarray
    reference: np.ndarray
    _windows: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    def codec(self, codec: RigCodec) -> RigCodec:
        """``codec`` with this database's reference rotations."""
        return codec.with_reference(self.reference)

    @property
    def num_frames(self) -> int:
        """``N``."""
        return len(self.vectors)

    @property
    def num_classes(self) -> int:
        """``C``."""
        return len(self.class_style)

    def rest_motion(self) -> Motion:
        """The stored reference clip on :attr:`skeleton`, at the database frame rate."""
        return Motion(self.skeleton, self.rest, self.rest_positions, self.config.fps,
                      {"name": "mar-reference", "file_unit": "cm"})

    @property
    def styles(self) -> tuple[str, ...]:
        """Every style label, sorted."""
        return tuple(sorted(set(self.class_style)))

    @property
    def actions(self) -> tuple[str, ...]:
        """Every action, sorted."""
        return tuple(sorted({g.split("/", 1)[1] for g in self.groups}))

    def class_action(self, c: int) -> str:
        """The action of class ``c``."""
        return self.groups[self.class_group[c]].split("/", 1)[1]

    def window_index(self) -> np.ndarray:
        """``(N, s)`` frame indices of each frame's window, oldest first (repeating a clip's
        first frame before its start)."""
        if "index" not in self._windows:
            s = self.config.window
            idx = np.empty((self.num_frames, s), dtype=np.int64)
            idx[:, -1] = np.arange(self.num_frames)
            for k in range(s - 2, -1, -1):
                idx[:, k] = self.prev[idx[:, k + 1]]
            self._windows["index"] = idx
        return self._windows["index"]

    def classes_where(self, action: str | None = None, style: str | None = None) -> np.ndarray:
        """Indices of the classes of an action and/or an input style (all when both None).

        Raises:
            TransferError: no class has that action or style; the message lists the known ones.
        """
        if action is not None and action not in self.actions:
            raise TransferError(f"unknown action {action!r} for --action; the index knows: "
                                f"{', '.join(self.actions)}")
        if style is not None and style not in self.styles:
            raise TransferError(f"unknown input style {style!r} for --input-style; the index "
                                f"knows: {', '.join(self.styles)}")
        keep = [c for c in range(self.num_classes)
                if (action is None or self.class_action(c) == action)
                and (style is None or self.class_style[c] == style)]
        if not keep:
            raise TransferError(f"the index has no examples of action {action!r} in style "
                                f"{style!r}; drop one of --action/--input-style")
        return np.array(keep, dtype=np.int64)

    def track_of(self, c: int, style: str) -> int | None:
        """The class of ``c``'s group in ``style`` (whose track gives the output), or None."""
        g = self.class_group[c]
        for k in range(self.num_classes):
            if self.class_group[k] == g and self.class_style[k] == style:
                return k
        return None

    def output_classes(self) -> np.ndarray:
        """``(C, S)`` class holding the track of each class's group in each of
        :attr:`styles` (``-1`` where the group lacks the style)."""
        if "output" not in self._windows:
            styles = self.styles
            lookup = {(int(g), s): k for k, (g, s) in
                      enumerate(zip(self.class_group, self.class_style, strict=True))}
            table = np.full((self.num_classes, len(styles)), -1, dtype=np.int64)
            for c in range(self.num_classes):
                for i, s in enumerate(styles):
                    table[c, i] = lookup.get((int(self.class_group[c]), s), -1)
            self._windows["output"] = table
        return self._windows["output"]

    def standard_tracks(self) -> np.ndarray:
        """``(L, D)`` :attr:`track_pose` standardized with :attr:`mean` and :attr:`std`
        (cached)."""
        if "standard_tracks" not in self._windows:
            self._windows["standard_tracks"] = (self.track_pose - self.mean) / self.std
        return self._windows["standard_tracks"]

    # ------------------------------------------------------------------ saving and loading

    def save(self, path: str | Path) -> Path:
        """Write the index to one uncompressed ``.npz`` file atomically."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {
            "format": INDEX_FORMAT, "config": self.config.to_dict(), "groups": self.groups,
            "class_style": self.class_style, "clip_names": self.clip_names,
            "skeleton": skeleton_to_dict(self.skeleton),
        }
        arrays = {name: getattr(self, name) for name in _ARRAYS}
        with atomic_output(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> MARDatabase:
        """Read an index written by :meth:`save`.

        Raises:
            TransferError: missing, corrupt or of another format; the message says how to
                rebuild it.
        """
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                if meta.get("format") != INDEX_FORMAT:
                    raise KeyError("format")
                arrays = {name: data[name] for name in _ARRAYS}
        except FileNotFoundError:
            raise TransferError(f"MAR index {path} does not exist; build it with "
                                "`emotive transfer --build-index`") from None
        except Exception as exc:  # numpy raises many types on a damaged file
            raise TransferError(f"MAR index {path} cannot be read ({exc}); rebuild it with "
                                "`emotive transfer --build-index --force`") from None
        return cls(
            config=MARConfig.from_dict(meta["config"]), groups=tuple(meta["groups"]),
            class_style=tuple(meta["class_style"]), clip_names=tuple(meta["clip_names"]),
            skeleton=skeleton_from_dict(meta["skeleton"]), **arrays,
        )


_ARRAYS = (
    "vectors", "points", "prev", "frame_class", "tau", "rate", "contacts", "features",
    "pca_mean", "pca_basis", "mean", "std", "class_group", "track_start", "track_pose",
    "track_rate", "track_contacts", "clip_start", "rest", "rest_positions", "reference",
)


# ---------------------------------------------------------------------- window features


def window_weights(config: MARConfig) -> np.ndarray:
    """``(s, 1)`` weight of each window frame: linear from ``taper`` (oldest) to 1 (newest),
    normalized so that all ``s * P`` point weights sum to one per point."""
    s = config.window
    w = np.linspace(config.taper, 1.0, s) if s > 1 else np.ones(1)
    return (w / w.sum())[:, None]


def canonical_windows(windows: np.ndarray, yaws: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``(M, s * P * 3)`` windows centred on their weighted ground centroid, turned so the
    newest frame faces +Z and scaled by the square root of the weights.

    Euclidean distances of these are the point-cloud distance for one particular rigid
    transform, which makes them a close stand-in for it in the search trees.

    Args:
        windows: ``(M, s, P, 3)`` point clouds.
        yaws: ``(M,)`` heading of each window's newest frame.
        weights: ``(s, P)`` point weights summing to one.
    """
    w = weights[None, ..., None]
    centre = (windows * w).sum((1, 2), keepdims=True) / w.sum((1, 2), keepdims=True)
    centre[..., 1] = 0.0
    rel = windows - centre
    c, s = np.cos(yaws)[:, None, None], np.sin(yaws)[:, None, None]
    x, z = rel[..., 0], rel[..., 2]
    turned = np.stack((c * x - s * z, rel[..., 1], s * x + c * z), -1)
    return (turned * np.sqrt(w)).reshape(len(windows), -1)


def point_weights(config: MARConfig, num_points: int) -> np.ndarray:
    """``(s, P)`` weights of the pose search: every role alike, tapered over the window."""
    return np.broadcast_to(window_weights(config), (config.window, num_points)) / num_points


# ---------------------------------------------------------------------- building


def _pick_reference(members: list[int], examples: Sequence[Example]) -> int:
    """The group's longest neutral example; when that is a fragment (under half the group's
    median length) or missing, the example nearest the median length, neutral first."""
    lengths = {i: examples[i].motion.num_frames for i in members}
    median = float(np.median(list(lengths.values())))
    neutral = [i for i in members if examples[i].style == "neutral"]
    if neutral:
        best = max(neutral, key=lambda i: (lengths[i], -i))
        if lengths[best] >= 0.5 * median:
            return best
    return min(members, key=lambda i: (abs(lengths[i] - median),
                                       examples[i].style != "neutral", i))


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
    from rich.console import Console
    from rich.progress import track

    from emotive.core.ops import resample
    from emotive.core.roles import resolve_roles
    from emotive.features.contacts import foot_contacts

    config = config or MARConfig()
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
    examples = [examples[i] for i in kept]
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


_FIELDS = (*_ARRAYS, "config", "groups", "class_style", "clip_names", "skeleton")


#: Weight, in a cycle track, of frames before a clip's first or after its last foot strike
#: (starting and stopping rather than walking).
OUTSIDE_STRIKES = 0.05


def _gait_cycle(members: list[int], ref: int, encoded: list) -> GaitCycle | None:
    """The group's canonical gait cycle (from its reference's contacts) when every member
    has at least two foot strikes; None for actions that are not gaits (their examples are
    warped onto the whole reference instead).

    Turning walks are registered by cycles too, so their class track is a mean step that
    holds the average turn (warping whole turning takes of different step counts onto each
    other was tried and gave worse pose and timing errors)."""
    cycle = GaitCycle.of(encoded[ref][2])
    if cycle is None:
        return None
    if any(len(strike_events(encoded[i][2])[0]) < 2 for i in members):
        return None
    return cycle


def _cycle_track(cands: list[int], cycle: GaitCycle, encoded: list, taus: list[np.ndarray],
                 rates: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mean cycle of a class's examples on the canonical cycle: pose vectors
    ``(L + 1, D)``, example frames per canonical frame ``(L + 1,)`` and contacts
    ``(L + 1, 2)``, ``L`` the cycle length (the last row repeats the first, so that linear
    interpolation at any canonical time in ``[0, L)`` needs no wrap).

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
    out = np.empty((db.num_frames, basis.shape[1]), dtype=np.float32)
    for start in range(0, db.num_frames, chunk):
        part = slice(start, start + chunk)
        win = canonical_windows(db.points[idx[part]].astype(np.float64), yaws[part], weights)
        out[part] = (win - pca_mean) @ basis
    return out, pca_mean, basis


# ---------------------------------------------------------------------- the default index


def clip_examples(config: MARConfig, exclude: Sequence[str] = ()) -> list[Example]:
    """The labelled clips of the config's data sets and actions (minus ``exclude``)."""
    from emotive.data.clips import load_clips
    from emotive.data.registry import get_dataset

    out = []
    for name in config.datasets:
        info = get_dataset(name)
        wanted = [a for a in config.actions if a in info.contents]
        if not wanted:
            continue
        for clip in load_clips(name, contents=wanted, progress=True):
            if clip.name in exclude:
                continue
            out.append(Example(clip.motion, name, clip.content, clip.info.emotion, clip.name))
    return out


def index_key(config: MARConfig) -> str:
    """Short hash naming the default index of a config, the data sets' archives and the source
    of the modules that compute the index (:data:`INDEX_SOURCES`)."""
    from emotive.data.registry import get_dataset

    digest = hashlib.sha256()
    for module in INDEX_SOURCES:
        digest.update(Path(importlib.import_module(module).__file__ or "").read_bytes())
    payload: dict[str, Any] = {
        "format": INDEX_FORMAT, "config": config.to_dict(), "code": digest.hexdigest(),
        "archives": [get_dataset(d).sha256 for d in config.datasets],
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:16]


def default_index_path(config: MARConfig | None = None) -> Path:
    """``$EMOTIVE_HOME/mar/index-<key>.npz``."""
    from emotive.data.store import emotive_home

    return emotive_home() / "mar" / f"index-{index_key(config or MARConfig())}.npz"


def build_default_index(config: MARConfig | None = None, path: str | Path | None = None,
                        progress: bool = True) -> Path:
    """Build the index of the config's data sets and write it (default location if None)."""
    config = config or MARConfig()
    path = Path(path) if path is not None else default_index_path(config)
    db = build_database(clip_examples(config), config, progress=progress)
    return db.save(path)


def load_default_index(config: MARConfig | None = None, progress: bool = True) -> MARDatabase:
    """The default index, built on first use (with a progress bar)."""
    path = default_index_path(config)
    if not path.is_file():
        log.info("building the MAR index %s (once)", path)
        build_default_index(config, path, progress)
    return MARDatabase.load(path)
