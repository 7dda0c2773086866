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
is reading arrays and building trees: seconds. :mod:`emotive.models.mar.build` builds it;
:mod:`emotive.models.mar.default_index` keeps the index of the default data sets.

Legend: ``N`` frames, ``D`` pose dimensions, ``P`` points, ``C`` classes, ``G`` groups,
``L`` track rows (the reference lengths of all classes' groups), ``d`` reduced dimensions.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton, skeleton_from_dict, skeleton_to_dict
from emotive.io.atomic import atomic_output
from emotive.models.mar.config import MARConfig, TransferError
from emotive.models.mar.representation import RigCodec

#: Version of the index layout; part of the default file name.
INDEX_FORMAT = "emotive-mar-index/2"


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
        """``(N, s)`` frame indices of each frame's window, oldest first.

        ``(N, s)`` frame indices of each frame's window, oldest first (repeating a clip's
        first frame before its start).
        """
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
        """``(C, S)`` track of each class's group in each of :attr:`styles`.

        ``(C, S)`` class holding the track of each class's group in each of
        :attr:`styles` (``-1`` where the group lacks the style).
        """
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
        """``(L, D)`` :attr:`track_pose` standardized with :attr:`mean` and :attr:`std` (cached)."""
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
        arrays = {name: getattr(self, name) for name in ARRAYS}
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
                arrays = {name: data[name] for name in ARRAYS}
            skeleton = skeleton_from_dict(meta["skeleton"])
        except FileNotFoundError:
            raise TransferError(f"MAR index {path} does not exist; build it with "
                                "`emotive transfer --build-index`") from None
        except Exception as exc:  # numpy raises many types on a damaged file
            raise TransferError(f"MAR index {path} cannot be read ({exc}); rebuild it with "
                                "`emotive transfer --build-index --force`") from None
        return cls(
            config=MARConfig.from_dict(meta["config"]), groups=tuple(meta["groups"]),
            class_style=tuple(meta["class_style"]), clip_names=tuple(meta["clip_names"]),
            skeleton=skeleton, **arrays,
        )


#: Array fields of :class:`MARDatabase`, as saved in the index file.
ARRAYS = (
    "vectors", "points", "prev", "frame_class", "tau", "rate", "contacts", "features",
    "pca_mean", "pca_basis", "mean", "std", "class_group", "track_start", "track_pose",
    "track_rate", "track_contacts", "clip_start", "rest", "rest_positions", "reference",
)


# ---------------------------------------------------------------------- window features


def window_weights(config: MARConfig) -> np.ndarray:
    """``(s, 1)`` weight of each window frame.

    Linear from ``taper`` (oldest) to 1 (newest), normalized so that all ``s * P`` point weights sum
    to one per point.
    """
    s = config.window
    w = np.linspace(config.taper, 1.0, s) if s > 1 else np.ones(1)
    return (w / w.sum())[:, None]


def canonical_windows(windows: np.ndarray, yaws: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``(M, s * P * 3)`` windows, normalized and weighted.

    ``(M, s * P * 3)`` windows centred on their weighted ground centroid, turned so the
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
