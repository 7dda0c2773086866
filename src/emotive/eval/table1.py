"""The motion-prediction protocol of Table 1 of Emotive Gaits (Randhavane et al.), with baselines.

Protocol (section 5.5 of the paper): each held-out gait is shown to a model for its first 18
frames (at 10 fps, 1.8 s), the model predicts the next 42 frames (4.2 s) keeping the gait's own
emotion as the desired one, and the prediction is compared with the recording by the pose error
relative to the character's bounding-box diagonal and the joint rotation error in degrees.
:func:`table1` runs that protocol on clips of any length and reports, per model, the mean and
standard deviation over windows of :func:`~emotive.eval.pose_errors.pose_error`,
:func:`~emotive.eval.pose_errors.rotation_error` and
:func:`~emotive.eval.pose_errors.euler_angle_error`.

Choices where the paper is silent or its data differ from ours:

* Windows. The paper's gaits are 60 frames long, one window each. Bandai Namco clips last 3 to
  10 s, so every window of ``primer + predicted`` frames starting every ``stride_seconds``
  (from the clip's first frame) is evaluated; clips shorter than one window are skipped and
  listed in :attr:`Table1Result.skipped_short`. Overlapping windows are correlated, so the
  standard deviation describes the spread of the errors, not the uncertainty of the mean.
* Frame rate. Clips are resampled to ``fps`` with :func:`emotive.core.ops.resample`. By default
  the primer and horizon keep the paper's durations, 1.8 s and 4.2 s, at any rate (18 and 42
  frames at 10 fps, 54 and 126 at 30 fps), so the same clips and windows are evaluated at every
  rate; pass ``primer_frames`` and ``predicted_frames`` to fix frame counts instead.
* Joints. Errors cover the rig's root (the ``root`` role, e.g. ``Hips``; joint 0 on rigs
  whose roles do not resolve) and its descendants: the body. Joints above it, such as the
  Bandai Namco ``joint_Root`` that stays at the world origin while the hips travel, are not
  part of the pose, and would otherwise put the whole trajectory into the root-relative pose
  error and into the bounding box. Rotation and Euler errors leave out joints without
  rotation channels, which the rig fixes at the identity.
* Pose error. Root-relative world positions of the body joints (the root itself left out) and
  the target's bounding-box diagonal over the predicted frames, as documented in
  :func:`~emotive.eval.pose_errors.pose_error`: the pose is judged apart from the trajectory.
* Averages. Each error of a window is its mean over the predicted frames and joints; the
  table reports the mean and standard deviation of these over windows, each window weighing
  the same (so long clips, which give more windows, weigh more than short ones).
* Emotion. A predictor gets the one-hot vector of the clip's intended emotion (its style)
  over ``labels``. Clips whose emotion is not among ``labels`` cannot be described to such a
  model; they are skipped and listed in :attr:`Table1Result.skipped_label` (pass
  :data:`emotive.data.emotion.ALL_LABELS` to keep every style).

The paper's predictions follow "the trajectory of the ground truth data"; a
:class:`~emotive.models.api.Predictor` (re-exported here) has no trajectory input yet, so
path-following models see only the primer.

Shapes: ``B`` windows, ``T`` frames, ``J`` joints, ``C`` emotion labels.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.models.api import Predictor

if TYPE_CHECKING:
    from emotive.core import Motion, Skeleton

__all__ = [
    "ERRORS",
    "PREDICTED_SECONDS",
    "PRIMER_SECONDS",
    "ErrorStats",
    "Predictor",
    "PredictorScores",
    "Table1Result",
    "ZeroVelocity",
    "merge_results",
    "table1",
]

#: Primer length of the paper's protocol: 18 frames at 10 fps.
PRIMER_SECONDS = 1.8
#: Prediction horizon of the paper's protocol: 42 frames at 10 fps.
PREDICTED_SECONDS = 4.2
#: The errors of one window, in the column order of :attr:`PredictorScores.errors`.
ERRORS: tuple[str, ...] = ("pose", "rotation", "euler")

# emotive.data.emotion.DEFAULT_LABELS, repeated so that importing this module loads no SciPy
# (the tests check that the two agree).
_DEFAULT_LABELS: tuple[str, ...] = ("happy", "sad", "angry", "neutral")


@dataclass(frozen=True)
class ZeroVelocity:
    """The zero-velocity baseline: the last primer frame, held.

    Every predicted frame repeats the primer's last local rotations and translations, so the
    character freezes where it stands. It ignores the emotion. This is the standard lower bar of
    motion prediction (a model must beat it to have learnt any dynamics), not a model of the
    paper; on short horizons it is hard to beat.

    Attributes:
        name: the name in the table.
    """

    name: str = "Zero velocity"

    def predict(
        self, primer: Motion, frames: int, emotion: np.ndarray, labels: tuple[str, ...]
    ) -> Motion:
        """``frames`` copies of the primer's last frame (see :meth:`Predictor.predict`).

        Raises:
            ValueError: ``frames < 1`` or the primer has no frames.
        """
        if isinstance(frames, bool) or not isinstance(frames, numbers.Integral) or frames < 1:
            raise ValueError(f"frames must be a positive whole number, got {frames!r}")
        if primer.num_frames < 1:
            raise ValueError("the primer has no frames: a zero-velocity prediction needs one")
        return primer.replace(
            rotations=np.repeat(primer.rotations[-1:], int(frames), axis=0),
            positions=np.repeat(primer.positions[-1:], int(frames), axis=0),
            metadata={**primer.metadata, "predictor": self.name},
        )


@dataclass(frozen=True)
class ErrorStats:
    """Errors of a set of windows: mean and standard deviation (``ddof = 0``) over windows.

    Attributes:
        pose: mean :func:`~emotive.eval.pose_errors.pose_error`, a fraction of the character's
            bounding-box diagonal.
        pose_std: its standard deviation.
        rotation: mean geodesic :func:`~emotive.eval.pose_errors.rotation_error`, degrees.
        rotation_std: its standard deviation.
        euler: mean :func:`~emotive.eval.pose_errors.euler_angle_error`, degrees.
        euler_std: its standard deviation.
        windows: number of windows.
        clips: number of clips they come from.
    """

    pose: float
    pose_std: float
    rotation: float
    rotation_std: float
    euler: float
    euler_std: float
    windows: int
    clips: int

    @classmethod
    def of(cls, errors: np.ndarray, clip_ids: np.ndarray) -> ErrorStats:
        """Statistics of ``(B, 3)`` window errors (columns :data:`ERRORS`) from ``(B,)`` clips."""
        mean, std = errors.mean(0), errors.std(0)
        return cls(
            float(mean[0]), float(std[0]), float(mean[1]), float(std[1]),
            float(mean[2]), float(std[2]), len(errors), len(np.unique(clip_ids)),
        )


@dataclass(frozen=True, eq=False)
class PredictorScores:
    """One predictor's results.

    Attributes:
        name: the predictor's name.
        errors: ``(B, 3)`` pose, rotation and Euler error (:data:`ERRORS`) of every window, in
            the order of :attr:`Table1Result.window_clips`.
        overall: statistics over all windows.
        per_emotion: statistics over the windows of each intended emotion, in label order;
            emotions without windows are absent.
        pose_by_frame: ``(B, T')`` pose error of every window at each predicted frame (the
            mean over the body joints, relative to the window's bounding-box diagonal), for
            errors by horizon (:mod:`emotive.eval.horizon`); its mean over frames is the
            window's pose error.
    """

    name: str
    errors: np.ndarray
    overall: ErrorStats
    per_emotion: dict[str, ErrorStats]
    pose_by_frame: np.ndarray


@dataclass(frozen=True, eq=False)
class Table1Result:
    """The outcome of :func:`table1`.

    Attributes:
        scores: one entry per predictor, in the order given.
        fps: evaluation frame rate.
        primer_frames: frames shown to each predictor.
        predicted_frames: frames predicted and scored.
        stride_frames: frames between window starts.
        labels: the ``C`` emotion labels the predictors were given.
        window_clips: ``(B,)`` name of each window's clip.
        window_starts: ``(B,)`` first primer frame of each window, at ``fps``.
        window_emotions: ``(B,)`` intended emotion of each window.
        skipped_short: clips shorter than one window at ``fps``.
        skipped_label: clips whose emotion is not among ``labels``.
    """

    scores: tuple[PredictorScores, ...]
    fps: float
    primer_frames: int
    predicted_frames: int
    stride_frames: int
    labels: tuple[str, ...]
    window_clips: tuple[str, ...]
    window_starts: np.ndarray
    window_emotions: tuple[str, ...]
    skipped_short: tuple[str, ...] = field(default=())
    skipped_label: tuple[str, ...] = field(default=())

    @property
    def windows(self) -> int:
        """Number of windows ``B``."""
        return len(self.window_clips)

    @property
    def clips(self) -> int:
        """Number of clips that gave at least one window."""
        return len(set(self.window_clips))

    def __getitem__(self, name: str) -> PredictorScores:
        """The scores of the predictor called ``name``."""
        for s in self.scores:
            if s.name == name:
                return s
        raise KeyError(f"no predictor {name!r}; predictors: {[s.name for s in self.scores]}")

    def rows(self, digits: int = 3) -> list[tuple[str, str, str, str, int]]:
        """Table 1 rows.

        Predictor, pose error, rotation error, Euler error (``mean ± std``, ``digits`` decimals) and
        number of windows.
        """
        def cell(mean: float, std: float) -> str:
            return f"{mean:.{digits}f} ± {std:.{digits}f}"

        rows = []
        for s in self.scores:
            o = s.overall
            rows.append((s.name, cell(o.pose, o.pose_std), cell(o.rotation, o.rotation_std),
                         cell(o.euler, o.euler_std), o.windows))
        return rows

    def to_dict(self) -> dict:
        """JSON-ready summary: settings, and per predictor overall and per-emotion statistics."""
        return {
            "fps": self.fps, "primer_frames": self.primer_frames,
            "predicted_frames": self.predicted_frames, "windows": self.windows,
            "clips": self.clips, "skipped_short": list(self.skipped_short),
            "predictors": {
                s.name: {"overall": asdict(s.overall),
                         "per_emotion": {k: asdict(v) for k, v in s.per_emotion.items()}}
                for s in self.scores
            },
        }

    def to_markdown(self, digits: int = 3) -> str:
        """The rows of :meth:`rows` as a Markdown table, one row per predictor."""
        header = ("Predictor", "Pose error (rel.)", "Rotation error (°)", "Euler error (°)",
                  "Windows")
        lines = ["| " + " | ".join(header) + " |", "|---|---:|---:|---:|---:|"]
        lines += ["| " + " | ".join(str(c).replace("|", "\\|") for c in row) + " |"
                  for row in self.rows(digits)]
        return "\n".join(lines)


# --------------------------------------------------------------------------- arguments


def _frame_count(value: Any, seconds: float, fps: float, name: str) -> int:
    """``value`` as a positive frame count, or ``seconds`` at ``fps`` when ``None``."""
    if value is None:
        count = math.floor(seconds * fps + 0.5)
        if count < 1:
            raise ValueError(f"{name}: {seconds} s at {fps} fps is less than one frame; raise "
                             f"fps or pass {name}")
        return count
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f"{name} must be a positive whole number of frames, got {value!r}")
    return int(value)


def _check_predictors(predictors: Iterable[Predictor]) -> tuple[Predictor, ...]:
    if isinstance(predictors, Predictor):
        predictors = (predictors,)
    out = tuple(predictors)
    if not out:
        raise ValueError("no predictors to evaluate: pass at least one, e.g. [ZeroVelocity()]")
    for p in out:
        if not isinstance(p, Predictor) or not isinstance(p.name, str):
            raise ValueError(f"{p!r} is not a Predictor: it needs a `name: str` attribute and a "
                             "`predict(primer, frames, emotion, labels)` method")
    names = [p.name for p in out]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise ValueError(f"predictor names repeat {dup}: give each predictor a unique name")
    return out


def _clip_name(clip: Any, i: int) -> str:
    name = getattr(getattr(clip, "info", None), "name", None)
    if name is None:
        name = getattr(getattr(clip, "motion", None), "metadata", {}).get("name")
    return str(name) if name is not None else f"clip {i}"


def _body(skeleton: Skeleton, root: str | None) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Indices of the body joints and rotation channels, and the Euler orders.

    Indices of the body joints (root first, then its descendants), of those with rotation
    channels, and the latter's Euler orders.
    """
    # Deferred: importing this module stays free of torch and scipy (test_table1.py).
    from emotive.core.roles import match_roles  # noqa: PLC0415

    if root is None:
        r = match_roles(skeleton)[1].get("root", 0)
        r = r if r < skeleton.num_joints else 0
    elif root in skeleton.names:
        r = skeleton.names.index(root)
    else:
        raise ValueError(f"root joint {root!r} is not in the rig (joints: "
                         f"{', '.join(skeleton.names)})")
    inside = np.zeros(skeleton.num_joints, dtype=bool)
    inside[r] = True
    # Parents come before their children, so one pass in index order marks every descendant.
    for j in range(r + 1, skeleton.num_joints):
        inside[j] = inside[skeleton.parents[j]]
    body = np.flatnonzero(inside)
    orders = [skeleton.rotation_order(int(j)) for j in body]
    rotated = body[[bool(o) for o in orders]]
    if len(rotated) == 0:
        raise ValueError(f"no joint below {skeleton.names[r]!r} has rotation channels: "
                         "rotation errors need at least one")
    return body, rotated, [o for o in orders if o]


def _check_prediction(pred: Any, primer: Motion, frames: int, name: str) -> Motion:
    # Deferred: importing this module stays free of torch and scipy (test_table1.py).
    from emotive.core import Motion  # noqa: PLC0415

    if not isinstance(pred, Motion):
        raise ValueError(f"predictor {name!r} returned {type(pred).__name__}, not a Motion")
    if pred.num_frames != frames:
        raise ValueError(f"predictor {name!r} returned {pred.num_frames} frames, expected "
                         f"{frames} (the continuation alone, without the primer)")
    if pred.skeleton.names != primer.skeleton.names or not np.array_equal(
        pred.skeleton.parents, primer.skeleton.parents
    ):
        raise ValueError(f"predictor {name!r} returned a motion on another rig "
                         f"({pred.skeleton.num_joints} joints): use the primer's skeleton")
    if abs(pred.fps - primer.fps) > 1e-9 * primer.fps:
        raise ValueError(f"predictor {name!r} returned a motion at {pred.fps} fps, expected the "
                         f"primer's {primer.fps} fps")
    return pred


# ------------------------------------------------------------------------------ protocol


def _check_protocol(
    fps: float,
    primer_frames: int | None,
    predicted_frames: int | None,
    stride_seconds: float,
    labels: Sequence[str],
) -> tuple[float, int, int, int, tuple[str, ...]]:
    """Check :func:`table1`'s protocol arguments and resolve them to frame counts.

    Args:
        fps: evaluation frame rate.
        primer_frames: frames shown, or ``None`` for :data:`PRIMER_SECONDS`.
        predicted_frames: frames predicted, or ``None`` for :data:`PREDICTED_SECONDS`.
        stride_seconds: time between window starts.
        labels: the emotion labels of the predictors.

    Returns:
        ``(fps, primer frames, predicted frames, stride frames, labels)``.

    Raises:
        ValueError: a bad rate, frame count, stride or label.
    """
    # Deferred: importing this module stays free of torch and scipy (test_table1.py).
    from emotive.data.emotion import check_labels  # noqa: PLC0415
    from emotive.errors import EmotionError  # noqa: PLC0415

    if isinstance(fps, bool) or not isinstance(fps, numbers.Real) or not (
        math.isfinite(fps) and fps > 0
    ):
        raise ValueError(f"fps must be a positive finite number, got {fps!r}")
    fps = float(fps)
    n_primer = _frame_count(primer_frames, PRIMER_SECONDS, fps, "primer_frames")
    n_pred = _frame_count(predicted_frames, PREDICTED_SECONDS, fps, "predicted_frames")
    if isinstance(stride_seconds, bool) or not isinstance(stride_seconds, numbers.Real) or not (
        math.isfinite(stride_seconds) and stride_seconds > 0
    ):
        raise ValueError(f"stride_seconds must be a positive number, got {stride_seconds!r}")
    stride = math.floor(stride_seconds * fps + 0.5)
    if stride < 1:
        raise ValueError(f"stride_seconds={stride_seconds} is less than one frame at {fps} fps")
    try:
        checked = check_labels(labels)
    except EmotionError as exc:
        raise ValueError(f"bad labels: {exc}") from None
    return fps, n_primer, n_pred, stride, checked


def table1(
    predictors: Iterable[Predictor],
    clips: Sequence[Any],
    *,
    fps: float = 10.0,
    primer_frames: int | None = None,
    predicted_frames: int | None = None,
    stride_seconds: float = 1.0,
    labels: Sequence[str] = _DEFAULT_LABELS,
    root: str | None = None,
) -> Table1Result:
    """Run the Table-1 prediction protocol of Emotive Gaits on held-out clips.

    For each clip (resampled to ``fps``), every window of ``primer_frames + predicted_frames``
    frames starting every ``stride_seconds`` is cut; each predictor gets the primer (the
    window's first ``primer_frames`` frames) and the clip's one-hot intended emotion, and its
    ``predicted_frames`` frames are scored against the rest of the window. See the module
    docstring for the choices (windows, durations, joints, skipped clips).

    Args:
        predictors: the models, each with a unique ``name``.
        clips: held-out clips with ``.motion`` (:class:`~emotive.core.Motion`) and
            ``.info.emotion`` (a label), e.g. ``split_clips(load_clips(...))["test"]``.
        fps: evaluation frame rate.
        primer_frames: frames shown, ``T``; ``None``: 1.8 s at ``fps`` (18 at 10 fps).
        predicted_frames: frames predicted, ``T'``; ``None``: 4.2 s at ``fps`` (42 at 10 fps).
        stride_seconds: time between window starts, rounded to whole frames at ``fps``.
        labels: the ``C`` emotion labels of the predictors (default: the paper's four,
            :data:`emotive.data.emotion.DEFAULT_LABELS`).
        root: name of the body's root joint; ``None``: the rig's ``root`` role (``Hips`` on
            Bandai Namco and CMU rigs), joint 0 where roles do not resolve.

    Returns:
        Per predictor, the errors of every window and their statistics, overall and per emotion
        (:class:`Table1Result`).

    Raises:
        ValueError: no or unnamed predictors, repeated names, no clips, a bad rate, frame count,
            stride, label or root, no clip long enough for one window, or a prediction of the
            wrong length, rig or rate.
    """
    # Deferred: importing this module stays free of torch and scipy (test_table1.py).
    from emotive.core.ops import resample  # noqa: PLC0415
    from emotive.data.emotion import Emotion, canonical_label  # noqa: PLC0415
    from emotive.data.windows import window_starts  # noqa: PLC0415
    from emotive.errors import EmotionError  # noqa: PLC0415
    from emotive.eval.pose_errors import euler_angle_error, pose_error, rotation_error  # noqa: PLC0415
    from emotive.transforms.kinematics import forward_kinematics_np  # noqa: PLC0415

    models = _check_predictors(predictors)
    fps, n_primer, n_pred, stride, labels = _check_protocol(
        fps, primer_frames, predicted_frames, stride_seconds, labels
    )
    length = n_primer + n_pred
    clips = list(clips)
    if not clips:
        raise ValueError("no clips to evaluate: pass held-out clips, e.g. split_clips(...)['test']")

    errors: dict[str, list[np.ndarray]] = {p.name: [] for p in models}
    by_frame: dict[str, list[np.ndarray]] = {p.name: [] for p in models}
    window_clips: list[str] = []
    window_emotions: list[str] = []
    starts_all: list[np.ndarray] = []
    skipped_short: list[str] = []
    skipped_label: list[str] = []
    bodies: dict[tuple[str, ...], tuple[np.ndarray, np.ndarray, list[str]]] = {}
    for i, clip in enumerate(clips):
        name = _clip_name(clip, i)
        try:
            emotion_label = canonical_label(str(clip.info.emotion))
            motion = clip.motion
        except AttributeError as exc:
            raise ValueError(f"clip {name} needs .motion and .info.emotion ({exc})") from None
        except EmotionError:
            # A style without an emotion label cannot be described to any predictor.
            emotion_label = ""
        if emotion_label not in labels:
            skipped_label.append(name)
            continue
        emotion = Emotion.one_hot(emotion_label, labels).weights.copy()
        motion = resample(motion, fps)
        starts = window_starts(motion.num_frames, length, stride)
        if len(starts) == 0:
            skipped_short.append(name)
            continue
        sk = motion.skeleton
        if sk.names not in bodies:
            bodies[sk.names] = _body(sk, root)
        body, rotated, orders = bodies[sk.names]

        future = starts[:, None] + n_primer + np.arange(n_pred)  # (B, T')
        true_rot = motion.rotations[future]  # (B, T', J, 4)
        true_pos = motion.global_positions()[future]  # (B, T', J, 3)
        for model in models:
            preds = []
            for s in starts:
                primer = motion.replace(
                    rotations=motion.rotations[s : s + n_primer].copy(),
                    positions=motion.positions[s : s + n_primer].copy(),
                    metadata=dict(motion.metadata),
                )
                out = model.predict(primer, n_pred, emotion.copy(), labels)
                preds.append(_check_prediction(out, primer, n_pred, model.name))
            pred_rot = np.stack([p.rotations for p in preds])
            pred_pos = forward_kinematics_np(
                pred_rot, np.stack([p.positions for p in preds]), sk.parents
            )[1]
            errors[model.name].append(np.stack([
                pose_error(pred_pos[..., body, :], true_pos[..., body, :], root_index=0),
                rotation_error(pred_rot[..., rotated, :], true_rot[..., rotated, :]),
                euler_angle_error(pred_rot[..., rotated, :], true_rot[..., rotated, :], orders),
            ], axis=-1))
            by_frame[model.name].append(pose_error(pred_pos[..., body, :], true_pos[..., body, :],
                                                   root_index=0, reduction="frame"))
        window_clips += [name] * len(starts)
        window_emotions += [emotion_label] * len(starts)
        starts_all.append(starts)

    if not window_clips:
        raise ValueError(
            f"no window of {length} frames ({length / fps:.2f} s at {fps} fps) in any clip: "
            f"{len(skipped_short)} too short, {len(skipped_label)} with an emotion outside "
            f"{list(labels)}"
        )
    scores = [_scores(name, np.concatenate(errors[name]), np.concatenate(by_frame[name]),
                      window_clips, window_emotions, labels) for name in errors]
    return Table1Result(
        scores=tuple(scores), fps=fps, primer_frames=n_primer, predicted_frames=n_pred,
        stride_frames=stride, labels=labels, window_clips=tuple(window_clips),
        window_starts=np.concatenate(starts_all), window_emotions=tuple(window_emotions),
        skipped_short=tuple(skipped_short), skipped_label=tuple(skipped_label),
    )


def _scores(name: str, errors: np.ndarray, pose_by_frame: np.ndarray,
            window_clips: Sequence[str], window_emotions: Sequence[str],
            labels: Sequence[str]) -> PredictorScores:
    """A predictor's :class:`PredictorScores` from its ``(B, 3)`` and ``(B, T')`` errors."""
    clip_ids, emotions = np.array(window_clips), np.array(window_emotions)
    per_emotion = {
        label: ErrorStats.of(errors[emotions == label], clip_ids[emotions == label])
        for label in labels if np.any(emotions == label)
    }
    return PredictorScores(name, errors, ErrorStats.of(errors, clip_ids), per_emotion,
                           pose_by_frame)


def merge_results(results: Sequence[Table1Result]) -> Table1Result:
    """Several :func:`table1` runs as one: their windows pooled, each weighing the same.

    The statistics of the merged result are those of every window of every run, as if
    :func:`table1` had been given all their clips at once (e.g. the test clips of two data
    sets evaluated apart, then together).

    Args:
        results: runs with the same predictors (names, in order), rate, frame counts, stride
            and labels.

    Returns:
        One :class:`Table1Result` over all their windows, in the order given.

    Raises:
        ValueError: no results, or runs that differ in predictors or protocol.
    """
    results = list(results)
    if not results:
        raise ValueError("no results to merge: pass at least one table1(...) result")
    first = results[0]

    def protocol(r: Table1Result) -> tuple:
        return (tuple(s.name for s in r.scores), r.fps, r.primer_frames, r.predicted_frames,
                r.stride_frames, r.labels)

    for r in results[1:]:
        if protocol(r) != protocol(first):
            raise ValueError(f"cannot merge table1 results with different predictors or "
                             f"protocol: {protocol(first)} and {protocol(r)}")
    clips = tuple(c for r in results for c in r.window_clips)
    emotions = tuple(e for r in results for e in r.window_emotions)
    scores = [
        _scores(s.name, np.concatenate([r.scores[k].errors for r in results]),
                np.concatenate([r.scores[k].pose_by_frame for r in results]),
                clips, emotions, first.labels)
        for k, s in enumerate(first.scores)
    ]
    return Table1Result(
        scores=tuple(scores), fps=first.fps, primer_frames=first.primer_frames,
        predicted_frames=first.predicted_frames, stride_frames=first.stride_frames,
        labels=first.labels, window_clips=clips,
        window_starts=np.concatenate([r.window_starts for r in results]),
        window_emotions=emotions,
        skipped_short=tuple(c for r in results for c in r.skipped_short),
        skipped_label=tuple(c for r in results for c in r.skipped_label),
    )
