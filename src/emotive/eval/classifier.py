"""The perceived-emotion classifier: an automatic stand-in for human observers.

A small temporal convolution network reads a window of per-frame motion features and gives
probabilities over emotion labels. It is trained on real motion only (the train split of the
Bandai Namco data), never on generated motion, so it can judge any generator.

Per-frame features (:func:`frame_features`, ``F`` = 152 columns), computed from the world
positions in metres of the 21 joint roles (:data:`emotive.core.roles.ROLES`), so any rig with a
role map works. Every role is read at a joint, never at an end site (:func:`judge_joints`: hand
tips at the wrists, toes at the toe joint below the ankle), so the same joint motion gives the
same features on rigs that differ in names, units, rotation orders, rest poses, end-site lengths
and extra helper bones:

* the pose in the body frame: role positions minus the root's ground position, turned so the
  body faces +Z, divided by the leg length (63);
* the velocity in the body frame, in leg lengths per second (63);
* the 18 pose affective features;
* 8 movement features: root height deviation and root speed and its low-passed version (leg
  lengths, leg lengths per second), orientation difference, curvature (leg lengths per second
  squared), sine and cosine of the stepping phase and the step frequency (steps per second).

Everything is resampled to :attr:`ClassifierConfig.fps` and standardized with the training
set's mean and standard deviation, saved with the weights.

Two networks (:mod:`emotive.eval.classifier_nets`), picked by
:attr:`ClassifierConfig.architecture`; both read ``(B, T, F)`` standardized features and
give ``(B, C)`` logits:

* ``"tcn"`` (:class:`EmotionClassifierNet`): a 1D convolution of width 5 to ``channels``, then
  ``blocks`` residual dilated convolutions (dilation 2, 4, ...), ELU, mean over time, a linear
  layer to the labels.
* ``"stgcn"`` (:class:`EmotionGraphNet`): a spatial-temporal graph convolution network in the
  spirit of STEP (Bhattacharya et al. 2020) and ST-GCN (Yan et al. 2018). Each of the 21
  roles is a graph node carrying its body-frame position and velocity (6 channels); the graph
  is the role skeleton (:mod:`emotive.eval.classifier_nets`). ``graph_blocks`` blocks
  each mix channels per joint, average over graph neighbours, convolve along time and add a
  residual; the result is averaged over time and joints. The affective and movement features
  pass through a small temporal branch, are averaged over time and joined to the graph
  summary before the linear layer, as STEP joins its affective features.

Both nets expose their pooled window embedding (``embed``, ``(B, E)``) and three heads on it:
``out``, the label logits; ``aux``, two valence/arousal values (tanh, the -1..1 circumplex of
:data:`emotive.data.circumplex.VALENCE_AROUSAL`) then logits over the styles both Bandai data
sets share (:attr:`ClassifierConfig.style_labels`, see :data:`SHARED_STYLE_OF`). The auxiliary
head lets the clips of every style teach the embedding, not only the labelled ones.

Calibration and "unsure" (:class:`EmotionClassifier`): label logits are divided by a
temperature fitted on the validation split; a window is *unsure* when the Mahalanobis distance
of its embedding from the training windows' embeddings is beyond their
:attr:`ClassifierConfig.unsure_quantile` quantile (the 99th percentile): a motion unlike
anything the classifier was trained on. :meth:`EmotionClassifier.judge` returns both.

Any window at least :attr:`ClassifierConfig.min_seconds` (0.8 s, about one stride) long can be
classified.

Legend: ``T`` frames, ``J`` joint roles, ``F`` features, ``B`` windows, ``C`` labels, ``E``
embedding width, ``S`` shared styles, ``K`` judged windows.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from emotive.core.motion import Motion
from emotive.core.roles import ROLES, JointRoles, resolve_roles
from emotive.core.skeleton import Skeleton
from emotive.data.emotion import DEFAULT_LABELS, check_labels
from emotive.errors import ConfigError, EmotiveError
from emotive.eval.classifier_augment import AugmentConfig
from emotive.eval.classifier_nets import ARCHITECTURES, NUM_FEATURES, build_net
from emotive.features.affective import affective_features_np, role_indices
from emotive.features.contacts import foot_contacts, leg_length
from emotive.features.movement import facing_directions, movement_features
from emotive.io.atomic import atomic_output
from emotive.models.checkpoint_checks import (
    FPS_RANGE,
    LOSS_WEIGHT_RANGE,
    SEED_RANGE,
    WEIGHT_LIMIT,
    WIDTH_RANGE,
    Range,
    build_weights,
    check_fields,
    check_tensor,
)
from emotive.models.training import MAX_MAGNITUDE, read_checkpoint, require_keys


class ClassifierError(EmotiveError):
    """A classifier file that cannot be used, motion too short to classify, or a bad config."""


class ClassifierFileError(ClassifierError, ConfigError):
    """A classifier file that is missing, unreadable, or holds a bad entry."""


#: The styles both data sets hold, by each data set's style name (dataset 1 | dataset 2).
SHARED_STYLE_OF: dict[str, str] = {
    "normal": "neutral", "active": "active", "feminine": "feminine",
    "masculinity": "masculine", "masculine": "masculine", "tired": "exhausted",
    "exhausted": "exhausted", "old": "elderly", "elderly": "elderly", "childish": "youthful",
    "youthful": "youthful",
}
#: The shared styles, in the order of the style head.
SHARED_STYLES: tuple[str, ...] = (
    "neutral", "active", "feminine", "masculine", "exhausted", "elderly", "youthful",
)
#: Version written by :meth:`EmotionClassifier.save`.
FILE_FORMAT = "emotive-emotion-classifier/2"
#: Largest magnitude of a network weight: the shipped network's largest is 0.22 (``aux``), so
#: this is 135 times the trained range
#: (:data:`~emotive.models.checkpoint_checks.WEIGHT_LIMIT` explains the choice). The feature
#: statistics (largest 4.05) keep the default bound.
NET_WEIGHT_LIMIT = 30.0
#: The entries of a file of :meth:`EmotionClassifier.save`.
FILE_ENTRIES = ("format", "config", "state", "mean", "std", "metrics", "temperature",
                "embedding_mean", "embedding_precision", "unsure_distance")
#: Plausible values of :class:`ClassifierConfig`'s numeric fields, checked with their types by
#: :func:`~emotive.models.checkpoint_checks.check_fields` (a TOML file's or a checkpoint's).
CONFIG_RANGES: dict[str, Range] = {
    "fps": FPS_RANGE, "min_seconds": Range(0, 60, above=True),
    "max_seconds": Range(0, 600, above=True), "channels": WIDTH_RANGE,
    "graph_channels": WIDTH_RANGE, "affect_channels": WIDTH_RANGE, "blocks": Range(1, 64),
    "graph_blocks": Range(1, 64), "dropout": Range(0, 1), "augment_copies": Range(0, 1000),
    "valence_arousal_weight": LOSS_WEIGHT_RANGE, "style_weight": LOSS_WEIGHT_RANGE,
    "epochs": Range(1, 1_000_000), "steps_per_epoch": Range(1, 1_000_000),
    "batch_size": Range(1, 100_000), "learning_rate": Range(0, 10, above=True),
    "weight_decay": Range(0, 10), "unsure_quantile": Range(0, 1, above=True),
    "seed": SEED_RANGE,
}
#: Plausible values of :class:`~emotive.eval.classifier_augment.AugmentConfig`'s fields.
AUGMENT_RANGES: dict[str, Range] = {
    "height_m": Range(0.3, 3.0), "segment_scale": Range(0, 0.9), "layout_shift": Range(0, 1),
    "fallback_probability": Range(0, 1), "mirror_probability": Range(0, 1),
    "frame_rates": FPS_RANGE,
}


@dataclass(frozen=True)
class ClassifierConfig:
    """Sizes, data and training settings; saved with every checkpoint.

    Attributes:
        labels: the emotion labels it tells apart.
        datasets: registry names of the training data (their locomotion clips).
        fps: frame rate of the features.
        min_seconds, max_seconds: training windows are drawn between these lengths; shorter
            windows are refused.
        style_labels: the shared styles of the auxiliary style head.
        architecture: the network, a key of :data:`ARCHITECTURES` (``"tcn"`` or ``"stgcn"``).
        channels: width of the convolutions (``"tcn"``).
        blocks: residual dilated blocks (``"tcn"``).
        graph_channels: per-joint width of the graph blocks (``"stgcn"``).
        graph_blocks: spatial-temporal graph blocks (``"stgcn"``).
        affect_channels: width of the affective and movement branch (``"stgcn"``).
        dropout: dropout before the heads.
        valence_arousal_weight: weight of the valence/arousal regression (squared error).
        style_weight: weight of the shared-style cross-entropy.
        augment: ranges of the rig, unit and frame-rate variants
            (:mod:`emotive.eval.classifier_augment`).
        augment_copies: augmented variants of every training clip besides the clip itself.
        epochs: training epochs.
        steps_per_epoch: batches per epoch (windows are drawn afresh for each).
        batch_size: windows per step.
        learning_rate: Adam's step size.
        weight_decay: Adam's L2 penalty.
        unsure_quantile: quantile of the training windows' embedding distances beyond which a
            window is unsure.
        seed: seed of initialization, augmentation, window draws and batching.
    """

    labels: tuple[str, ...] = DEFAULT_LABELS
    datasets: tuple[str, ...] = ("bandai-namco-1", "bandai-namco-2-locomotion")
    fps: float = 15.0
    min_seconds: float = 0.8
    max_seconds: float = 4.0
    style_labels: tuple[str, ...] = SHARED_STYLES
    architecture: str = "tcn"
    channels: int = 48
    blocks: int = 3
    graph_channels: int = 24
    graph_blocks: int = 3
    affect_channels: int = 16
    dropout: float = 0.3
    valence_arousal_weight: float = 1.0
    style_weight: float = 0.5
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    augment_copies: int = 3
    epochs: int = 20
    steps_per_epoch: int = 40
    batch_size: int = 64
    learning_rate: float = 2e-3
    weight_decay: float = 1e-3
    unsure_quantile: float = 0.99
    seed: int = 0

    def __post_init__(self) -> None:
        try:
            check_fields(self)
        except ValueError as exc:
            raise ClassifierError(str(exc)) from None
        object.__setattr__(self, "labels", check_labels(self.labels))
        object.__setattr__(self, "datasets", tuple(self.datasets))
        object.__setattr__(self, "style_labels", tuple(self.style_labels))
        if self.architecture not in ARCHITECTURES:
            raise ClassifierError(f"unknown classifier architecture {self.architecture!r}; "
                                  f"choose one of {sorted(ARCHITECTURES)}")
        if not 0 < self.min_seconds <= self.max_seconds:
            raise ClassifierError(f"min_seconds {self.min_seconds} and max_seconds "
                                  f"{self.max_seconds} must satisfy 0 < min <= max")
        unknown = sorted(set(self.style_labels) - set(SHARED_STYLES))
        if unknown:
            raise ClassifierError(f"style_labels {unknown} are not shared styles; choose from "
                                  f"{list(SHARED_STYLES)}")
        try:
            check_fields(self, CONFIG_RANGES)
            check_fields(self.augment, AUGMENT_RANGES)
        except ValueError as exc:
            raise ClassifierError(str(exc)) from None

    @classmethod
    def from_dict(cls, values: dict) -> ClassifierConfig:
        """The config saved as ``asdict(config)`` (lists back to tuples)."""
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        if isinstance(values.get("augment"), dict):
            values["augment"] = AugmentConfig.from_dict(values["augment"])
        return cls(**values)


#: Role map of a role track: role ``k`` of :data:`ROLES` is point ``k``.
ROLE_POINTS = JointRoles({r: k for k, r in enumerate(ROLES)}, {r: r for r in ROLES}, "roles")


#: Hand tips the classifier reads at their wrist.
HAND_TIPS: dict[str, str] = {"l_handtip": "l_wrist", "r_handtip": "r_wrist"}
#: Toes the classifier reads at the first joint below their ankle.
TOES: dict[str, str] = {"l_toe": "l_ankle", "r_toe": "r_ankle"}


def judge_joints(skeleton: Skeleton, roles: JointRoles) -> np.ndarray:
    """``(21,)`` joint indices the classifier reads for the roles, in :data:`ROLES` order.

    Only joints are read, never end sites, so neither the lengths a rig gives its end sites
    nor its finger, twist and helper bones change what the classifier sees:

    * a hand tip is read at its wrist (rigs end their hands at a wrist end site, a knuckle
      or a finger tip);
    * a toe is read at the toe joint below the ankle on the way to the rig's toe point (the
      ball of the foot: Bandai ``Toes``, Mixamo and CMU ``ToeBase``, Unreal ``ball``, SMPL
      ``foot``), at the ankle when the rig has none;
    * any other role mapped to an end site is read at that end site's joint.

    Args:
        skeleton: the rig (``J`` joints, ``E`` end sites).
        roles: its resolved roles (indices into the ``J + E`` joint-then-end-site points).

    Returns:
        Indices into the rig's ``J`` joints.
    """
    n = skeleton.num_joints

    def joint_of(point: int) -> int:
        return point if point < n else int(skeleton.end_site_parents[point - n])

    out = []
    for role in ROLES:
        joint = joint_of(roles.index[HAND_TIPS.get(role, role)])
        if role in TOES:
            ankle = joint_of(roles.index[TOES[role]])
            path = skeleton.between(ankle, joint) if joint != ankle else None
            joint = [*path, joint][0] if path is not None else ankle
        out.append(joint)
    return np.array(out, dtype=np.int64)


def role_track(motion: Motion, role_map: str | None = None) -> np.ndarray:
    """``(T, 21, 3)`` world positions of the classifier's role joints, metres, Y up.

    The joints are those of :func:`judge_joints`, in :data:`ROLES` order.
    """
    roles = resolve_roles(motion.skeleton, role_map)
    return motion.global_positions()[:, judge_joints(motion.skeleton, roles)]


def frame_features(positions: np.ndarray, roles: JointRoles, fps: float,
                   out_fps: float) -> np.ndarray:
    """Per-frame classifier features (see the module docstring), resampled to ``out_fps``.

    Args:
        positions: ``(T, J + E, 3)`` world positions of joints then end sites, metres, Y up.
        roles: resolved roles of the rig.
        fps: frame rate of ``positions``.
        out_fps: frame rate of the result.

    Returns:
        ``(T', F)`` float32 features, ``T' = round(T * out_fps / fps)``.
    """
    p = np.asarray(positions, dtype=np.float64)
    leg = leg_length(p, roles)
    if not leg > 0:
        raise ClassifierError("cannot measure the legs of this motion (zero leg length)")
    pts = p[:, role_indices(roles, ROLES)]
    root = pts[:, ROLES.index("root")]
    facing = facing_directions(p, roles)
    facing[np.linalg.norm(facing, axis=1) == 0] = (0.0, 1.0)
    # Rotation that turns the facing (sin a, cos a) onto +Z, applied to (x, z).
    sin_a, cos_a = facing[:, 0], facing[:, 1]

    def body_frame(v: np.ndarray) -> np.ndarray:
        x = cos_a[:, None] * v[..., 0] - sin_a[:, None] * v[..., 2]
        z = sin_a[:, None] * v[..., 0] + cos_a[:, None] * v[..., 2]
        return np.stack((x, v[..., 1], z), axis=-1)

    pose = body_frame(pts - root[:, None] * [1.0, 0.0, 1.0]) / leg
    velocity = body_frame(np.gradient(pts, axis=0) * fps) / leg if len(p) > 1 else pose * 0.0
    affect = affective_features_np(p, roles)
    contacts = foot_contacts(p, roles, fps)
    move = movement_features(p, roles, fps, contacts=contacts)
    movement = np.stack((
        move.root_height / leg, move.root_speed * fps / leg, move.root_speed_lowpass * fps / leg,
        move.orientation_difference, move.curvature * fps**2 / leg, np.sin(move.step_phase),
        np.cos(move.step_phase), move.step_frequency * fps / np.pi,
    ), axis=1)
    table = np.concatenate(
        (pose.reshape(len(p), -1), velocity.reshape(len(p), -1), affect, movement), axis=1
    )
    n_out = max(1, round(len(p) * out_fps / fps))
    t_in = np.arange(len(p)) / fps
    t_out = np.arange(n_out) / out_fps
    out = np.stack([np.interp(t_out, t_in, table[:, k]) for k in range(table.shape[1])], 1)
    return out.astype(np.float32)


def motion_features(motion: Motion, config: ClassifierConfig,
                    role_map: str | None = None) -> np.ndarray:
    """:func:`frame_features` of a clip at the classifier's rate: ``(T', F)``."""
    return track_features(role_track(motion, role_map), motion.fps, config)


def track_features(points: np.ndarray, fps: float, config: ClassifierConfig) -> np.ndarray:
    """:func:`frame_features` of a ``(T, J, 3)`` role track at the classifier's rate."""
    return frame_features(points, ROLE_POINTS, fps, config.fps)


