"""The project's one emotion model: weights over labels, schedules and coercion.

The project's one emotion model: weight vectors over named labels, schedules over time,
and :func:`coerce_emotion`, the one way every model turns a user's emotion into its input.

An emotion is a normalized, non-negative weight vector ``(C,)`` over an ordered tuple of
``C`` labels (:mod:`emotive.data.circumplex`, whose names this module re-exports: the labels,
their valence/arousal points and the conversions between the two). Models fix their labels in
their config; every function takes ``labels`` for that reason.

Text form (command line, JSON): ``"happy=0.7,neutral=0.3"`` or a single name ``"sad"``; each
weight is from 0 to 1 and the blend is normalized to sum to one. ``"valence=0.5,arousal=-0.2"``
is a point of the -1..1 circumplex (:data:`~emotive.data.circumplex.VA_LIMIT`), blended over the
labels by the Gaussian kernel of :func:`~emotive.data.circumplex.weights_from_valence_arousal`.
Unknown names, weights outside 0..1, NaN or infinite weights, all-zero vectors and points
outside -1..1 raise :class:`~emotive.errors.EmotionError`: a value is refused, never clamped.

Schedules
---------
:class:`EmotionSchedule` holds keyframes ``[{"t": 0, "emotion": {"angry": 1}},
{"t": 10, "emotion": "happy=1"}]`` (seconds; a keyframe may give ``"valence"`` and ``"arousal"``
instead of ``"emotion"``), interpolated linearly, held constant before the first and after the
last keyframe, renormalized per frame and sampled at any frame rate to ``(T, C)``. Two keyframes
at the same time make an instant switch. Beside the label weights it keeps a valence/arousal
track ``(K, 2)``: exactly the given point for a valence/arousal keyframe, the weighted mean of
the label points for a label keyframe (:meth:`EmotionSchedule.sample_valence_arousal`).

Shapes: ``T`` frames, ``C`` labels, ``K`` keyframes, ``N`` query points.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from emotive.data.circumplex import (
    ALIASES,
    ALL_LABELS,
    DEFAULT_LABELS,
    EXTRA_LABELS,
    VA_KERNEL_WIDTH,
    VA_LIMIT,
    VALENCE_AROUSAL,
    AffectPoint,
    canonical_label,
    check_labels,
    check_valence_arousal,
    label_points,
    normalize_weights,
    style_to_label,
    valence_arousal,
    weights_from_valence_arousal,
)
from emotive.data.emotion_blend import Emotion, jsonable
from emotive.errors import EmotionError

__all__ = [
    "ALIASES",
    "ALL_LABELS",
    "DEFAULT_LABELS",
    "EXTRA_LABELS",
    "VALENCE_AROUSAL",
    "VA_KERNEL_WIDTH",
    "VA_LIMIT",
    "AffectPoint",
    "Emotion",
    "EmotionLike",
    "EmotionSchedule",
    "canonical_label",
    "check_labels",
    "check_valence_arousal",
    "coerce_blend",
    "coerce_emotion",
    "label_points",
    "point_emotion",
    "style_to_label",
    "valence_arousal",
    "weights_from_valence_arousal",
]


@dataclass(frozen=True, eq=False)
class EmotionSchedule:
    """Emotion over time, by linear interpolation between keyframes.

    Attributes:
        times: ``(K,)`` keyframe times in seconds, non-decreasing, from 0.
        weights: ``(K, C)`` normalized emotion at each keyframe.
        labels: the ``C`` labels.
        points: ``(K, 2)`` valence/arousal at each keyframe; by default (``None``) the
            weighted mean of the label points of ``weights``.
    """

    times: np.ndarray
    weights: np.ndarray
    labels: tuple[str, ...] = DEFAULT_LABELS
    points: np.ndarray | None = None

    def __post_init__(self) -> None:
        labels = check_labels(self.labels)
        times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        if len(times) == 0:
            raise EmotionError("an emotion schedule needs at least one keyframe")
        if not np.all(np.isfinite(times)) or np.any(times < 0):
            raise EmotionError(
                f"keyframe times must be finite and >= 0 seconds, got {times.tolist()}"
            )
        if np.any(np.diff(times) < 0):
            raise EmotionError(
                f"keyframe times must not decrease, got {times.tolist()}: sort the keyframes by t"
            )
        weights = normalize_weights(np.asarray(self.weights, dtype=np.float64), "keyframes", labels)
        if weights.shape != (len(times), len(labels)):
            raise EmotionError(
                f"expected keyframe weights of shape ({len(times)}, {len(labels)}), "
                f"got {weights.shape}"
            )
        points = (weights @ label_points(labels) if self.points is None
                  else np.asarray(self.points, dtype=np.float64))
        if points.shape != (len(times), 2) or not np.all(np.isfinite(points)):
            raise EmotionError(
                f"expected finite keyframe valence/arousal of shape ({len(times)}, 2), "
                f"got {points.tolist()}"
            )
        for name, value in (("times", times), ("weights", weights), ("labels", labels),
                            ("points", points)):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def constant(cls, emotion: Emotion, point: Sequence[float] | None = None) -> EmotionSchedule:
        """The same emotion at every time.

        Args:
            emotion: the emotion.
            point: its exact valence/arousal, if it was given as a point (default: the
                weighted mean of the label points).
        """
        points = None if point is None else np.asarray(point, dtype=np.float64).reshape(1, 2)
        return cls(np.zeros(1), emotion.weights[None], emotion.labels, points)

    @classmethod
    def from_keyframes(
        cls, keyframes: Sequence[Mapping[str, Any]], labels: Sequence[str] = DEFAULT_LABELS,
        points_over: Sequence[str] | None = None,
    ) -> EmotionSchedule:
        """A schedule from ``[{"t": 0, "emotion": {"angry": 1}}, {"t": 10, "emotion": "happy"}]``.

        Each keyframe has ``t`` (seconds) and either ``emotion`` (a mapping or the text form of
        :meth:`Emotion.parse`) or ``valence`` and ``arousal`` (blended over ``points_over``,
        default all ``labels``: :func:`point_emotion`).

        Raises:
            EmotionError: naming the keyframe and what is wrong with it.
        """
        labels = check_labels(labels)
        if isinstance(keyframes, Mapping) or isinstance(keyframes, str | bytes):
            raise EmotionError(
                'an emotion schedule is a list of keyframes [{"t": 0, "emotion": {...}}, ...]'
            )
        if len(keyframes) == 0:
            raise EmotionError("an emotion schedule needs at least one keyframe")
        times, rows, points = [], [], []
        for k, frame in enumerate(keyframes):
            where = f"keyframe {k} ({json.dumps(frame) if jsonable(frame) else frame!r})"
            if not isinstance(frame, Mapping) or "t" not in frame:
                raise EmotionError(f'{where} needs "t" (seconds) and "emotion"')
            try:
                t = float(frame["t"])
            except (TypeError, ValueError):
                raise EmotionError(f'{where}: "t" must be a number of seconds') from None
            if not (math.isfinite(t) and t >= 0):
                raise EmotionError(f'{where}: "t" must be a finite time >= 0')
            unknown = set(frame) - {"t", "emotion", "valence", "arousal"}
            if unknown:
                raise EmotionError(
                    f"{where} has unknown keys {sorted(unknown)}; use t, emotion, valence, arousal"
                )
            point = None
            try:
                if "emotion" in frame:
                    value = frame["emotion"]
                    if isinstance(value, str):
                        emotion = Emotion.parse(value, labels)
                    elif isinstance(value, Mapping):
                        emotion = Emotion.from_dict(value, labels)
                    else:
                        raise EmotionError('"emotion" must be a mapping or text like "happy=1"')
                elif "valence" in frame and "arousal" in frame:
                    point = check_valence_arousal(frame["valence"], frame["arousal"])
                    emotion = point_emotion(point, labels, points_over)
                else:
                    raise EmotionError('give "emotion", or "valence" and "arousal"')
            except EmotionError as exc:
                raise EmotionError(f"{where}: {exc}") from None
            except (TypeError, ValueError):
                raise EmotionError(f"{where}: valence and arousal must be numbers") from None
            times.append(t)
            rows.append(emotion.weights)
            points.append(emotion.valence_arousal() if point is None else point)
        if any(b < a for a, b in itertools.pairwise(times)):
            raise EmotionError(f"keyframe times {times} decrease: sort the keyframes by t")
        return cls(np.array(times), np.stack(rows), labels, np.array(points))

    @classmethod
    def from_json(
        cls, source: str | os.PathLike, labels: Sequence[str] = DEFAULT_LABELS,
        points_over: Sequence[str] | None = None,
    ) -> EmotionSchedule:
        """A schedule from JSON text or a ``.json`` file holding a list of keyframes.

        Keyframes as for :meth:`from_keyframes` (``points_over`` likewise).

        Raises:
            EmotionError: the file does not exist, is not valid JSON (line and column named),
                or a keyframe is bad; text that is neither a file nor JSON says so.
        """
        text = str(source)
        where = "emotion schedule"
        if isinstance(source, os.PathLike) or not text.lstrip().startswith("["):
            text, where = _schedule_text(text)
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise EmotionError(f"{where} is not valid JSON (line {exc.lineno}, column "
                               f"{exc.colno}: {exc.msg}); give a list of keyframes "
                               '[{"t": 0, "emotion": "sad"}, ...]') from None
        try:
            return cls.from_keyframes(data, labels, points_over)
        except EmotionError as exc:
            raise EmotionError(f"{where}: {exc}") from None

    @classmethod
    def parse(cls, spec: str, labels: Sequence[str] = DEFAULT_LABELS) -> EmotionSchedule:
        """A schedule from a command-line value.

        JSON keyframes, a ``.json`` path or an emotion (:func:`coerce_emotion` of the text).
        """
        return coerce_emotion(spec, labels)

    @property
    def duration(self) -> float:
        """Time of the last keyframe in seconds."""
        return float(self.times[-1])

    def at(self, t: np.ndarray | float) -> np.ndarray:
        """Emotion at times ``t``.

        Args:
            t: ``(N,)`` times in seconds (or a scalar).

        Returns:
            ``(N, C)`` normalized weights (``(C,)`` for a scalar ``t``).
        """
        t = np.asarray(t, dtype=np.float64)
        out = self._interpolate(self.weights, t.reshape(-1))
        out /= out.sum(axis=-1, keepdims=True)
        return out.reshape((*t.shape, -1))

    def _interpolate(self, values: np.ndarray, flat: np.ndarray) -> np.ndarray:
        """Interpolate keyframe ``values`` at times ``flat``.

        ``(N, D)`` keyframe ``values`` ``(K, D)`` at times ``flat`` ``(N,)``: linear, held
        outside the keyframes, an instant switch at equal times.
        """
        k = len(self.times)
        if k == 1:
            return np.broadcast_to(values[0], (len(flat), values.shape[1])).copy()
        # First keyframe after each query; times under 1 ns apart switch instantly.
        hi = np.clip(np.searchsorted(self.times, flat, side="right"), 1, k - 1)
        lo = hi - 1
        span = self.times[hi] - self.times[lo]
        ramp, safe = span > 1e-9, np.where(span > 1e-9, span, 1.0)
        alpha = np.clip(np.where(ramp, (flat - self.times[lo]) / safe, 1.0), 0.0, 1.0)
        alpha[flat < self.times[0]] = 0.0
        return (1 - alpha)[:, None] * values[lo] + alpha[:, None] * values[hi]

    def sample(
        self, fps: float, num_frames: int | None = None, duration: float | None = None
    ) -> np.ndarray:
        """The schedule at ``fps`` frames per second, frame ``i`` at time ``i / fps``.

        Args:
            fps: frame rate.
            num_frames: number of frames ``T``; by default enough to cover ``duration``.
            duration: seconds to cover (default: the last keyframe's time), inclusive.

        Returns:
            ``(T, C)`` weights, each row summing to one.
        """
        if not (math.isfinite(fps) and fps > 0):
            raise EmotionError(f"fps must be a positive number, got {fps}")
        if num_frames is None:
            span = self.duration if duration is None else float(duration)
            num_frames = math.floor(span * fps + 1e-9) + 1
        if num_frames < 0:
            raise EmotionError(f"num_frames must be >= 0, got {num_frames}")
        return self.at(np.arange(num_frames) / fps).reshape(num_frames, len(self.labels))

    def sample_valence_arousal(self, frames: int, fps: float) -> np.ndarray:
        """The valence/arousal track at ``fps``, frame ``i`` at time ``i / fps``.

        Args:
            frames: number of frames ``T``.
            fps: frame rate.

        Returns:
            ``(T, 2)`` valence and arousal: a valence/arousal keyframe's point exactly, a label
            keyframe's weighted mean of label points, linear in between.

        Raises:
            EmotionError: ``fps`` not positive or ``frames`` negative.
        """
        if not (math.isfinite(fps) and fps > 0):
            raise EmotionError(f"fps must be a positive number, got {fps}")
        if frames < 0:
            raise EmotionError(f"frames must be >= 0, got {frames}")
        return self._interpolate(self.points, np.arange(frames) / fps)

    def relabel(self, labels: Sequence[str]) -> EmotionSchedule:
        """The schedule over other ``labels``.

        A label it weighs that ``labels`` lack is an error, one ``labels`` add weighs zero.

        Raises:
            EmotionError: weight on a label not in ``labels``, naming it and the known ones.
        """
        labels = check_labels(labels)
        if self.labels == labels:
            return self
        weights = np.zeros((len(self.times), len(labels)))
        for k, name in enumerate(self.labels):
            if name in labels:
                weights[:, labels.index(name)] = self.weights[:, k]
            elif np.any(self.weights[:, k] > 0):
                raise EmotionError(
                    f"the model has no emotion {name!r}; it knows {', '.join(labels)}"
                )
        return EmotionSchedule(self.times, weights, labels, self.points)

    def to_keyframes(self) -> list[dict[str, Any]]:
        """The keyframes as JSON-ready dicts (inverse of :meth:`from_keyframes`)."""
        return [
            {"t": float(t), "emotion": Emotion(w, self.labels).to_dict()}
            for t, w in zip(self.times, self.weights, strict=True)
        ]


def _schedule_text(text: str) -> tuple[str, str]:
    """The JSON text of a schedule given as a path, and how messages name it.

    A path that exists is read. One that does not is an error saying so when it is named like
    a file (``.json`` or a folder in it); other text is taken as JSON, so that ``not json``
    is "not valid JSON", not "no such file".

    Raises:
        EmotionError: a file that does not exist or cannot be read, or a folder.
    """
    path = Path(text)
    if path.is_dir():
        raise EmotionError(f"emotion schedule {path} is a folder; give a .json file of keyframes")
    if path.exists():
        try:
            return path.read_text(), f"emotion schedule {path}"
        except (OSError, UnicodeDecodeError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
            raise EmotionError(f"emotion schedule {path} cannot be read ({reason}): check the "
                               "file") from None
    if path.suffix.lower() == ".json" or os.sep in text:
        raise EmotionError(f"emotion schedule {path} does not exist: check the path")
    return text, f"emotion schedule {text!r}"


#: What :func:`coerce_emotion` accepts.
EmotionLike = (Emotion | EmotionSchedule | str | os.PathLike | Mapping[str, Any]
               | Sequence[Mapping[str, Any]] | np.ndarray)


def _point(value: str | Mapping[str, Any]) -> tuple[float, float] | None:
    """``(valence, arousal)`` of a valence/arousal value, or ``None``.

    ``(valence, arousal)`` of ``"valence=V,arousal=A"`` or ``{"valence": V, "arousal": A}``,
    checked by :func:`check_valence_arousal`; ``None`` for anything else.
    """
    if isinstance(value, str):
        items = [item.replace(":", "=", 1).split("=", 1) for item in value.split(",")]
        if not all(len(item) == 2 for item in items):
            return None
        pairs = {k.strip().lower(): v.strip() for k, v in items}
    else:
        pairs = {str(k).strip().lower(): v for k, v in value.items()}
    keys = set(pairs) & {"valence", "arousal"}
    if not keys:
        return None
    if set(pairs) != {"valence", "arousal"}:
        raise EmotionError(f"emotion {value!r}: give both valence and arousal and nothing else, "
                           "e.g. 'valence=0.5,arousal=-0.2', or label weights such as "
                           "'happy=0.7,neutral=0.3'")
    return check_valence_arousal(pairs["valence"], pairs["arousal"], f"emotion {value!r}")


def point_emotion(point: Sequence[float], labels: Sequence[str],
                  points_over: Sequence[str] | None = None) -> Emotion:
    """The blend over ``labels`` of a valence/arousal ``point``.

    Args:
        point: ``(valence, arousal)``.
        labels: the labels of the result.
        points_over: the labels the point's kernel blends (default: all of ``labels``); a
            model whose extra labels are styles rather than emotions (the gait network's
            dataset-2 styles) blends a point over its emotions only.

    Raises:
        EmotionError: a bad point, or ``points_over`` not among ``labels``.
    """
    if points_over is None:
        return Emotion.from_valence_arousal(*point, labels)
    near = Emotion.from_valence_arousal(*point, points_over)
    return Emotion.from_dict(near.to_dict(), labels)


def coerce_blend(value: EmotionLike, labels: Sequence[str],
                 points_over: Sequence[str] | None = None) -> Emotion:
    """One constant emotion over ``labels``.

    :func:`coerce_emotion` of a value that does not change over time (no schedule, keyframes or
    file).

    Raises:
        EmotionError: as :func:`coerce_emotion`, or a value that changes over time.
    """
    labels = check_labels(labels)
    if isinstance(value, Emotion):
        return Emotion.from_dict(value.to_dict(), labels)
    if isinstance(value, np.ndarray):
        return Emotion(value, labels)
    if isinstance(value, str | Mapping):
        point = _point(value)
        if point is not None:
            return point_emotion(point, labels, points_over)
        if isinstance(value, Mapping):
            return Emotion.from_dict(value, labels)
        return Emotion.parse(value, labels)
    raise EmotionError(
        f"an emotion must be a name such as 'sad', weights such as 'happy=0.7,neutral=0.3', "
        f"'valence=V,arousal=A' or a mapping, got {type(value).__name__}"
    )


def coerce_emotion(value: EmotionLike, labels: Sequence[str],
                   points_over: Sequence[str] | None = None) -> EmotionSchedule:
    """Any emotion a user or a caller can give, as a schedule over a model's ``labels``.

    Args:
        value: an :class:`Emotion`; an :class:`EmotionSchedule`; a label ``"sad"``; a blend
            ``"happy=0.7,neutral=0.3"``; a point ``"valence=V,arousal=A"`` of the -1..1
            circumplex (``|V|, |A| <= VA_LIMIT``); a mapping of either; ``(C,)`` weights over
            ``labels``; a list of keyframes; or JSON keyframes as text or a path to a file.
        labels: the model's ``C`` labels. Labels of ``value`` that the model lacks must weigh
            zero.
        points_over: the labels a valence/arousal point blends (:func:`point_emotion`;
            default: all of ``labels``).

    Returns:
        The schedule over ``labels`` (one keyframe at ``t = 0`` for a constant emotion), with
        the exact valence/arousal of points given as such.

    Raises:
        EmotionError: unknown names, negative, non-finite or all-zero weights, a point outside
            the circumplex (showing the conversion from the FCRBM's old 1..3 scale), a bad
            keyframe or file, or weight on a label the model does not know.
    """
    labels = check_labels(labels)
    if isinstance(value, Emotion):
        value = EmotionSchedule.constant(value)
    if isinstance(value, EmotionSchedule):
        return value.relabel(labels)
    if isinstance(value, os.PathLike):
        return EmotionSchedule.from_json(value, labels, points_over)
    if isinstance(value, str):
        text = value.strip()
        if text.startswith("[") or text.endswith(".json") or os.sep in text:
            return EmotionSchedule.from_json(text, labels, points_over)
    if isinstance(value, Sequence) and not isinstance(value, str):
        return EmotionSchedule.from_keyframes(value, labels, points_over)
    if isinstance(value, str | Mapping):
        point = _point(value)
        if point is not None:
            return EmotionSchedule.constant(point_emotion(point, labels, points_over), point)
    return EmotionSchedule.constant(coerce_blend(value, labels, points_over))
