"""What a caller gives a gait agent, checked and coerced: its emotion and its pace.

Shared by :class:`~emotive.models.gait.generate.GaitGenerator` and everything that feeds it
(the live server checks messages against the same range and blends points the same way).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from emotive.data.emotion import DEFAULT_LABELS, EmotionLike, EmotionSchedule, coerce_emotion

#: Allowed per-agent pace factors (times the emotion's walking speed).
PACE_RANGE = (0.5, 1.5)


def check_pace(pace: float) -> float:
    """``pace`` as a float if it lies in :data:`PACE_RANGE`.

    Raises:
        ValueError: outside the range or not finite.
    """
    lo, hi = PACE_RANGE
    if not (math.isfinite(pace) and lo <= pace <= hi):
        raise ValueError(f"pace must be between {lo:g} and {hi:g} times the emotion's walking "
                         f"speed, got {pace!r}")
    return float(pace)


def point_labels(labels: Sequence[str]) -> tuple[str, ...] | None:
    """The labels a valence/arousal point blends for a network with ``labels``.

    The four emotions it knows (happy, sad, angry, neutral), not the dataset-2 styles; ``None``
    (all labels) for a network that knows none of them.
    """
    return tuple(label for label in DEFAULT_LABELS if label in labels) or None


def to_model_schedule(emotion: EmotionLike, labels: Sequence[str]) -> EmotionSchedule:
    """An emotion or schedule over the model's ``labels``.

    Accepts what :func:`~emotive.data.emotion.coerce_emotion` accepts: an ``Emotion``, an
    ``EmotionSchedule``, text such as ``"happy=0.7,neutral=0.3"`` or
    ``"valence=0.5,arousal=0.2"``, a mapping, ``(C,)`` weights over ``labels``, keyframes or a
    JSON file of them. Labels of the input that the model lacks must weigh zero.

    A valence/arousal point blends the four emotions only (:func:`point_labels`), not
    the dataset-2 styles the network also knows: styles such as ``chimpira`` or ``active``
    sit near the emotions on the circumplex, and blending them in made angry's own point read
    as happy to the classifier (P(angry) 0.06 against 0.89 for the label).

    Raises:
        EmotionError: unknown names, negative, NaN or all-zero weights, or weight on a label
            the model was not trained with.
    """
    return coerce_emotion(emotion, labels, points_over=point_labels(labels))
