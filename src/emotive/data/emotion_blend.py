"""One constant emotion: a normalized weight vector over named labels.

:class:`Emotion` is the blend the project's one emotion model (:mod:`emotive.data.emotion`)
builds schedules from: parsed from text (``"happy=0.7,neutral=0.3"``, ``"sad"``), from a
mapping, or from a valence/arousal point of the -1..1 circumplex
(:mod:`emotive.data.circumplex`). Import it from :mod:`emotive.data.emotion`.

Shapes: ``C`` labels.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from emotive.data.circumplex import (
    DEFAULT_LABELS,
    VA_KERNEL_WIDTH,
    canonical_label,
    check_labels,
    normalize_weights,
    unknown_label_message,
    valence_arousal,
    weights_from_valence_arousal,
)
from emotive.errors import EmotionError


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
        w = normalize_weights(np.asarray(self.weights, dtype=np.float64).reshape(-1), "emotion",
                              labels)
        w.setflags(write=False)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "weights", w)

    @classmethod
    def from_dict(
        cls, mapping: Mapping[str, float], labels: Sequence[str] = DEFAULT_LABELS
    ) -> Emotion:
        """An emotion from ``{"happy": 0.7, "neutral": 0.3}``; missing labels weigh zero.

        Each weight is from 0 to 1; the blend is scaled to sum to one.

        Raises:
            EmotionError: unknown names, repeats, weights outside 0..1, non-finite or all-zero
                weights.
        """
        where = json.dumps(dict(mapping)) if jsonable(mapping) else repr(mapping)
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
                raise EmotionError(unknown_label_message(name, labels, where))
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
            if not 0 <= weight <= 1:
                raise EmotionError(
                    f"weight of {name!r} in {where} is {weight:g}, outside 0..1: give each "
                    "label a weight from 0 to 1 (a blend is then scaled to sum to 1), e.g. "
                    "'happy=0.7,neutral=0.3'"
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
        Each weight is from 0 to 1 (``"happy=2"`` is refused, not read as ``happy=1``).
        A name without a weight stands for weight 1 only when it is alone: in a blend every
        label needs its weight (``"happy=0.7,sad"`` is an error, not ``sad=1``).

        Raises:
            EmotionError: empty or malformed text, a blend entry without a weight, or the
                errors of :meth:`from_dict`.
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
            if sep is None and "," in text:
                raise EmotionError(
                    f"entry {item!r} of the blend {text!r} has no weight: give every label of a "
                    f"blend one, e.g. '{item}=0.3', or give a single name alone"
                )
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
            raise EmotionError(unknown_label_message(key, self.labels, "this emotion"))
        return float(self.weights[self.labels.index(key)])

    def __str__(self) -> str:
        return ",".join(f"{n}={w:.3g}" for n, w in self.to_dict().items())


def jsonable(value: Any) -> bool:
    """Whether ``dict(value)`` can be written as JSON (for messages that quote it)."""
    try:
        json.dumps(dict(value))
    except (TypeError, ValueError):
        return False
    return True
