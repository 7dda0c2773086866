"""Emotion of the stimuli as intended and as perceived: the gaits and forced-choice designs.

Helpers of :mod:`emotive.study.analyze`, one per report section:

* :func:`gaits_section` -- Bhattacharya et al. 2020 (emotive gaits), section 6.3.1 and Table 3:
  the perceived emotion vector of each stimulus from likert ratings named after emotion labels,
  and the 2-sample Anderson-Darling test of intended against perceived; section 6.3.3: the
  k-sample test across raters (:func:`consistency_section`); section 6.3.4: naturalness
  (:func:`naturalness_section`).
* :func:`choice_section` -- Carreno-Medrano et al. 2018, section 7.1: forced-choice accuracy per
  intended emotion, the confusion matrix and Fleiss' kappa of the raters.

Shapes: ``C`` emotion labels, ``R`` raters, ``S`` stimuli.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from emotive.data.circumplex import ALL_LABELS, DEFAULT_LABELS, canonical_label
from emotive.data.emotion import coerce_emotion
from emotive.errors import EmotionError
from emotive.eval.agreement import fleiss_kappa
from emotive.eval.stats import anderson_darling_ksamp
from emotive.study.analysis_data import Ratings, finite
from emotive.study.analysis_plots import plot_confusion, plot_emotion_bars
from emotive.study.analysis_text import Section, attempt, fmt, fmt_p, pct, table
from emotive.study.config import Question, StudyConfig

if TYPE_CHECKING:
    import pandas as pd


def intended_emotion(text: str, labels: Sequence[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """Weights ``(C,)`` over ``labels`` and the valence/arousal point ``(2,)`` of an intention.

    ``text`` is the stimulus's ``intended`` (:mod:`emotive.data.emotion` text: a label, a
    blend or ``valence=V,arousal=A``, blended over ``labels`` by the circumplex kernel). The
    point is exact for a valence/arousal text, else the weighted mean of the label points.

    Returns:
        ``None`` for an empty text, or one with weight on a label outside ``labels``.
    """
    text = text.strip()
    if not text or text.startswith("[") or text.endswith(".json") or "/" in text:
        return None
    try:
        schedule = coerce_emotion(text, tuple(labels))
    except EmotionError:
        return None
    return np.asarray(schedule.weights[0]), np.asarray(schedule.points[0])


def emotion_likerts(study: StudyConfig) -> tuple[Question, ...]:
    """The likert questions named after emotion labels (``happy``, ``sad``, ...), if two or more."""
    found = tuple(q for q in study.questions
                  if q.kind == "likert" and canonical_label(q.id) in ALL_LABELS)
    return found if len(found) >= 2 else ()


def emotion_choice(study: StudyConfig) -> Question | None:
    """The first choice question whose options are all emotion labels, or ``None``."""
    for q in study.questions:
        if q.kind == "choice" and all(canonical_label(o) in ALL_LABELS for o in q.options):
            return q
    return None


def level_labels(study: StudyConfig) -> tuple[str, ...]:
    """The labels an intended emotion is named by: choice options, likert labels or defaults."""
    choice = emotion_choice(study)
    if choice is not None:
        return tuple(canonical_label(o) for o in choice.options)
    likerts = emotion_likerts(study)
    if likerts:
        return tuple(canonical_label(q.id) for q in likerts)
    return DEFAULT_LABELS


def intended_label(study: StudyConfig, text: str) -> str | None:
    """The dominant label of an intention over :func:`level_labels` (``None`` when none)."""
    labels = level_labels(study)
    parsed = intended_emotion(text, labels)
    return None if parsed is None else labels[int(np.argmax(parsed[0]))]


# --------------------------------------------------------------------------------------------
# Gaits: intended against perceived emotion vectors


@dataclass(frozen=True)
class EmotionTest:
    """The 2-sample Anderson-Darling test of one stimulus (Bhattacharya et al. 2020, Table 3).

    Attributes:
        stimulus: the stimulus.
        source: its source.
        intended: ``(C,)`` intended emotion weights.
        perceived: ``(C,)`` mean of the raters' l1-normalized vectors.
        raters: raters whose vector entered the mean.
        statistic: normalized statistic (SciPy's; negative values are usual under the null).
        p_value: p-value, capped to [0.001, 0.25].
        p_bounded: the p-value lies at a cap.
    """

    stimulus: str
    source: str
    intended: tuple[float, ...]
    perceived: tuple[float, ...]
    raters: int
    statistic: float
    p_value: float
    p_bounded: bool

    @property
    def rejected(self) -> bool:
        """Whether the test rejects "intended and perceived are one distribution" at 0.05."""
        return self.p_value < 0.05

    @property
    def distance(self) -> float:
        """Total variation distance ``sum |intended - perceived| / 2`` in [0, 1], label-wise."""
        return 0.5 * float(np.abs(np.subtract(self.intended, self.perceived)).sum())

    @property
    def same_dominant(self) -> bool:
        """Whether the perceived vector's largest label is one of the intended's largest."""
        top = np.flatnonzero(np.isclose(self.intended, max(self.intended)))
        return int(np.argmax(self.perceived)) in top


def perceived_vectors(ratings: Ratings, questions: Sequence[Question]
                      ) -> dict[str, np.ndarray]:
    """Stimulus -> ``(R_s, C)`` each rater's l1-normalized ``(rating - min)`` vector.

    A rater's ratings of a stimulus are first averaged over the passes; a rater who rated
    every label at the scale's minimum (an all-zero vector) is left out of that stimulus.
    """
    import pandas as pd  # noqa: PLC0415 (heavy: pandas)

    tables = [ratings.per_rater(q.id) - q.min for q in questions]
    stimuli = sorted(set().union(*(t.index for t in tables)))
    raters = sorted(set().union(*(t.columns for t in tables)))
    stack = np.stack([t.reindex(index=pd.Index(stimuli), columns=pd.Index(raters)).to_numpy(
        dtype=float) for t in tables], axis=-1)  # (S, R, C)
    out = {}
    for s, sid in enumerate(stimuli):
        vectors = stack[s]
        sums = vectors.sum(axis=1)
        keep = np.all(np.isfinite(vectors), axis=1) & (sums > 0)
        if keep.any():
            out[sid] = vectors[keep] / sums[keep, None]
    return out


def _vector(values: Sequence[float]) -> str:
    return " / ".join(f"{v:.2f}" for v in values)


def _emotion_test(ratings: Ratings, sid: str, vectors: np.ndarray, labels: tuple[str, ...],
                  section: Section) -> EmotionTest | None:
    parsed = intended_emotion(ratings.intended(sid), labels)
    if parsed is None:
        return None
    intended, perceived = parsed[0], vectors.mean(axis=0)
    res = attempt(section, f"Anderson-Darling, stimulus {sid}", anderson_darling_ksamp,
                  [intended, perceived])
    if res is None:
        return None
    return EmotionTest(sid, ratings.source(sid), tuple(float(x) for x in intended),
                       tuple(float(x) for x in perceived), len(vectors), res.statistic,
                       res.p_value, res.p_value_bounded)


def gaits_section(ratings: Ratings, out: Path, section: Section) -> list[EmotionTest]:
    """Intended against perceived emotion per stimulus, with its bar plot.

    Bhattacharya et al. 2020, section 6.3.1: the perceived emotion of a stimulus is the mean
    over raters of their l1-normalized emotion vectors; the 2-sample Anderson-Darling test
    (:func:`emotive.eval.stats.anderson_darling_ksamp`) of the intended against the perceived
    probabilities, as Table 3. Stimuli without an intended emotion (or one outside the rated
    labels) are shown without a test.

    Returns:
        The test of each stimulus it could be computed for.
    """
    questions = emotion_likerts(ratings.study)
    labels = tuple(canonical_label(q.id) for q in questions)
    vectors = perceived_vectors(ratings, questions)
    section.add(
        f"Emotion scales: {', '.join(q.id for q in questions)}. A rater's vector of a stimulus "
        "is their ratings minus the scale's minimum, l1-normalized; the perceived emotion is "
        "the mean over raters (Bhattacharya et al. 2020, section 6.3.1). Each stimulus's "
        "intended and perceived probabilities are compared by the 2-sample Anderson-Darling "
        "test (their Table 3); p-values are capped to [0.001, 0.25].", "")
    if not vectors:
        section.skip("intended vs perceived emotion", "no rater rated any stimulus above the "
                     "scales' minimum")
        return []
    tests, rows = [], []
    for sid in [s.id for s in ratings.study.stimuli if s.id in vectors]:
        test = _emotion_test(ratings, sid, vectors[sid], labels, section)
        if test is not None:
            tests.append(test)
            rows.append([sid, test.source or "-", _vector(test.intended),
                         _vector(test.perceived), test.raters, fmt(test.statistic),
                         fmt_p(test.p_value, test.p_bounded),
                         "**yes**" if test.rejected else "no",
                         "yes" if test.same_dominant else "**no**", fmt(test.distance, 2)])
        else:
            rows.append([sid, ratings.source(sid) or "-", ratings.intended(sid) or "(none)",
                         _vector(vectors[sid].mean(axis=0)), len(vectors[sid]), "-", "-", "-",
                         "-", "-"])
    section.add(*table(["stimulus", "source", f"intended ({'/'.join(labels)})", "perceived",
                        "raters", "A²", "p", "reject at 0.05", "same top label", "distance"],
                       rows))
    if tests:
        kept = sum(not t.rejected for t in tests)
        section.add(f"Not rejected for **{kept} of {len(tests)}** stimuli: for those, intended "
                    "and perceived emotion cannot be told apart at the 5% level. The test "
                    "compares the two sets of C values, not label by label (all on sad and all "
                    "on neutral are not told apart), so read it beside the last two columns: "
                    "whether the most perceived label is the most intended one, and the total "
                    "variation distance (half the l1 distance, 0 to 1).", "")
    plot = plot_emotion_bars(out, labels, [(sid, intended_emotion(ratings.intended(sid), labels),
                                            vectors[sid].mean(axis=0)) for sid in vectors])
    if plot is not None:
        section.plots.append(plot)
        section.add(f"![Intended and perceived emotion per stimulus]({plot.name})", "")
    return tests


# --------------------------------------------------------------------------------------------
# Consistency across raters (k-sample Anderson-Darling)


@dataclass(frozen=True)
class ConsistencyTest:
    """The k-sample Anderson-Darling test across raters of one unit and likert question.

    Attributes:
        unit: the stimulus, or ``intended LABEL`` for the stimuli of one intended emotion.
        question: the likert question.
        raters: k, the number of raters (samples).
        statistic: normalized statistic.
        p_value: p-value, capped to [0.001, 0.25].
        p_bounded: the p-value lies at a cap.
    """

    unit: str
    question: str
    raters: int
    statistic: float
    p_value: float
    p_bounded: bool


def _consistency_units(ratings: Ratings) -> tuple[dict[str, list[str]], str]:
    """Unit name -> its stimuli, and the sentence saying what a unit is."""
    study = ratings.study
    if study.repeats > 1:
        return ({s.id: [s.id] for s in study.stimuli},
                "one test per stimulus; a rater's sample is their ratings over the passes")
    units: dict[str, list[str]] = {}
    for s in study.stimuli:
        label = intended_label(study, s.intended)
        if label is not None:
            units.setdefault(f"intended {label}", []).append(s.id)
    return (units, "each rater rated each stimulus once, and k samples of one value each make "
            "the statistic 0 whatever the answers, so the stimuli are pooled by intended "
            "emotion (as Figure 8 of the paper): a rater's sample is their ratings of those "
            "stimuli")


def _samples(rows: pd.DataFrame) -> list[np.ndarray]:
    return [finite(g["num"]) for _, g in rows.groupby("participant", sort=True)]


def consistency_section(ratings: Ratings, section: Section) -> list[ConsistencyTest]:
    """k-sample Anderson-Darling test across raters per unit and likert question.

    Bhattacharya et al. 2020, section 6.3.3: are all raters' values of a question for a
    stimulus samples of one distribution (k = number of raters)? See
    :func:`_consistency_units` for the unit when each stimulus was rated once.
    """
    likerts = [q for q in ratings.study.questions if q.kind == "likert"]
    units, how = _consistency_units(ratings)
    section.add("### Consistency across raters", "",
                "k-sample Anderson-Darling test that every rater's values come from one "
                f"distribution (Bhattacharya et al. 2020, section 6.3.3; k = raters): {how}. "
                "Bold: rejected at 0.05 (raters disagree).", "")
    tests: list[ConsistencyTest] = []
    rows = []
    for unit, stimuli in units.items():
        cells = []
        for q in likerts:
            sub = ratings.of(q.id)
            samples = [s for s in _samples(sub[sub["stimulus"].isin(stimuli)]) if s.size]
            cell = "-"
            if len(samples) >= 2 and max(s.size for s in samples) >= 2:
                pooled = np.concatenate(samples)
                cell = "all equal"
                if np.any(pooled != pooled[0]):
                    res = attempt(section, f"k-sample Anderson-Darling, {unit}, {q.id}",
                                  anderson_darling_ksamp, samples)
                    cell = "failed"
                    if res is not None:
                        tests.append(ConsistencyTest(unit, q.id, len(samples), res.statistic,
                                                     res.p_value, res.p_value_bounded))
                        p = fmt_p(res.p_value, res.p_value_bounded)
                        cell = f"**{p}**" if res.p_value < 0.05 else p
            cells.append(cell)
        rows.append([unit, *cells])
    if not tests:
        section.skip("consistency across raters", "needs at least 2 raters with 2 or more "
                     "values each in a unit, and values that differ")
        return tests
    section.add(*table(["unit", *(f"p ({q.id})" for q in likerts)], rows))
    kept = sum(t.p_value >= 0.05 for t in tests)
    section.add(f"Not rejected in **{kept} of {len(tests)}** tests. \"all equal\": every rater "
                "gave the same value (consistent; the test is undefined). \"-\": fewer than "
                "2 raters, or one value each.", "")
    return tests


# --------------------------------------------------------------------------------------------
# Naturalness


def naturalness_section(ratings: Ratings, question: Question, section: Section
                        ) -> dict[str, float]:
    """Share of each value of the naturalness scale per source, and the share at least middle.

    Bhattacharya et al. 2020, section 6.3.4 ("89% of the users marked at least three"), over
    every rating of the raters kept (all passes).

    Returns:
        Source -> share of ratings at least the scale's middle value.
    """
    rows = ratings.of(question.id)
    middle = math.ceil((question.min + question.max) / 2)
    values = list(range(question.min, question.max + 1))
    section.add(f"Share of the ratings of `{question.id}` ({question.min}..{question.max}) per "
                f"source and the share of at least {middle} (satisfactory; Bhattacharya et al. "
                "2020, section 6.3.4).", "")
    if rows.empty:
        section.skip("naturalness", "no ratings")
        return {}
    out, lines = {}, []
    sources = rows["stimulus"].map(ratings.source).replace("", "(none)")
    for source, group in rows.groupby(sources, sort=True):
        num = finite(group["num"])
        if num.size == 0:
            continue
        out[str(source)] = float(np.mean(num >= middle))
        lines.append([source, num.size, *(pct(float(np.mean(num == v))) for v in values),
                      f"**{pct(out[str(source)])}**"])
    section.add(*table(["source", "ratings", *map(str, values), f">= {middle}"], lines))
    return out


# --------------------------------------------------------------------------------------------
# Forced choice


@dataclass(frozen=True)
class KappaRow:
    """Fleiss' kappa of one condition's raters on the forced choice (first pass).

    Attributes:
        condition: the condition.
        kappa: the statistic.
        stimuli: rated subjects.
        raters: raters who answered every stimulus of the condition.
    """

    condition: str
    kappa: float
    stimuli: int
    raters: int


def choice_rows(ratings: Ratings, question: Question) -> pd.DataFrame:
    """The answers to ``question`` with ``target`` (the intended option) and ``correct``."""
    options = {canonical_label(o): o for o in question.options}
    labels = tuple(options)
    targets = {}
    for s in ratings.study.stimuli:
        parsed = intended_emotion(s.intended, labels)
        if parsed is not None:
            targets[s.id] = options[labels[int(np.argmax(parsed[0]))]]
    rows = ratings.of(question.id)
    rows = rows.assign(target=rows["stimulus"].map(targets))
    rows = rows[rows["target"].notna()]
    return rows.assign(correct=(rows["value"] == rows["target"]).astype(float))


def _accuracy_table(rows: pd.DataFrame, options: Sequence[str], conditions: Sequence[str]
                    ) -> tuple[list[str], list[list[str]]]:
    def cell(sub: pd.DataFrame) -> str:
        return f"{pct(float(sub['correct'].mean()))} ({len(sub)})" if len(sub) else "-"

    split = list(conditions) if len(conditions) > 1 else []
    lines = []
    for target in [o for o in options if o in set(rows["target"])]:
        sub = rows[rows["target"] == target]
        lines.append([target, *(cell(sub[sub["condition"] == c]) for c in split), cell(sub)])
    lines.append(["**all**", *(cell(rows[rows["condition"] == c]) for c in split),
                  f"**{cell(rows)}**"])
    return ["intended", *split, "all conditions" if split else "accuracy (answers)"], lines


def _kappa(rows: pd.DataFrame, question: Question, condition: str, section: Section
           ) -> KappaRow | None:
    first = rows[(rows["condition"] == condition) & (rows["repeat"] == 0)]
    answers = first.pivot_table(index="stimulus", columns="participant", values="value",
                                aggfunc="first")
    answers = answers.loc[:, answers.notna().all(axis=0)]
    counts = np.array([[int((answers.loc[s] == o).sum()) for o in question.options]
                       for s in answers.index], dtype=float).reshape(-1, len(question.options))
    res = attempt(section, f"Fleiss' kappa, condition {condition}", fleiss_kappa, counts,
                  counts=True)
    if res is None:
        return None
    return KappaRow(condition, res.kappa, res.n_subjects, res.n_raters)


def choice_section(ratings: Ratings, question: Question, out: Path, section: Section
                   ) -> tuple[dict[str, float], list[KappaRow]]:
    """Forced-choice accuracy per intended emotion, confusion matrix and Fleiss' kappa.

    Carreno-Medrano et al. 2018, section 7.1.1 ("which of the listed emotions is conveyed?"):
    an answer is correct when it is the dominant label of the stimulus's intended emotion.
    Fleiss' kappa (:func:`emotive.eval.agreement.fleiss_kappa`) per condition, over the first
    pass of the raters who answered every stimulus of the condition.

    Returns:
        Accuracy per intended option (all conditions) and the kappa of each condition.
    """
    rows = choice_rows(ratings, question)
    chance = 1.0 / len(question.options)
    section.add(f"Question `{question.id}` (options: {', '.join(question.options)}; chance "
                f"{pct(chance)}). An answer is correct when it is the dominant label of the "
                "stimulus's intended emotion (Carreno-Medrano et al. 2018, section 7.1). Cells: "
                "accuracy (answers).", "")
    if rows.empty:
        section.skip("forced-choice accuracy", "no answers to stimuli with an intended emotion "
                     "among the options")
        return {}, []
    headers, lines = _accuracy_table(rows, question.options, ratings.conditions)
    section.add(*table(headers, lines))
    accuracy = {t: float(rows.loc[rows["target"] == t, "correct"].mean())
                for t in question.options if t in set(rows["target"])}
    targets = [o for o in question.options if o in set(rows["target"])]
    confusion = np.array([[int(((rows["target"] == t) & (rows["value"] == o)).sum())
                           for o in question.options] for t in targets])
    plot = plot_confusion(out, targets, list(question.options), confusion)
    if plot is not None:
        section.plots.append(plot)
        section.add(f"![Confusion matrix: intended (rows) and chosen (columns)]({plot.name})",
                    "")
    answers = ratings.of(question.id)
    kappas = [k for c in ratings.conditions
              if (k := _kappa(answers, question, c, section)) is not None]
    if kappas:
        section.add("Fleiss' kappa of the raters (first pass; 1: full agreement, 0: chance):",
                    "", *table(["condition", "kappa", "stimuli", "raters"],
                               [[k.condition, fmt(k.kappa), k.stimuli, k.raters]
                                for k in kappas]))
    return accuracy, kappas
