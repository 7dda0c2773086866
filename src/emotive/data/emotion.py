"""The project's one emotion model: weight vectors over named labels, valence/arousal, schedules.

An emotion is a normalized, non-negative weight vector ``(C,)`` over an ordered tuple of
``C`` labels. The default labels are the four emotions of the main paper (Bhattacharya et al.
2020): ``happy``, ``sad``, ``angry``, ``neutral``. Every other style of the Bandai Namco data
sets is available as an extra label; the Bandai style ``normal`` is the label ``neutral``.
Models fix their labels in their config; every function takes ``labels`` for that reason.

Text form (command line, JSON): ``"happy=0.7,neutral=0.3"`` or a single name ``"sad"``; weights
are normalized to sum to one. Unknown names, negative, NaN or infinite weights and all-zero
vectors raise :class:`~emotive.errors.EmotionError`.

Valence and arousal
-------------------
:data:`VALENCE_AROUSAL` places every label in the circumplex plane, valence (unpleasant -1 ..
+1 pleasant) on the first axis and arousal (sleepy -1 .. +1 activated) on the second. Sources:

* ``happy``, ``angry``, ``sad``, ``tired``: the direction of the same word in Russell's
  circumplex (J. A. Russell, "A circumplex model of affect", J. Pers. Soc. Psychol. 39(6),
  1161-1178, 1980; direct circular scaling of 28 affect words), on the unit circle:
  ``(cos θ, sin θ)`` with θ = 7.8° (happy), 99.0° (angry), 207.5° (sad), 267.7° (tired), as
  the angles are commonly tabulated from that paper.
* ``neutral``: the centre of the circumplex ``(0, 0)`` by definition.
* every other entry (``proud``, ``not-confident``, ``masculinity``/``masculine``,
  ``feminine``, ``childish``, ``old``/``elderly``, ``active``, ``musical``, ``giant``,
  ``chimpira``, ``exhausted``, ``youthful``): **the project's own estimates**, placed by hand
  from the meaning of the word and the Bandai Namco clips; they are not measured ratings.
  Synonyms across the two data sets share a point.

An emotion vector maps to valence/arousal as the weighted mean of its labels' points. The way
back blends the labels by a Gaussian kernel on the distance to their points,
``w_c ∝ exp(-|p - p_c|² / (2 width²))``, so a label's own point gives mostly that label.

Schedules
---------
:class:`EmotionSchedule` holds keyframes ``[{"t": 0, "emotion": {"angry": 1}},
{"t": 10, "emotion": "happy=1"}]`` (seconds; a keyframe may give ``"valence"`` and ``"arousal"``
instead of ``"emotion"``), interpolated linearly, held constant before the first and after the
last keyframe, renormalized per frame and sampled at any frame rate to ``(T, C)``. Two keyframes
at the same time make an instant switch.

Shapes: ``T`` frames, ``C`` labels, ``K`` keyframes, ``N`` query points.
"""

from __future__ import annotations

import difflib
import itertools
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.special import softmax

from emotive.errors import EmotionError

#: The main paper's four emotions, in model order.
DEFAULT_LABELS: tuple[str, ...] = ("happy", "sad", "angry", "neutral")
#: Every other style of the Bandai Namco data sets (1 and 2), as extra labels.
EXTRA_LABELS: tuple[str, ...] = (
    "proud", "not-confident", "masculinity", "feminine", "childish", "old", "tired", "active",
    "musical", "giant", "chimpira", "elderly", "exhausted", "masculine", "youthful",
)
ALL_LABELS: tuple[str, ...] = DEFAULT_LABELS + EXTRA_LABELS
#: Other names accepted for a label (data set style names).
ALIASES: dict[str, str] = {"normal": "neutral"}


@dataclass(frozen=True)
class AffectPoint:
    """A label's place in the valence/arousal plane.

    Attributes:
        valence: -1 (unpleasant) .. 1 (pleasant).
        arousal: -1 (sleepy) .. 1 (activated).
        source: ``"russell1980"``, ``"definition"`` or ``"estimate"`` (the project's own).
        angle_deg: the word's angle in Russell's circumplex, for ``"russell1980"`` entries.
    """

    valence: float
    arousal: float
    source: str
    angle_deg: float | None = None


