"""The simulated raters of ``emotive study simulate``: who is careless, and what each answers.

A careful rater's answers are drawn from the classifier's reading of the stimulus
(``stimuli/readings.json``: label probabilities, valence and arousal), else from the
stimulus's intended emotion, else from a uniform blend, with rater noise (a personal noise
level, bias and choice temperature, plus Gaussian noise per answer):

* a likert question named after a label: ``min + (max - min) * p_label`` plus noise;
* ``valence`` / ``arousal`` likert: the reading's -1..1 value mapped onto the scale, plus noise;
  ``naturalness``: three quarters up the scale (4 of 1..5), plus noise; ``confidence``: the
  upper half of the scale (3 to 5 of 1..5); any other likert: the middle, plus noise;
* a choice among labels: drawn from the probabilities sharpened or flattened by the rater's
  temperature; any other choice: uniform;
* a grid: the cell of the reading's valence (column) and arousal (row), plus noise;
* an attention check: exactly the answers it expects (the check is found by its position in
  the plan, :func:`emotive.study.design.plan_for`, and its instruction text).

A ``careless`` share of raters (drawn per participant) answer every question uniformly at
random and fast (``rt_ms`` 0.3 to 1.5 s), attention checks included; an answer that happens
to pass a check is drawn again, so that every careless rater who reaches a check fails it.
Every draw is a function of ``(seed, participant index in the simulation, item)``, so a run is
reproducible given the order in which the server admits the participants (with
``concurrency=1``, exactly).
"""

from __future__ import annotations

import contextlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from emotive.data.emotion import DEFAULT_LABELS
from emotive.errors import EmotionError
from emotive.study.config import GRID_VALUES, AttentionCheck, Question, StudyConfig

#: Redraws of a careless answer that happens to pass an attention check.
CARELESS_REDRAWS = 50
#: Range of a rater's noise, as a fraction of a scale's range (standard deviation).
NOISE_RANGE = (0.08, 0.2)
#: Standard deviation of a rater's bias, fraction of a scale's range.
BIAS_SD = 0.04
#: Range of a rater's choice temperature (1: the classifier's probabilities as they are).
TEMPERATURE_RANGE = (0.7, 1.5)
#: Where ``naturalness`` sits on its scale for a careful rater (4 of 1..5).
NATURALNESS = 0.75
#: Response times of careless raters, milliseconds.
CARELESS_RT_MS = (300, 1500)
#: Stream numbers of the random draws (mixed into the seed with the participant index).
_TRAITS, _JITTER, _ITEM = 0, 1, 2


@dataclass(frozen=True)
class Reading:
    """What a careful rater perceives in a stimulus.

    Attributes:
        probabilities: label -> probability (summing to 1).
        valence: -1..1.
        arousal: -1..1.
        unsure: the classifier was unsure (raters answer less consistently).
    """

    probabilities: dict[str, float]
    valence: float
    arousal: float
    unsure: bool = False


@dataclass(frozen=True)
class Rater:
    """One simulated participant's traits.

    Attributes:
        index: the participant's index in the simulation (0, 1, ...).
        careless: answers everything at random, fast.
        noise: standard deviation of the answer noise, fraction of a scale's range.
        bias: constant shift of every scale answer, fraction of a scale's range.
        temperature: of forced choices (> 1 flattens the probabilities).
    """

    index: int
    careless: bool
    noise: float
    bias: float
    temperature: float


def _rng(seed: int, *keys: int) -> np.random.Generator:
    return np.random.default_rng([seed % 2**63, *keys])


def rater_for(seed: int, index: int, careless: float) -> Rater:
    """The traits of the ``index``-th simulated participant (a function of ``seed, index``).

    Args:
        seed: the simulation's seed.
        index: the participant's index in the simulation.
        careless: share of careless raters, 0..1.
    """
    rng = _rng(seed, index, _TRAITS)
    is_careless = bool(rng.random() < careless)
    return Rater(index, is_careless, float(rng.uniform(*NOISE_RANGE)),
                 float(rng.normal(0.0, BIAS_SD)), float(rng.uniform(*TEMPERATURE_RANGE)))


def stimulus_reading(study: StudyConfig, readings: Mapping[str, Any] | None,
                     stimulus: str) -> Reading:
    """The reading a careful rater answers from (see the module docstring).

    Args:
        study: the study.
        readings: the parsed ``stimuli/readings.json``, or ``None``.
        stimulus: the stimulus id.
    """
    entry = ((readings or {}).get("stimuli") or {}).get(stimulus)
    if isinstance(entry, Mapping) and isinstance(entry.get("probabilities"), Mapping):
        labels = (readings or {}).get("labels") or DEFAULT_LABELS
        probs = dict.fromkeys(map(str, labels), 0.0)
        probs.update({str(k): max(float(v), 0.0) for k, v in entry["probabilities"].items()})
        total = sum(probs.values())
        if total > 0:
            return Reading({k: v / total for k, v in probs.items()},
                           float(entry.get("valence", 0.0)), float(entry.get("arousal", 0.0)),
                           bool(entry.get("unsure", False)))
    intended = None
    with contextlib.suppress(KeyError, EmotionError):
        intended = study.stimulus(stimulus).intended_emotion()
    if intended is not None:
        valence, arousal = (float(x) for x in intended.valence_arousal())
        weights = dict(zip(intended.labels, map(float, intended.weights), strict=True))
        return Reading(weights, valence, arousal)
    return Reading(dict.fromkeys(DEFAULT_LABELS, 1.0 / len(DEFAULT_LABELS)), 0.0, 0.0)


