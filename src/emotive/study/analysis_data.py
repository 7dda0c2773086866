"""The export table of a study, prepared for :mod:`emotive.study.analyze`: raters kept and not.

* :func:`prepare_frame` checks and types the table of ``emotive study export`` (one row per
  stored answer value);
* :func:`participation` counts who joined, who completed and what they answered;
* :func:`careless_raters` finds the participants who failed an attention check (an
  instructed-response item, the catch trials of Carreno-Medrano et al. 2018, section 7.1.2,
  footnote 6);
* :func:`outlier_raters` flags, per condition, the raters whose agreement with the others lies
  below Tukey's lower fence (the same paper, section 7.1.2, eq. 3), through
  :func:`emotive.eval.agreement.rater_outliers`;
* :class:`Ratings` holds the rated values of the raters kept, and pivots them to
  ``(n_stimuli, n_raters)`` matrices.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.eval.agreement import rater_outliers
from emotive.study.analysis_text import Section, attempt, plural
from emotive.study.config import GRID_VALUES, AttentionCheck, StudyConfig, stored_values
from emotive.study.errors import StudyError

if TYPE_CHECKING:
    import pandas as pd

#: Columns of the export table (those of ``emotive.study.store.EXPORT_COLUMNS``).
EXPORT_COLUMNS = ("participant", "condition", "stimulus", "question", "value", "time", "item",
                  "repeat", "check", "source", "intended", "rt_ms", "excluded")
_TEXT = ("participant", "condition", "stimulus", "question", "value", "time", "check",
         "source", "intended")
_INTEGER = ("item", "repeat", "excluded")


def _text(value: Any) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return str(value).strip()


def prepare_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """The export table with its types fixed, and a numeric column ``num``.

    Works on the table as ``pandas.read_csv`` gives it with or without ``dtype=str``: text
    columns become ``str`` (empty for a missing value), ``item``, ``repeat`` and ``excluded``
    integers, ``rt_ms`` a float (NaN when not given), and ``num`` is ``value`` as a float (NaN
    for a choice answer).

    Args:
        frame: the export table, columns :data:`EXPORT_COLUMNS` (others are ignored).

    Returns:
        A new table, one row per stored value, rows without a participant dropped.

    Raises:
        StudyError: a column is missing.
    """
    import pandas as pd  # noqa: PLC0415 (heavy: pandas)

    missing = [c for c in EXPORT_COLUMNS if c not in frame.columns]
    if missing:
        raise StudyError(f"the export table lacks the column(s) {missing}; make it again with "
                         "`emotive study export`")
    df = frame.loc[:, list(EXPORT_COLUMNS)].copy()
    for col in _TEXT:
        df[col] = df[col].map(_text).astype(object)
    for col in _INTEGER:
        df[col] = pd.to_numeric(df[col], errors="coerce").fillna(0).astype(int)
    df["rt_ms"] = pd.to_numeric(df["rt_ms"], errors="coerce").astype(float)
    df["num"] = pd.to_numeric(df["value"], errors="coerce").astype(float)
    return df[df["participant"] != ""].reset_index(drop=True)


def numeric_scales(study: StudyConfig) -> dict[str, tuple[float, float]]:
    """Stored value name -> its ``(lowest, highest)`` value, for likert and grid questions.

    A likert question's values run ``min..max``; a grid's ``valence`` and ``arousal`` -1..1.
    """
    scales: dict[str, tuple[float, float]] = {}
    for q in study.questions:
        if q.kind == "likert":
            scales[q.id] = (float(q.min), float(q.max))
        elif q.kind == "grid":
            scales.update(dict.fromkeys(GRID_VALUES, (-1.0, 1.0)))
    return scales


@dataclass(frozen=True)
class Participation:
    """Who took part and how far they came.

    Attributes:
        joined: participants with at least one stored answer (the export holds no others).
        completed: participants who answered every item of their plan.
        responses: items answered, all participants (one submission each).
        values: stored values (rows of the export).
        per_condition: ``(condition, joined, completed, responses)`` per condition.
    """

    joined: int
    completed: int
    responses: int
    values: int
    per_condition: tuple[tuple[str, int, int, int], ...]


def plan_length(study: StudyConfig, condition: str) -> int | None:
    """Items of a participant's plan in ``condition`` (``None`` for an unknown condition).

    Every stimulus of the condition once per pass, plus every attention check
    (:func:`emotive.study.design.plan_for`).
    """
    try:
        shown = study.condition(condition).stimuli
    except KeyError:
        return None
    return len(shown) * study.repeats + len(study.checks)


def participation(study: StudyConfig, rows: pd.DataFrame) -> Participation:
    """Count participants, completions and answers in the prepared export table."""
    items = rows.groupby(["participant", "condition"], sort=False)["item"].nunique()
    names = [c.name for c in study.conditions]
    names += sorted(set(rows["condition"]) - set(names))
    per: dict[str, list[int]] = {name: [0, 0, 0] for name in names}
    for (_, condition), answered in items.items():
        entry = per[condition]
        entry[0] += 1
        entry[1] += int(answered == plan_length(study, condition))
        entry[2] += int(answered)
    table = tuple((name, *per[name]) for name in names)
    return Participation(
        joined=int(rows["participant"].nunique()),
        completed=sum(e[1] for e in per.values()),
        responses=sum(e[2] for e in per.values()),
        values=len(rows),
        per_condition=tuple((n, int(a), int(b), int(c)) for n, a, b, c in table),
    )


def _fails(study: StudyConfig, check: AttentionCheck,
           given: Mapping[str, tuple[str, float]]) -> bool:
    """Whether the answers ``given`` (stored name -> (text, number)) differ from ``check``'s.

    Questions not answered are not held against the participant (as the admin page does).
    """
    for qid, value in check.expect.items():
        try:
            question = study.question(qid)
        except KeyError:
            continue
        if question.kind == "grid" and isinstance(value, list) and len(value) == 2:
            value = dict(zip(GRID_VALUES, value, strict=True))
        wanted = stored_values(question, value)
        if any(name not in given for name in wanted):
            continue
        for name, want in wanted.items():
            text, number = given[name]
            if isinstance(want, str):
                if text != want:
                    return True
            elif not (math.isfinite(number) and abs(number - float(want)) < 1e-6):
                return True
    return False


def careless_raters(study: StudyConfig, rows: pd.DataFrame) -> dict[str, tuple[str, ...]]:
    """Participants who failed an attention check -> the ids of the checks they failed.

    A check is failed when an answer given on its item differs from its ``expect``; a grid
    expectation ``[valence cell, arousal cell]`` is compared on the stored -1..1 values
    (:func:`emotive.study.config.stored_values`).
    """
    checks = {c.id: c for c in study.checks}
    failed: dict[str, list[str]] = {}
    at_checks = rows[rows["check"] != ""]
    for (pid, cid), answers in at_checks.groupby(["participant", "check"], sort=False):
        check = checks.get(str(cid))
        if check is None:
            continue
        given = {q: (v, n) for q, v, n in zip(answers["question"], answers["value"],
                                              answers["num"], strict=True)}
        if _fails(study, check, given):
            failed.setdefault(str(pid), []).append(str(cid))
    return {pid: tuple(ids) for pid, ids in failed.items()}


def _pivot(rows: pd.DataFrame, column: str) -> pd.DataFrame:
    """``(n_stimuli, n_raters)`` mean of ``column`` per stimulus and participant (passes pooled)."""
    return rows.pivot_table(index="stimulus", columns="participant", values=column,
                            aggfunc="mean")


def agreement_matrix(study: StudyConfig, rated: pd.DataFrame) -> pd.DataFrame:
    """Every rated value of a group of raters, as one ``(n_values, n_raters)`` matrix.

    Rows are (stored value, stimulus) pairs: a likert or grid value scaled by its range, a
    choice answer as one 0/1 row per option (the share of passes it was chosen). In each block
    of rows (one stored value or option) every rater's column is centred on its own mean, so
    that a rater's correlation with the others measures agreement on which stimuli rate
    higher on each scale, not the offsets between scales or a rater's leniency. Only raters
    who rated every stimulus of the group are columns.
    """
    import pandas as pd  # noqa: PLC0415 (heavy: pandas)

    scales = numeric_scales(study)
    blocks = []
    for q in study.questions:
        if q.kind == "choice":
            answers = rated[rated["question"] == q.id]
            for option in q.options:
                marked = answers.assign(x=(answers["value"] == option).astype(float))
                blocks.append(_pivot(marked, "x"))
        else:
            for name in q.stored:
                lo, hi = scales[name]
                blocks.append(_pivot(rated[rated["question"] == name], "num") / (hi - lo))
    blocks = [b for b in blocks if not b.empty]
    if not blocks:
        return pd.DataFrame()
    matrix = pd.concat(blocks, keys=range(len(blocks)))
    complete = matrix.columns[matrix.notna().all(axis=0)]
    matrix = matrix.loc[:, complete]
    if matrix.shape[1] == 0:
        return matrix
    return matrix - matrix.groupby(level=0).transform("mean")


@dataclass(frozen=True)
class OutlierGroup:
    """The Tukey-fence screen of one condition's raters.

    Attributes:
        condition: the condition.
        tested: raters tested (those who rated every stimulus of the condition).
        agreement: ``(n_tested,)`` each one's Spearman correlation with the others' mean.
        lower: Tukey's lower fence ``Q1 - 1.5 IQR``.
        flagged: the outliers, a subset of ``tested``.
        untested: raters not tested, having rated only some stimuli.
    """

    condition: str
    tested: tuple[str, ...]
    agreement: tuple[float, ...]
    lower: float
    flagged: tuple[str, ...]
    untested: tuple[str, ...]


def outlier_raters(study: StudyConfig, rated: pd.DataFrame, section: Section
                   ) -> list[OutlierGroup]:
    """Flag, per condition, raters whose agreement with the others is below Tukey's fence.

    Carreno-Medrano et al. 2018, section 7.1.2: each rater's agreement coefficient with the
    other raters of their group, and the interval ``[Q1 - 1.5 IQR, Q3 + 1.5 IQR]`` of eq. 3
    (only low agreement is flagged: :func:`emotive.eval.agreement.rater_outliers`). A
    condition where it cannot be computed gets a line in ``section``.

    Args:
        study: the study.
        rated: rated (not attention-check) rows of the raters to screen.
        section: where reasons go.
    """
    groups = []
    for condition in sorted(set(rated["condition"])):
        rows = rated[rated["condition"] == condition]
        raters = sorted(set(rows["participant"]))
        matrix = agreement_matrix(study, rows)
        tested = [str(c) for c in matrix.columns]
        untested = tuple(r for r in raters if r not in tested)
        what = f"outlier screen, condition {condition}"
        if len(tested) < 3:
            section.skip(what, f"{plural(len(tested), 'rater')} rated every stimulus of the "
                         "condition; Tukey fences need at least 3")
            continue
        result = attempt(section, what, rater_outliers, matrix.to_numpy(dtype=float))
        if result is None:
            continue
        if not np.isfinite(result.agreement).any():
            section.skip(what, "every rater gave one answer to everything, so no agreement "
                         "can be computed (no rater is flagged)")
            continue
        flagged = tuple(tested[i] for i in result.outlier_indices)
        groups.append(OutlierGroup(condition, tuple(tested),
                                   tuple(float(a) for a in result.agreement),
                                   float(result.lower), flagged, untested))
    return groups


@dataclass(frozen=True)
class Ratings:
    """The rated values of the raters kept (attention-check items left out).

    Attributes:
        study: the study.
        rows: the prepared export rows (:func:`prepare_frame`) of the raters kept, without
            attention-check items.
    """

    study: StudyConfig
    rows: pd.DataFrame

    @property
    def raters(self) -> tuple[str, ...]:
        """The raters kept, sorted."""
        return tuple(sorted(set(self.rows["participant"])))

    @property
    def conditions(self) -> tuple[str, ...]:
        """The conditions of the raters kept, in the study's order."""
        present = set(self.rows["condition"])
        known = [c.name for c in self.study.conditions if c.name in present]
        return (*known, *sorted(present - set(known)))

    def of(self, name: str) -> pd.DataFrame:
        """The rows of one stored value name (a question id, or ``valence``/``arousal``)."""
        return self.rows[self.rows["question"] == name]

    def per_rater(self, name: str, condition: str | None = None) -> pd.DataFrame:
        """``(n_stimuli, n_raters)`` each rater's mean ``num`` of ``name`` over the passes."""
        rows = self.of(name)
        if condition is not None:
            rows = rows[rows["condition"] == condition]
        return _pivot(rows, "num")

    def source(self, stimulus: str) -> str:
        """The stimulus's source from the study (``""`` when it is not in the study)."""
        try:
            return self.study.stimulus(stimulus).source
        except KeyError:
            return ""

    def intended(self, stimulus: str) -> str:
        """The stimulus's intended emotion text from the study (``""`` when none)."""
        try:
            return self.study.stimulus(stimulus).intended
        except KeyError:
            return ""


def finite(values: Any) -> np.ndarray:
    """``values`` as a float vector without its NaN."""
    arr = np.asarray(values, dtype=float).reshape(-1)
    return arr[np.isfinite(arr)]