def _russell(angle_deg: float) -> AffectPoint:
    theta = math.radians(angle_deg)
    return AffectPoint(round(math.cos(theta), 4), round(math.sin(theta), 4), "russell1980",
                       angle_deg)


#: Valence/arousal of every label; see the module docstring for the sources.
VALENCE_AROUSAL: dict[str, AffectPoint] = {
    "happy": _russell(7.8),
    "sad": _russell(207.5),
    "angry": _russell(99.0),
    "neutral": AffectPoint(0.0, 0.0, "definition"),
    "tired": _russell(267.7),
    "proud": AffectPoint(0.60, 0.40, "estimate"),
    "not-confident": AffectPoint(-0.45, -0.25, "estimate"),
    "masculinity": AffectPoint(0.10, 0.35, "estimate"),
    "masculine": AffectPoint(0.10, 0.35, "estimate"),
    "feminine": AffectPoint(0.25, 0.05, "estimate"),
    "childish": AffectPoint(0.55, 0.60, "estimate"),
    "youthful": AffectPoint(0.50, 0.45, "estimate"),
    "old": AffectPoint(-0.15, -0.55, "estimate"),
    "elderly": AffectPoint(-0.15, -0.55, "estimate"),
    "exhausted": AffectPoint(-0.45, -0.85, "estimate"),
    "active": AffectPoint(0.45, 0.80, "estimate"),
    "musical": AffectPoint(0.65, 0.50, "estimate"),
    "giant": AffectPoint(0.00, 0.25, "estimate"),
    "chimpira": AffectPoint(-0.35, 0.60, "estimate"),
}

#: Default kernel width of :func:`weights_from_valence_arousal`.
VA_KERNEL_WIDTH = 0.35


def canonical_label(name: str) -> str:
    """Normalize a user's label spelling: lower case, ``_`` as ``-``, aliases resolved."""
    key = name.strip().lower().replace("_", "-").replace(" ", "-")
    return ALIASES.get(key, key)


def style_to_label(style: str) -> str:
    """The emotion label of a data set style (``"normal"`` -> ``"neutral"``).

    Raises:
        EmotionError: the style is not a known label.
    """
    label = canonical_label(style)
    if label not in VALENCE_AROUSAL:
        raise EmotionError(
            f"style {style!r} has no emotion label; known labels: {', '.join(ALL_LABELS)}"
        )
    return label


def check_labels(labels: Sequence[str]) -> tuple[str, ...]:
    """Validate a label tuple: known names, no repeats, at least one.

    Raises:
        EmotionError: naming the bad entry.
    """
    out = tuple(canonical_label(x) for x in labels)
    if not out:
        raise EmotionError("an emotion needs at least one label, e.g. ('happy', 'sad')")
    for name in out:
        if name not in VALENCE_AROUSAL:
            raise EmotionError(_unknown_message(name, ALL_LABELS, f"labels {list(labels)}"))
    if len(set(out)) != len(out):
        dup = sorted({x for x in out if out.count(x) > 1})
        raise EmotionError(f"labels {list(labels)} repeat {dup}: give each label once")
    return out


