"""The emotion-to-navigation table: personal space and willingness to yield from an emotion.

One table, :data:`TABLE`, gives the per-agent navigation parameters of JuPedSim's
operational models (the anticipation velocity model and the collision-free speed model V2
name them alike) at the four emotions of the main paper. An agent's emotion (weights over the
model's labels) is placed in the valence/arousal circumplex
(:func:`emotive.data.emotion.valence_arousal`), blended over the four rows by the project's
own kernel (:func:`emotive.data.emotion.weights_from_valence_arousal`), and the rows are mixed
by those weights; so a blend, a valence/arousal point and a dataset-2 style all get
parameters from the same four rows.

The desired speed is not in the table: it is the gait network's own walking pace for the
emotion, ``(m @ controls.speed) * fps * pace`` (:class:`~emotive.models.gait.controls.GaitControls`,
the median walking speed per label in the training data), so navigation never asks a body to
walk faster or slower than the network walks with that emotion.

Columns (see ``docs/crowd.md`` for the sources):

* ``radius`` (m): the navigation disc, the agent's personal space; bodies keep about twice
  it between their hips.
* ``time_gap`` (s): the headway the model keeps to the agent ahead (``v = (s - l) / T``).
* ``yield_strength``: the model's neighbour repulsion strength; a larger value turns the
  agent aside sooner (it yields), a smaller one keeps its line (others yield).
* ``yield_range`` (m): the range of that repulsion.

Every number is **our choice**; what rests on the literature is the direction of each change
from neutral (neutral itself is JuPedSim's default agent, except a radius widened from 0.2 m
to 0.25 m and a repulsion range from 0.1 m to 0.25 m, so that agents step aside earlier and
hips stay 0.3 m apart with the body's tracking error):

* Durupinar et al. 2011 (OCEAN in HiDAC, IEEE CG&A 31(3)): extraverted agents accept smaller
  personal distances and walk faster; agreeable agents wait and give way rather than push.
  We read happy as the extraverted, agreeable end: a smaller radius and time gap, yielding as
  neutral.
* Bera et al. 2017 (personality from crowd videos, IJCAI): aggressive pedestrians plan over
  shorter horizons with smaller personal space; shy and tense ones keep larger distances. We
  read angry as aggressive (smallest time gap) and sad as shy (largest radius and time gap).
* Randhavane et al. 2019 (pedestrian dominance, ICRA): dominant pedestrians keep their path
  and others move aside; submissive ones give way. We read angry as dominant (weakest
  repulsion: it yields least) and sad as submissive (strongest repulsion: it yields most).

Legend: ``C`` emotion labels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.data.emotion import DEFAULT_LABELS, valence_arousal, weights_from_valence_arousal

__all__ = ["COLUMNS", "TABLE", "NavParams", "engine_parameters", "navigation_params",
           "navigation_rows", "navigation_table"]

#: Parameter names, in table order.
COLUMNS = ("radius", "time_gap", "yield_strength", "yield_range")
#: One row per emotion of the main paper (all values our choice; directions from the sources
#: in the module docstring). Neutral is JuPedSim's default agent, radius widened to 0.25 m
#: and repulsion range to 0.25 m (earlier side steps, measured in docs/crowd.md).
TABLE: dict[str, tuple[float, float, float, float]] = {
    #          radius  time_gap  yield_strength  yield_range
    "neutral": (0.25, 1.00, 8.0, 0.25),
    "happy": (0.23, 0.85, 8.0, 0.22),
    "sad": (0.30, 1.40, 12.0, 0.35),
    "angry": (0.22, 0.60, 4.0, 0.15),
}


@dataclass(frozen=True)
class NavParams:
    """Navigation parameters of one agent.

    Attributes:
        desired_speed: m/s, the gait's walking pace for the emotion times the pace factor.
        radius: m, personal space.
        time_gap: s, headway to the agent ahead.
        yield_strength: neighbour repulsion strength (larger yields more).
        yield_range: m, neighbour repulsion range.
    """

    desired_speed: float
    radius: float
    time_gap: float
    yield_strength: float
    yield_range: float


def _rows() -> np.ndarray:
    """``(4, 4)`` the table in :data:`DEFAULT_LABELS` order."""
    return np.array([TABLE[label] for label in DEFAULT_LABELS], dtype=np.float64)


def navigation_params(weights: np.ndarray, labels: Sequence[str], walk_speed: np.ndarray,
                      pace: float = 1.0) -> NavParams:
    """The navigation parameters of an emotion.

    Args:
        weights: ``(C,)`` emotion weights over ``labels``.
        labels: the model's ``C`` labels.
        walk_speed: ``(C,)`` the gait model's walking speed per label, m/s.
        pace: the agent's factor on its emotion's walking speed.

    Returns:
        The parameters (speed from the gait, the rest from :data:`TABLE`).
    """
    row = navigation_rows(np.asarray(weights, dtype=np.float64)[None], labels, walk_speed,
                          np.array([pace], dtype=np.float64))[0]
    return NavParams(*(float(x) for x in row))


def navigation_rows(weights: np.ndarray, labels: Sequence[str], walk_speed: np.ndarray,
                    pace: np.ndarray) -> np.ndarray:
    """:func:`navigation_params` of ``B`` agents at once.

    Args:
        weights: ``(B, C)`` emotion weights.
        labels: the ``C`` labels.
        walk_speed: ``(C,)`` walking speed per label, m/s.
        pace: ``(B,)`` pace factors.

    Returns:
        ``(B, 5)`` desired speed then the :data:`COLUMNS`, the fields of :class:`NavParams`.
    """
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum(-1, keepdims=True)
    mix = weights_from_valence_arousal(valence_arousal(w, labels), DEFAULT_LABELS) @ _rows()
    speed = (w @ np.asarray(walk_speed, dtype=np.float64)) * np.asarray(pace, dtype=np.float64)
    return np.concatenate((speed[:, None], mix), 1)


#: ``yield_strength`` of the neutral row and the change of one engine priority step: the
#: engines' priorities are set by the same ordering as the table's yielding (see
#: :func:`engine_parameters`).
NEUTRAL_YIELD = TABLE["neutral"][2]
PRIORITY_PER_YIELD = 10.0


def engine_parameters(params: NavParams) -> dict[str, dict[str, float]]:
    """One agent's parameters as the game engines' crowd agents name them.

    The mapping is ours (``docs/runtime.md``): speed and radius carry over in the engine's
    units; the yielding becomes a priority (Unity's ``avoidancePriority``, 0 most important to
    99, 50 by default; Godot's ``avoidance_priority``, 0 to 1, where a higher one is avoided by
    the others) or a scale of the separation weight (Unreal's Detour crowd); the time gap is
    Godot's ``time_horizon_agents``, which Unity and Unreal lack.

    Args:
        params: the agent's parameters (:func:`navigation_params`).

    Returns:
        ``{"unity": ..., "unreal": ..., "godot": ...}``, each a dict of property values.
    """
    unity = int(np.clip(round(50 + PRIORITY_PER_YIELD * (params.yield_strength - NEUTRAL_YIELD)),
                        0, 99))
    engines = {
        "unity": {"speed": params.desired_speed, "radius": params.radius,
                  "avoidancePriority": unity},
        "unreal": {"MaxWalkSpeed": 100.0 * params.desired_speed,
                   "AgentRadius": 100.0 * params.radius,
                   "CrowdSeparationWeightScale": params.yield_strength / NEUTRAL_YIELD,
                   "CrowdCollisionQueryRangeScale": params.yield_range / TABLE["neutral"][3]},
        "godot": {"max_speed": params.desired_speed, "radius": params.radius,
                  "avoidance_priority": round(1.0 - unity / 99.0, 4),
                  "time_horizon_agents": params.time_gap},
    }
    return {engine: {k: round(float(v), 4) if isinstance(v, float) else v
                     for k, v in values.items()} for engine, values in engines.items()}


def navigation_table(labels: Sequence[str], walk_speed: np.ndarray) -> dict:
    """The emotion-to-navigation table of a model, as the exported ``agent.json`` carries it.

    Args:
        labels: the model's ``C`` labels.
        walk_speed: ``(C,)`` the gait model's walking speed per label, m/s.

    Returns:
        ``columns`` (the fields of :class:`NavParams`), ``rows`` (each label's values, its
        desired speed the gait's own pace), ``engines`` (each label's
        :func:`engine_parameters`) and ``blend``: how a blend or a valence/arousal point gets
        its row.
    """
    rows, engines = {}, {}
    for k, label in enumerate(labels):
        params = navigation_params(np.eye(len(labels))[k], labels, walk_speed)
        rows[label] = [round(float(v), 4) for v in vars(params).values()]
        engines[label] = engine_parameters(params)
    return {"columns": list(NavParams.__dataclass_fields__), "rows": rows, "engines": engines,
            "blend": "the rows of happy, sad, angry and neutral mixed by the valence/arousal "
                     "kernel of `emotion` (points, kernel_width); the desired speed is the "
                     "emotion weights times each label's desired speed, times the pace"}
