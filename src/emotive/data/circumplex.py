"""The emotion labels and their place in the valence/arousal circumplex.

The default labels are the four emotions of the main paper (Bhattacharya et al. 2020):
``happy``, ``sad``, ``angry``, ``neutral``. Every other style of the Bandai Namco data sets is
available as an extra label; the Bandai style ``normal`` is the label ``neutral``. The emotion
types built on these (:class:`~emotive.data.emotion.Emotion`,
:class:`~emotive.data.emotion.EmotionSchedule`) live in :mod:`emotive.data.emotion`, which
re-exports every name of this module.

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
Points within :data:`VA_LIMIT` of the centre on each axis, the -1..1 scale, are accepted;
:func:`check_valence_arousal` refuses the rest, never clamps them, and shows the conversion from
the FCRBM's old 1..3 scale.

Shapes: ``C`` labels.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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
            raise EmotionError(unknown_label_message(name, ALL_LABELS, f"labels {list(labels)}"))
    if len(set(out)) != len(out):
        dup = sorted({x for x in out if out.count(x) > 1})
        raise EmotionError(f"labels {list(labels)} repeat {dup}: give each label once")
    return out


def unknown_label_message(name: str, labels: Sequence[str], where: str) -> str:
    """The error message for an emotion ``name`` that is not one of ``labels``."""
    if name in VALENCE_AROUSAL:
        return (
            f"emotion {name!r} in {where} is not one of this model's labels "
            f"({', '.join(labels)}); use one of those, or a model whose labels include {name!r}"
        )
    close = difflib.get_close_matches(name, [*labels, *ALIASES], n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"unknown emotion {name!r} in {where}{hint}; known labels: {', '.join(labels)}"


def normalize_weights(weights: np.ndarray, where: str, labels: Sequence[str]) -> np.ndarray:
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
    with np.errstate(over="ignore"):
        total = w.sum(axis=-1, keepdims=True)
    if not np.all(np.isfinite(total)):
        # Finite weights whose sum overflows (1e308 + 1e308): scale by the largest first.
        w = w / w.max(axis=-1, keepdims=True)
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
    return normalize_weights(weights, "emotion weights", labels) @ label_points(labels)


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
    # A softmax of -d2 / (2 width^2), written out: scipy's import costs the command line 0.3 s
    # before it can check its arguments. The nearest label's term is 1, so the sum is >= 1.
    logits = -d2 / (2.0 * width**2)
    weights = np.exp(logits - logits.max(axis=-1, keepdims=True))
    return weights / weights.sum(axis=-1, keepdims=True)


#: Largest accepted ``|valence|`` and ``|arousal|``: the circumplex's one scale, -1..1.
VA_LIMIT = 1.0


def check_valence_arousal(valence: float, arousal: float, where: str = "") -> tuple[float, float]:
    """Validate a valence/arousal point on the toolkit's -1..1 circumplex.

    Args:
        valence: -1 (unpleasant) .. 1 (pleasant).
        arousal: -1 (sleepy) .. 1 (activated).
        where: what the point belongs to, for the message (e.g. ``"keyframe 2"``).

    Returns:
        ``(valence, arousal)`` as floats.

    Raises:
        EmotionError: a value that is not a finite number within ``-VA_LIMIT..VA_LIMIT``
            (refused, never clamped); for a value that fits the FCRBM's old 1..3 scale the
            message shows it converted.
    """
    prefix = f"{where}: " if where else ""
    scale = f"-{VA_LIMIT:g}..{VA_LIMIT:g}"
    out = []
    for name, value in (("valence", valence), ("arousal", arousal)):
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise EmotionError(f"{prefix}{name}={value!r} is not a number; give a value "
                               f"in {scale}, e.g. {name}=0.5") from None
        if not math.isfinite(x):
            raise EmotionError(f"{prefix}{name}={x} is not finite; give a value in {scale}")
        if abs(x) > VA_LIMIT:
            hint = (f"; if you meant the old FCRBM 1..3 scale, subtract 2: {name}={x - 2:g}"
                    if abs(x - 2) <= VA_LIMIT else f"; give a value in {scale}")
            raise EmotionError(f"{prefix}{name}={x:g} is outside {scale}" + hint)
        out.append(x)
    return out[0], out[1]