def _scale(question: Question, fraction: float, rater: Rater, noise: float,
           rng: np.random.Generator) -> int:
    shifted = fraction + rater.bias + rng.normal(0.0, noise)
    value = round(question.min + (question.max - question.min) * shifted)
    return int(np.clip(value, question.min, question.max))


def _cell(point: float, size: int, rater: Rater, noise: float, rng: np.random.Generator) -> int:
    shifted = (point + 1.0) / 2.0 + rater.bias + rng.normal(0.0, noise)
    return int(np.clip(round(1 + (size - 1) * shifted), 1, size))


def _careful_likert(question: Question, reading: Reading, rater: Rater, noise: float,
                    rng: np.random.Generator) -> int:
    if question.id in reading.probabilities:
        fraction = reading.probabilities[question.id]
    elif question.id in GRID_VALUES:  # valence, arousal
        fraction = ((reading.valence if question.id == "valence" else reading.arousal) + 1) / 2
    elif question.id == "naturalness":
        fraction = NATURALNESS
    elif question.id == "confidence":
        low = question.min + round((question.max - question.min) / 2)
        return int(rng.integers(low, question.max + 1))
    else:
        fraction = 0.5
    return _scale(question, fraction, rater, noise, rng)


def _careful_answer(question: Question, reading: Reading, rater: Rater,
                    rng: np.random.Generator) -> Any:
    noise = rater.noise * (1.5 if reading.unsure else 1.0)
    if question.kind == "likert":
        return _careful_likert(question, reading, rater, noise, rng)
    if question.kind == "grid":
        return {"valence": _cell(reading.valence, question.size, rater, noise, rng),
                "arousal": _cell(reading.arousal, question.size, rater, noise, rng)}
    options = list(question.options)
    if all(o in reading.probabilities for o in options):
        temperature = rater.temperature * (2.0 if reading.unsure else 1.0)
        weights = np.array([reading.probabilities[o] for o in options]) + 1e-6
        weights = weights ** (1.0 / temperature)
        return options[int(rng.choice(len(options), p=weights / weights.sum()))]
    return options[int(rng.integers(len(options)))]


def _random_answer(question: Question, rng: np.random.Generator) -> Any:
    if question.kind == "likert":
        return int(rng.integers(question.min, question.max + 1))
    if question.kind == "grid":
        cells = rng.integers(1, question.size + 1, size=2)
        return {"valence": int(cells[0]), "arousal": int(cells[1])}
    return question.options[int(rng.integers(len(question.options)))]


def _expected(question: Question, value: Any) -> Any:
    if question.kind == "grid" and isinstance(value, list | tuple):
        return dict(zip(GRID_VALUES, value, strict=True))
    return value


def _passes(study: StudyConfig, check: AttentionCheck, answers: Mapping[str, Any]) -> bool:
    return all(answers.get(qid) == _expected(study.question(qid), value)
               for qid, value in check.expect.items())


def draw_answers(study: StudyConfig, rater: Rater, seed: int, item: int, reading: Reading,
                 check: AttentionCheck | None = None) -> tuple[dict[str, Any], int]:
    """One item's answers and response time (a function of ``seed, rater.index, item``).

    Args:
        study: the study.
        rater: the participant.
        seed: the simulation's seed.
        item: the item's number in the participant's plan.
        reading: what the stimulus shows (:func:`stimulus_reading`).
        check: the attention check the item is, or ``None``.

    Returns:
        Question id -> answer (the protocol's form) and ``rt_ms``, milliseconds.
    """
    rng = _rng(seed, rater.index, _ITEM, item)
    if rater.careless:
        answers = {q.id: _random_answer(q, rng) for q in study.questions}
        for _ in range(CARELESS_REDRAWS):
            if check is None or not _passes(study, check, answers):
                break
            answers = {q.id: _random_answer(q, rng) for q in study.questions}
        return answers, int(rng.integers(*CARELESS_RT_MS))
    answers = {q.id: _careful_answer(q, reading, rater, rng) for q in study.questions}
    if check is not None:
        for qid, value in check.expect.items():
            answers[qid] = _expected(study.question(qid), value)
    rt_ms = 1000.0 * (study.seconds * rng.uniform(1.0, 2.0) + rng.uniform(2.0, 8.0))
    return answers, int(rt_ms)


def check_items(study: StudyConfig, condition: str) -> dict[int, AttentionCheck]:
    """Plan item number -> the attention check shown there, in a condition's plans.

    Checks stand at the same places in every plan of a condition (:func:`~emotive.study.
    design.plan_for`): the ``j``-th by ``(position, id)`` at ``min(position, n) + j``, ``n``
    the condition's stimuli.
    """
    try:
        shown = len(study.condition(condition).stimuli)
    except KeyError:
        return {}
    ordered = sorted(study.checks, key=lambda c: (c.position, c.id))
    return {min(c.position, shown) + j: c for j, c in enumerate(ordered)}


def find_check(study: StudyConfig, at: Mapping[int, AttentionCheck],
               item: Mapping[str, Any]) -> AttentionCheck | None:
    """The attention check a plan item is (its ``instruction`` is not null), else ``None``.

    The check placed at the item's number is taken when its instruction is the item's; else
    the first check with the item's stimulus and instruction, else with its instruction.
    """
    instruction = item.get("instruction")
    if instruction is None:
        return None
    placed = at.get(item.get("item", -1))
    if placed is not None and placed.instruction == instruction:
        return placed
    same = [c for c in study.checks if c.instruction == instruction]
    for check in same:
        if check.stimulus == item.get("stimulus"):
            return check
    return same[0] if same else None