@dataclass(frozen=True)
class Judgement:
    """What the classifier says about the windows of a clip.

    Attributes:
        times: ``(K,)`` window centre times, seconds.
        probabilities: ``(K, C)`` calibrated label probabilities.
        valence_arousal: ``(K, 2)`` valence and arousal in -1..1.
        distance: ``(K,)`` Mahalanobis distance of each window's embedding from the training
            windows'.
        unsure: ``(K,)`` True where ``distance`` is beyond the training windows' quantile.
        labels: the label of each probability column.
    """

    times: np.ndarray
    probabilities: np.ndarray
    valence_arousal: np.ndarray
    distance: np.ndarray
    unsure: np.ndarray
    labels: tuple[str, ...]

    @property
    def perceived(self) -> list[str]:
        """Each window's most probable label, or ``"unsure"``."""
        return ["unsure" if u else label for u, label in zip(
            self.unsure, window_labels(self.probabilities, self.labels), strict=True)]

    @property
    def clip_unsure(self) -> bool:
        """Whether most windows are unsure."""
        return bool(self.unsure.mean() > 0.5)


@dataclass
class EmotionClassifier:
    """A trained classifier: network, standardization, calibration, novelty test and config.

    A classifier built without the calibration entries (a fresh network) has temperature 1
    and is never unsure.

    Attributes:
        config: how it was built and trained.
        net: the network of ``config.architecture`` (eval mode).
        mean, std: ``(F,)`` standardization of the features.
        metrics: held-out results recorded at training time (accuracy, confusion matrix, ...).
        temperature: the label logits are divided by it (fitted on the validation split).
        embedding_mean: ``(E,)`` mean embedding of the training windows (``None``: no test).
        embedding_precision: ``(E, E)`` inverse covariance of those embeddings.
        unsure_distance: Mahalanobis distance beyond which a window is unsure.
    """

    config: ClassifierConfig
    net: nn.Module
    mean: np.ndarray
    std: np.ndarray
    metrics: dict = field(default_factory=dict)
    temperature: float = 1.0
    embedding_mean: np.ndarray | None = None
    embedding_precision: np.ndarray | None = None
    unsure_distance: float = math.inf

    @property
    def labels(self) -> tuple[str, ...]:
        """The labels, in output order."""
        return self.config.labels

    def outputs(self, windows: np.ndarray) -> dict[str, np.ndarray]:
        """Every output for feature windows ``(B, T, F)``.

        Returns:
            ``{"embedding": (B, E), "logits": (B, C) uncalibrated, "probabilities": (B, C)
            calibrated, "valence_arousal": (B, 2), "style_logits": (B, S), "distance": (B,),
            "unsure": (B,) bool}``.
        """
        x = (np.asarray(windows, dtype=np.float32) - self.mean) / self.std
        self.net.eval()
        with torch.no_grad():
            e, logits, va, style = (t.numpy() for t in self.net.heads(
                torch.from_numpy(np.ascontiguousarray(x))))
        z = logits / self.temperature
        prob = np.exp(z - z.max(-1, keepdims=True))
        prob /= prob.sum(-1, keepdims=True)
        if self.embedding_mean is None or self.embedding_precision is None:
            distance = np.zeros(len(e))
        else:
            d = e.astype(np.float64) - self.embedding_mean
            distance = np.sqrt(np.maximum(np.einsum("be,ef,bf->b", d, self.embedding_precision,
                                                    d), 0.0))
        return {"embedding": e, "logits": logits, "probabilities": prob.astype(np.float32),
                "valence_arousal": va, "style_logits": style, "distance": distance,
                "unsure": distance > self.unsure_distance}

    def predict_features(self, windows: np.ndarray) -> np.ndarray:
        """Calibrated probabilities ``(B, C)`` for feature windows ``(B, T, F)`` (or ``(T, F)``)."""
        x = np.asarray(windows, dtype=np.float32)
        single = x.ndim == 2
        prob = self.outputs(x[None] if single else x)["probabilities"]
        return prob[0] if single else prob

    def windows(self, feats: np.ndarray, window_seconds: float, hop_seconds: float,
                name: str = "the motion", seconds: float | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
        """Cut ``(T, F)`` features into judged windows.

        Args:
            feats: ``(T, F)`` features at the classifier's rate.
            window_seconds: length of each window (a shorter clip is one window).
            hop_seconds: spacing of the windows.
            name: the clip, for messages.
            seconds: the clip's duration, for messages (default: that of the features).

        Returns:
            ``(K,)`` window centre times, seconds, and ``(K, L, F)`` windows.

        Raises:
            ClassifierError: the window or the clip is shorter than ``min_seconds``.
        """
        rate = self.config.fps
        least = self.config.min_seconds
        seconds = len(feats) / rate if seconds is None else seconds
        if window_seconds < least - 1e-9:
            raise ClassifierError(
                f"a window of {window_seconds:g} s is too short for {name} ({seconds:.2f} s): "
                f"the classifier needs windows of at least {least:g} s; pass a longer window"
            )
        need = math.ceil(least * rate - 1e-9)
        if len(feats) < need:
            raise ClassifierError(
                f"{name} lasts {seconds:.2f} s; the classifier needs at least {least:g} s "
                "(about one stride): give it a longer clip"
            )
        length = min(len(feats), max(need, round(window_seconds * rate)))
        hop = max(1, round(hop_seconds * rate))
        starts = np.arange(0, len(feats) - length + 1, hop)
        return (starts + 0.5 * length) / rate, np.stack([feats[s:s + length] for s in starts])

    def judge(self, motion: Motion, window_seconds: float = 4.0, hop_seconds: float = 1.0,
              role_map: str | None = None) -> Judgement:
        """Perceived emotion over time, with valence/arousal and the unsure flags.

        Args:
            motion: any clip whose rig has the joint roles, at any frame rate and size.
            window_seconds: length of each judged window (at least ``min_seconds``; clips
                shorter than a window are judged whole).
            hop_seconds: spacing of the windows.
            role_map: role map of the rig (see :func:`emotive.core.roles.resolve_roles`).

        Raises:
            ClassifierError: the window or the clip is shorter than ``min_seconds``.
        """
        name = str(motion.metadata.get("name", "the motion"))
        feats = motion_features(motion, self.config, role_map)
        times, windows = self.windows(feats, window_seconds, hop_seconds, name, motion.duration)
        out = self.outputs(windows)
        return Judgement(times, out["probabilities"], out["valence_arousal"], out["distance"],
                         out["unsure"], self.labels)

    def classify(
        self, motion: Motion, window_seconds: float = 4.0, hop_seconds: float = 1.0,
        role_map: str | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Perceived emotion over time (:meth:`judge` without the extras).

        Returns:
            ``(K,)`` window centre times in seconds and ``(K, C)`` calibrated probabilities.

        Raises:
            ClassifierError: the window or the clip is shorter than ``min_seconds``.
        """
        j = self.judge(motion, window_seconds, hop_seconds, role_map)
        return j.times, j.probabilities

    def save(self, path: str | Path) -> Path:
        """Write the classifier to one ``.pt`` file atomically."""
        width = self.net.out.in_features
        payload = {
            "format": FILE_FORMAT,
            "config": asdict(self.config),
            "state": self.net.state_dict(),
            "mean": torch.from_numpy(self.mean),
            "std": torch.from_numpy(self.std),
            "metrics": json.dumps(self.metrics),
            "temperature": torch.tensor(float(self.temperature), dtype=torch.float64),
            "embedding_mean": torch.from_numpy(np.asarray(
                self.embedding_mean if self.embedding_mean is not None else np.zeros(width),
                dtype=np.float64)),
            "embedding_precision": torch.from_numpy(np.asarray(
                self.embedding_precision if self.embedding_precision is not None
                else np.eye(width), dtype=np.float64)),
            "unsure_distance": torch.tensor(float(self.unsure_distance), dtype=torch.float64),
        }
        # An open file makes torch raise OSError (ENOSPC) on a full disk, which atomic_output
        # turns into one OutputError; a path would give torch's multi-line RuntimeError.
        with atomic_output(path) as tmp, open(tmp, "wb") as fh:
            torch.save(payload, fh)
        return Path(path)

    @classmethod
    def load(cls, path: str | Path) -> EmotionClassifier:
        """Read a file written by :meth:`save`, checked entry by entry.

        The config is checked field by field (types, finite, :data:`CONFIG_RANGES`), the
        weights tensor by tensor before the network is built (keys, dtypes and shapes of the
        config's network, finite values within the trained range:
        :func:`~emotive.models.checkpoint_checks.build_weights`); ``mean`` and ``std`` must be
        float32 ``(F,)`` within that range, the ``std`` above 0; the temperature above 0; the
        embedding statistics float64 ``(E,)`` and ``(E, E)``; ``metrics`` a JSON text; no
        other entry (:data:`FILE_ENTRIES`). The shipped file must match the fingerprint of its
        model card.

        Raises:
            ClassifierFileError: missing, a folder, unreadable, or not a usable classifier
                file; one line naming the file, the bad entry and the fix (also a
                :class:`~emotive.errors.ConfigError`).
        """
        path = Path(path)
        if not path.exists():
            raise ClassifierFileError(f"classifier file {path} does not exist") from None
        try:
            return read_checkpoint(path, "a valid emotive classifier", _build,
                                   "train one with `emotive train classifier` or use the "
                                   "built-in one", FILE_ENTRIES)[0]
        except ConfigError as exc:
            raise ClassifierFileError(f"classifier file {exc}") from None


def _build(payload: dict) -> EmotionClassifier:
    """The classifier of a loaded file (``ValueError`` and others on a bad entry)."""
    if payload.get("format") != FILE_FORMAT:
        raise ValueError(f"no 'format' entry {FILE_FORMAT!r} (files of format 1, from before "
                         "the calibrated classifier, must be retrained)")
    require_keys(payload, {"config": dict, "state": dict, "mean": torch.Tensor,
                           "std": torch.Tensor, "metrics": str, "temperature": torch.Tensor,
                           "embedding_mean": torch.Tensor,
                           "embedding_precision": torch.Tensor,
                           "unsure_distance": torch.Tensor})
    config = ClassifierConfig.from_dict(payload["config"])
    net = build_weights(lambda: build_net(config), payload["state"], limit=NET_WEIGHT_LIMIT)
    width = net.out.in_features
    # The embedding's inverse covariance grows as its spread shrinks: only bounded loosely.
    for name, dtype, shape, limit in (
        ("mean", torch.float32, (NUM_FEATURES,), WEIGHT_LIMIT),
        ("std", torch.float32, (NUM_FEATURES,), WEIGHT_LIMIT),
        ("embedding_mean", torch.float64, (width,), WEIGHT_LIMIT),
        ("embedding_precision", torch.float64, (width, width), MAX_MAGNITUDE),
        ("temperature", torch.float64, (), MAX_MAGNITUDE),
    ):
        check_tensor(payload[name], torch.empty(shape, dtype=dtype, device="meta"), repr(name),
                     std=name == "std", limit=limit)
    unsure_value = payload["unsure_distance"]
    if unsure_value.dtype != torch.float64 or unsure_value.shape != ():
        raise ValueError(f"'unsure_distance' is a {unsure_value.dtype} tensor of shape "
                         f"{tuple(unsure_value.shape)}, not one float64 number")
    stats = {name: payload[name].numpy().astype(np.float32) for name in ("mean", "std")}
    temperature = float(payload["temperature"])
    if not (math.isfinite(temperature) and temperature > 0):
        raise ValueError(f"'temperature' is {temperature}, not a positive number")
    unsure = float(payload["unsure_distance"])
    if not unsure > 0:
        raise ValueError(f"'unsure_distance' is {unsure}, not a positive number")
    try:
        metrics = json.loads(payload["metrics"])
    except json.JSONDecodeError as exc:
        raise ValueError(f"'metrics' is not a JSON text ({exc})") from None
    if not isinstance(metrics, dict):
        raise ValueError(f"'metrics' holds a {type(metrics).__name__}, not a JSON object")
    net.eval()
    return EmotionClassifier(config, net, stats["mean"], stats["std"], metrics, temperature,
                             payload["embedding_mean"].numpy(),
                             payload["embedding_precision"].numpy(), unsure)


def default_classifier_path() -> Path:
    """The committed classifier under ``emotive/assets``."""
    return Path(__file__).resolve().parents[1] / "assets" / "classifier" / "emotion-classifier.pt"


def load_default_classifier() -> EmotionClassifier:
    """The committed classifier (see its model card beside it)."""
    return EmotionClassifier.load(default_classifier_path())


def window_labels(probabilities: np.ndarray, labels: Sequence[str]) -> list[str]:
    """The most probable label of each row of ``(K, C)`` probabilities."""
    return [labels[i] for i in np.argmax(probabilities, axis=-1)]