def _unknown_message(name: str, labels: Sequence[str], where: str) -> str:
    if name in VALENCE_AROUSAL:
        return (
            f"emotion {name!r} in {where} is not one of this model's labels "
            f"({', '.join(labels)}); use one of those, or a model whose labels include {name!r}"
        )
    close = difflib.get_close_matches(name, [*labels, *ALIASES], n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown emotion {name!r} in {where}{hint}; known labels: {', '.join(labels)}"


def _normalize(weights: np.ndarray, where: str, labels: Sequence[str]) -> np.ndarray:
    """Check ``(..., C)`` weights and scale each vector to sum to one."""
    w = np.asarray(weights, dtype=np.float64)
    if w.shape[-1:] != (len(labels),):
        raise EmotionError(
            f"{where}: expected {len(labels)} weights for labels {list(labels)}, "
            f"got shape {w.shape}"
        )
    if not np.all(np.isfinite(w)):
        raise EmotionError(f"{where}: weights must be finite numbers, got {w.tolist()}")
    if np.any(w < 0):
        raise EmotionError(f"{where}: weights must be >= 0, got {w.tolist()}")
    total = w.sum(axis=-1, keepdims=True)
    if np.any(total <= 0):
        raise EmotionError(f"{where}: all weights are zero; give at least one positive weight")
    return w / total


def label_points(labels: Sequence[str] = DEFAULT_LABELS) -> np.ndarray:
    """``(C, 2)`` valence/arousal of each label."""
    labels = check_labels(labels)
    return np.array([[VALENCE_AROUSAL[x].valence, VALENCE_AROUSAL[x].arousal] for x in labels])


def valence_arousal(weights: np.ndarray, labels: Sequence[str] = DEFAULT_LABELS) -> np.ndarray:
    """Valence/arousal of emotion vectors.

    Args:
        weights: ``(..., C)`` non-negative weights (normalized here).
        labels: the ``C`` labels.

    Returns:
        ``(..., 2)`` valence and arousal: the weighted mean of the labels' points.
    """
    labels = check_labels(labels)
    return _normalize(weights, "emotion weights", labels) @ label_points(labels)


def weights_from_valence_arousal(
    va: np.ndarray, labels: Sequence[str] = DEFAULT_LABELS, width: float = VA_KERNEL_WIDTH
) -> np.ndarray:
    """Emotion vectors for valence/arousal points.

    Args:
        va: ``(..., 2)`` valence and arousal.
        labels: the ``C`` labels.
        width: kernel width in valence/arousal units; smaller gives sharper blends.

    Returns:
        ``(..., C)`` weights ``∝ exp(-|va - p_c|² / (2 width²))``, summing to one.

    Raises:
        EmotionError: ``va`` is not finite or has the wrong shape, or ``width <= 0``.
    """
    labels = check_labels(labels)
    va = np.asarray(va, dtype=np.float64)
    if va.shape[-1:] != (2,) or not np.all(np.isfinite(va)):
        raise EmotionError(f"valence/arousal must be finite (..., 2) values, got {va.tolist()}")
    if not width > 0:
        raise EmotionError(f"kernel width must be positive, got {width}")
    d2 = ((va[..., None, :] - label_points(labels)) ** 2).sum(-1)
    return softmax(-d2 / (2.0 * width**2), axis=-1)


@dataclass(frozen=True, eq=False)
class Emotion:
    """A blend of emotion labels.

    Attributes:
        weights: ``(C,)`` non-negative weights summing to one (normalized on construction).
        labels: the ``C`` labels, in model order.
    """

    weights: np.ndarray
    labels: tuple[str, ...] = DEFAULT_LABELS

    def __post_init__(self) -> None:
        labels = check_labels(self.labels)
        w = _normalize(np.asarray(self.weights, dtype=np.float64).reshape(-1), "emotion", labels)
        w.setflags(write=False)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "weights", w)

    @classmethod
    def from_dict(
        cls, mapping: Mapping[str, float], labels: Sequence[str] = DEFAULT_LABELS
    ) -> Emotion:
        """An emotion from ``{"happy": 0.7, "neutral": 0.3}``; missing labels weigh zero.

        Raises:
            EmotionError: unknown names, repeats, negative, non-finite or all-zero weights.
        """
        where = json.dumps(dict(mapping)) if _jsonable(mapping) else repr(mapping)
        return cls._from_pairs(mapping, labels, where)

    @classmethod
    def _from_pairs(
        cls, mapping: Mapping[str, Any], labels: Sequence[str], where: str
    ) -> Emotion:
        labels = check_labels(labels)
        w = np.zeros(len(labels))
        seen: set[str] = set()
        for raw, value in mapping.items():
            name = canonical_label(str(raw))
            if name not in labels:
                raise EmotionError(_unknown_message(name, labels, where))
            if name in seen:
                raise EmotionError(f"emotion {name!r} appears twice in {where}: give it once")
            seen.add(name)
            try:
                weight = float(value)
            except (TypeError, ValueError):
                raise EmotionError(
                    f"weight {value!r} of {name!r} in {where} is not a number"
                ) from None
            if not math.isfinite(weight):
                raise EmotionError(
                    f"weight of {name!r} in {where} is {weight}: use a finite number"
                )
            if weight < 0:
                raise EmotionError(
                    f"weight of {name!r} in {where} is {weight}: weights must be >= 0"
                )
            w[labels.index(name)] = weight
        if not w.any():
            raise EmotionError(
                f"all weights are zero in {where}: give at least one positive weight, "
                "e.g. 'happy=0.7,neutral=0.3'"
            )
        return cls(w, labels)

    @classmethod
    def parse(cls, text: str, labels: Sequence[str] = DEFAULT_LABELS) -> Emotion:
        """An emotion from ``"happy=0.7,neutral=0.3"`` or a single name ``"sad"``.

        ``:`` may stand for ``=``; names are case-insensitive and ``normal`` means ``neutral``.

        Raises:
            EmotionError: empty or malformed text, or the errors of :meth:`from_dict`.
        """
        if not text or not text.strip():
            raise EmotionError(
                "empty emotion: give a name such as 'happy' or weights such as "
                "'happy=0.7,neutral=0.3'"
            )
        pairs: dict[str, Any] = {}
        for item in text.split(","):
            item = item.strip()
            if not item:
                raise EmotionError(f"empty entry in emotion {text!r}: remove the extra comma")
            sep = "=" if "=" in item else ":" if ":" in item else None
            name, value = (item.split(sep, 1) if sep else (item, "1"))
            name, value = name.strip(), value.strip()
            if not name:
                raise EmotionError(f"entry {item!r} of emotion {text!r} has no name")
            try:
                weight = float(value)
            except ValueError:
                raise EmotionError(
                    f"weight {value!r} of {name!r} in emotion {text!r} is not a number"
                ) from None
            key = canonical_label(name)
            if key in pairs:
                raise EmotionError(f"emotion {key!r} appears twice in {text!r}: give it once")
            pairs[key] = weight
        return cls._from_pairs(pairs, labels, repr(text))

    @classmethod
    def one_hot(cls, name: str, labels: Sequence[str] = DEFAULT_LABELS) -> Emotion:
        """All weight on one label (a data set style name is accepted: ``normal``)."""
        return cls.from_dict({name: 1.0}, labels)

    @classmethod
    def from_valence_arousal(
        cls,
        valence: float,
        arousal: float,
        labels: Sequence[str] = DEFAULT_LABELS,
        width: float = VA_KERNEL_WIDTH,
    ) -> Emotion:
        """The blend of labels near a point (see :func:`weights_from_valence_arousal`)."""
        weights = weights_from_valence_arousal(np.array([valence, arousal]), labels, width)
        return cls(weights, labels)

    def valence_arousal(self) -> np.ndarray:
        """``(2,)`` valence and arousal of this blend."""
        return valence_arousal(self.weights, self.labels)

    def to_dict(self) -> dict[str, float]:
        """``{label: weight}`` of the labels with non-zero weight."""
        return {n: float(w) for n, w in zip(self.labels, self.weights, strict=True) if w > 0}

    @property
    def dominant(self) -> str:
        """The label with the largest weight."""
        return self.labels[int(np.argmax(self.weights))]

    def __getitem__(self, name: str) -> float:
        key = canonical_label(name)
        if key not in self.labels:
            raise EmotionError(_unknown_message(key, self.labels, "this emotion"))
        return float(self.weights[self.labels.index(key)])

    def __str__(self) -> str:
        return ",".join(f"{n}={w:.3g}" for n, w in self.to_dict().items())


