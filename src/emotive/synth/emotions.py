"""Novel emotions, the pairs walked as transitions, and each walk's emotion schedule.

The main paper's augmented data set walks "100 emotions, also not present in the dataset"
and "transitions between 50 pairs of emotions on each trajectory, picking a pair of emotions
from the 100 novel ones without replacement" (Bhattacharya et al. 2020, section 5.2). The
data's emotions are the corners of the blend simplex (one label per clip); a novel emotion is
drawn away from them:

* for models of label blends (the gait network): weights over happy, sad, angry, neutral
  drawn uniformly on the simplex (a flat Dirichlet) and drawn again while any weight is
  above :data:`MAX_WEIGHT` (so every blend is at least ``2 (1 - MAX_WEIGHT)`` in L1 from
  every corner);
* for models driven by valence and arousal (the FCRBM): a point uniform in the disc of
  radius :data:`VA_RADIUS` of the -1..1 circumplex, drawn again while it is within
  :data:`VA_CLEARANCE` of the point of any label of the data's styles
  (:data:`emotive.data.emotion.VALENCE_AROUSAL`).

Emotion ``e`` draws from a generator seeded ``[seed, 2, e]``; trajectory ``p``'s pairs are
the first ``K`` disjoint pairs of a permutation of the ``E`` emotions seeded ``[seed, 3, p]``;
a transition's time from ``[seed, 4, i]`` (sample ``i``), uniform in :data:`SWITCH_SHARE` of
the walk, where the emotion moves linearly from the first to the second over
:data:`RAMP_SECONDS` (at most a fifth of the walk).

Legend: ``C`` labels (happy, sad, angry, neutral).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from emotive.data.emotion import (
    DEFAULT_LABELS,
    VALENCE_AROUSAL,
    valence_arousal,
    weights_from_valence_arousal,
)

#: Labels of the blends (the paper's four emotions).
LABELS = DEFAULT_LABELS
#: Largest weight of any label in a novel blend.
MAX_WEIGHT = 0.7
#: Radius of the disc novel valence/arousal points are drawn in.
VA_RADIUS = 0.9
#: Least distance of a novel valence/arousal point from any labelled style's point.
VA_CLEARANCE = 0.2
#: Share of the walk at which a transition starts, ``(low, high)``.
SWITCH_SHARE = (0.4, 0.6)
#: Seconds a transition takes (at most a fifth of the walk).
RAMP_SECONDS = 1.0
#: Seed streams (the second entry of the generators' seeds).
EMOTION_STREAM, PAIR_STREAM, SWITCH_STREAM = 2, 3, 4
#: Draws before giving up (never reached: about 9 in 10 blends and half the points pass).
MAX_DRAWS = 10_000


def ranges() -> dict[str, Any]:
    """The choices above, for the recipe and the data set card."""
    return {"labels": list(LABELS), "max_weight": MAX_WEIGHT, "va_radius": VA_RADIUS,
            "va_clearance": VA_CLEARANCE, "switch_share": list(SWITCH_SHARE),
            "ramp_seconds": RAMP_SECONDS}


@dataclass(frozen=True)
class NovelEmotion:
    """One novel emotion.

    Attributes:
        index: emotion index ``e``.
        weights: ``(C,)`` weights over :data:`LABELS`, summing to one.
        valence: valence in -1..1.
        arousal: arousal in -1..1.
        point: whether it was drawn as a valence/arousal point (the weights are then the
            circumplex's kernel blend of the point).
    """

    index: int
    weights: tuple[float, ...]
    valence: float
    arousal: float
    point: bool

    def keyframe(self, t: float) -> dict[str, Any]:
        """A keyframe of :func:`emotive.data.emotion.coerce_emotion` at ``t`` seconds."""
        if self.point:
            return {"t": t, "valence": self.valence, "arousal": self.arousal}
        return {"t": t, "emotion": dict(zip(LABELS, self.weights, strict=True))}


def novel_emotion(seed: int, index: int, point: bool) -> NovelEmotion:
    """Emotion ``index`` of a recipe with ``seed`` (module docstring).

    Args:
        seed: the recipe's seed.
        index: emotion index ``e >= 0``.
        point: draw a valence/arousal point (models driven by them) instead of a blend.
    """
    rng = np.random.default_rng([seed, EMOTION_STREAM, index])
    if point:
        labelled = np.array([[p.valence, p.arousal] for p in VALENCE_AROUSAL.values()])
        for _ in range(MAX_DRAWS):
            r, a = VA_RADIUS * np.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * np.pi)
            va = np.array([r * np.cos(a), r * np.sin(a)])
            if np.linalg.norm(labelled - va, axis=1).min() >= VA_CLEARANCE:
                break
        w = weights_from_valence_arousal(va, LABELS)
        return NovelEmotion(index, tuple(w.tolist()), float(va[0]), float(va[1]), True)
    for _ in range(MAX_DRAWS):
        w = rng.dirichlet(np.ones(len(LABELS)))
        if w.max() <= MAX_WEIGHT:
            break
    va = valence_arousal(w, LABELS)
    return NovelEmotion(index, tuple(w.tolist()), float(va[0]), float(va[1]), False)


def pairs(seed: int, path: int, emotions: int, count: int) -> np.ndarray:
    """``(count, 2)`` emotion indices of trajectory ``path``'s transitions (disjoint pairs).

    Args:
        seed: the recipe's seed.
        path: trajectory index.
        emotions: ``E``.
        count: ``K``, at most ``E // 2``.
    """
    order = np.random.default_rng([seed, PAIR_STREAM, path]).permutation(emotions)
    return order[:2 * count].reshape(count, 2)


def switch_time(seed: int, sample: int, seconds: float) -> tuple[float, float]:
    """``(start, ramp)`` of sample ``sample``'s transition, seconds."""
    rng = np.random.default_rng([seed, SWITCH_STREAM, sample])
    return float(seconds * rng.uniform(*SWITCH_SHARE)), min(RAMP_SECONDS, 0.2 * seconds)


def schedule_keyframes(first: NovelEmotion, second: NovelEmotion | None = None,
                       start: float = 0.0, ramp: float = 0.0) -> list[dict[str, Any]]:
    """Keyframes of a walk: constant ``first``, or ``first`` then ``second`` from ``start``."""
    if second is None:
        return [first.keyframe(0.0)]
    return [first.keyframe(0.0), first.keyframe(start), second.keyframe(start + ramp)]