def _jsonable(value: Any) -> bool:
    try:
        json.dumps(dict(value))
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True, eq=False)
class EmotionSchedule:
    """Emotion over time, by linear interpolation between keyframes.

    Attributes:
        times: ``(K,)`` keyframe times in seconds, non-decreasing, from 0.
        weights: ``(K, C)`` normalized emotion at each keyframe.
        labels: the ``C`` labels.
    """

    times: np.ndarray
    weights: np.ndarray
    labels: tuple[str, ...] = DEFAULT_LABELS

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
        weights = _normalize(np.asarray(self.weights, dtype=np.float64), "keyframes", labels)
        if weights.shape != (len(times), len(labels)):
            raise EmotionError(
                f"expected keyframe weights of shape ({len(times)}, {len(labels)}), "
                f"got {weights.shape}"
            )
        for name, value in (("times", times), ("weights", weights), ("labels", labels)):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def constant(cls, emotion: Emotion) -> EmotionSchedule:
        """The same emotion at every time."""
        return cls(np.zeros(1), emotion.weights[None], emotion.labels)

    @classmethod
    def from_keyframes(
        cls, keyframes: Sequence[Mapping[str, Any]], labels: Sequence[str] = DEFAULT_LABELS
    ) -> EmotionSchedule:
        """A schedule from ``[{"t": 0, "emotion": {"angry": 1}}, {"t": 10, "emotion": "happy"}]``.

        Each keyframe has ``t`` (seconds) and either ``emotion`` (a mapping or the text form of
        :meth:`Emotion.parse`) or ``valence`` and ``arousal``.

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
        times, rows = [], []
        for k, frame in enumerate(keyframes):
            where = f"keyframe {k} ({json.dumps(frame) if _jsonable(frame) else frame!r})"
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
                    emotion = Emotion.from_valence_arousal(
                        float(frame["valence"]), float(frame["arousal"]), labels
                    )
                else:
                    raise EmotionError('give "emotion", or "valence" and "arousal"')
            except EmotionError as exc:
                raise EmotionError(f"{where}: {exc}") from None
            except (TypeError, ValueError):
                raise EmotionError(f"{where}: valence and arousal must be numbers") from None
            times.append(t)
            rows.append(emotion.weights)
        if any(b < a for a, b in itertools.pairwise(times)):
            raise EmotionError(f"keyframe times {times} decrease: sort the keyframes by t")
        return cls(np.array(times), np.stack(rows), labels)

    @classmethod
    def from_json(
        cls, source: str | os.PathLike, labels: Sequence[str] = DEFAULT_LABELS
    ) -> EmotionSchedule:
        """A schedule from JSON text or a ``.json`` file holding a list of keyframes.

        Raises:
            EmotionError: the file is missing or not valid JSON, or a keyframe is bad.
        """
        text = str(source)
        where = "emotion schedule"
        if not text.lstrip().startswith("["):
            path = Path(text)
            where = str(path)
            try:
                text = path.read_text()
            except OSError as exc:
                raise EmotionError(
                    f"emotion schedule {path} cannot be read ({exc.strerror}): check the path"
                ) from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise EmotionError(f"{where} is not valid JSON ({exc})") from None
        try:
            return cls.from_keyframes(data, labels)
        except EmotionError as exc:
            raise EmotionError(f"{where}: {exc}") from None

    @classmethod
    def parse(cls, spec: str, labels: Sequence[str] = DEFAULT_LABELS) -> EmotionSchedule:
        """A schedule from a command-line value: JSON keyframes, a ``.json`` path or an emotion.

        ``"happy=0.7,neutral=0.3"`` gives a constant schedule.
        """
        text = spec.strip()
        if text.startswith("[") or text.endswith(".json") or os.sep in text:
            return cls.from_json(text, labels)
        return cls.constant(Emotion.parse(text, labels))

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
        flat = t.reshape(-1)
        k = len(self.times)
        # Index of the first keyframe after each query; equal times switch instantly.
        hi = np.clip(np.searchsorted(self.times, flat, side="right"), 1, k - 1) if k > 1 else None
        if hi is None:
            out = np.broadcast_to(self.weights[0], (len(flat), self.weights.shape[1])).copy()
        else:
            lo = hi - 1
            span = self.times[hi] - self.times[lo]
            safe = np.where(span > 0, span, 1.0)
            alpha = np.clip(np.where(span > 0, (flat - self.times[lo]) / safe, 1.0), 0.0, 1.0)
            alpha[flat < self.times[0]] = 0.0
            out = (1 - alpha)[:, None] * self.weights[lo] + alpha[:, None] * self.weights[hi]
        out /= out.sum(axis=-1, keepdims=True)
        return out.reshape((*t.shape, -1))

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

    def to_keyframes(self) -> list[dict[str, Any]]:
        """The keyframes as JSON-ready dicts (inverse of :meth:`from_keyframes`)."""
        return [
            {"t": float(t), "emotion": Emotion(w, self.labels).to_dict()}
            for t, w in zip(self.times, self.weights, strict=True)
        ]
