"""Valence and arousal ratings, the mixed ANOVA and repeated ratings of a study.

Helpers of :mod:`emotive.study.analyze`, one per report section:

* :func:`affect_section` -- Alemi et al. 2015 (FCRBM), section V.D: per stimulus the mean
  valence and arousal with a 95% confidence interval, Cronbach's alpha with the raters as
  items, and recorded against generated movements by the Mann-Whitney U test;
* :func:`anova_section` -- Carreno-Medrano et al. 2018, sections 7.1.3 and 7.2.2: two-way
  mixed ANOVA, intended emotion within and the study's between factor between subjects, on
  accuracy, valence and arousal, with the Greenhouse-Geisser correction;
* :func:`repeats_section` -- the same paper, section 7.2.1 (every clip rated twice): how
  consistent each rater is between the two passes.

Valence and arousal come from a grid question (stored on -1..1) or from likert questions named
``valence`` and ``arousal`` (mapped linearly to -1..1 here, so that they compare with intended
points; the ANOVA keeps the likert scale).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from emotive.data.circumplex import ALL_LABELS
from emotive.eval.agreement import cronbach_alpha
from emotive.eval.anova import MixedAnovaResult, mixed_anova
from emotive.eval.stats import mann_whitney_u
from emotive.study.analysis_data import Ratings, finite, numeric_scales
from emotive.study.analysis_emotion import (
    choice_rows,
    emotion_choice,
    intended_emotion,
    intended_label,
)
from emotive.study.analysis_plots import plot_affect
from emotive.study.analysis_text import Section, attempt, fmt, fmt_p, pct, table
from emotive.study.config import GRID_VALUES

if TYPE_CHECKING:
    import pandas as pd


def affect_names(ratings: Ratings) -> tuple[str, ...]:
    """The stored values ``valence`` and ``arousal`` the study has (grid or likert)."""
    scales = numeric_scales(ratings.study)
    return tuple(name for name in GRID_VALUES if name in scales)


def unit_values(ratings: Ratings, name: str, condition: str | None = None) -> pd.DataFrame:
    """``(n_stimuli, n_raters)`` each rater's mean of ``name`` over the passes, on -1..1."""
    lo, hi = numeric_scales(ratings.study)[name]
    return 2.0 * (ratings.per_rater(name, condition) - lo) / (hi - lo) - 1.0


@dataclass(frozen=True)
class StimulusAffect:
    """Mean perceived valence and arousal of one stimulus, on -1..1.

    Attributes:
        stimulus: the stimulus.
        source: its source.
        raters: raters who rated it.
        mean: ``(2,)`` mean valence and arousal over raters (NaN for a value not asked).
        ci: ``(2, 2)`` 95% t-interval ``[[v_low, v_high], [a_low, a_high]]`` (NaN for one
            rater).
        intended: ``(2,)`` the intended point, or ``None``.
    """

    stimulus: str
    source: str
    raters: int
    mean: tuple[float, float]
    ci: tuple[tuple[float, float], tuple[float, float]]
    intended: tuple[float, float] | None


@dataclass(frozen=True)
class AlphaRow:
    """Cronbach's alpha of one condition and value, raters as items (Alemi et al. 2015).

    Attributes:
        condition: the condition.
        value: ``valence`` or ``arousal``.
        alpha: the statistic.
        ci_low: lower end of its 95% interval (Feldt).
        ci_high: upper end.
        stimuli: cases.
        raters: items (raters who rated every stimulus of the condition).
    """

    condition: str
    value: str
    alpha: float
    ci_low: float
    ci_high: float
    stimuli: int
    raters: int


@dataclass(frozen=True)
class MannWhitneyRow:
    """The Mann-Whitney U test of one value between two sources.

    Attributes:
        value: ``valence`` or ``arousal``.
        source_x: the first source.
        source_y: the second source.
        u: U of ``source_x``.
        p_value: two-sided p-value.
        n_x: ratings of ``source_x`` (raters x stimuli, passes averaged).
        n_y: ratings of ``source_y``.
        rank_biserial: ``P(X > Y) - P(X < Y)``.
    """

    value: str
    source_x: str
    source_y: str
    u: float
    p_value: float
    n_x: int
    n_y: int
    rank_biserial: float


def _mean_ci(values: np.ndarray) -> tuple[float, tuple[float, float]]:
    """Mean and 95% t-interval of a sample (NaN interval below two values)."""
    from scipy import stats  # noqa: PLC0415 (heavy: scipy)

    values = finite(values)
    if values.size == 0:
        return float("nan"), (float("nan"), float("nan"))
    mean = float(values.mean())
    if values.size < 2:
        return mean, (float("nan"), float("nan"))
    half = float(stats.t.ppf(0.975, values.size - 1) * values.std(ddof=1) / np.sqrt(values.size))
    return mean, (mean - half, mean + half)


def _stimulus_affect(ratings: Ratings, names: tuple[str, ...]) -> list[StimulusAffect]:
    tables = {name: unit_values(ratings, name) for name in names}
    out = []
    for s in ratings.study.stimuli:
        means, cis, raters = [], [], 0
        for name in GRID_VALUES:
            if name in tables and s.id in tables[name].index:
                row = tables[name].loc[s.id].to_numpy(dtype=float)
                mean, ci = _mean_ci(row)
                raters = max(raters, finite(row).size)
            else:
                mean, ci = float("nan"), (float("nan"), float("nan"))
            means.append(mean)
            cis.append(ci)
        if raters:
            parsed = intended_emotion(s.intended, ALL_LABELS)
            point = None if parsed is None else (float(parsed[1][0]), float(parsed[1][1]))
            out.append(StimulusAffect(s.id, s.source, raters, (means[0], means[1]),
                                      (cis[0], cis[1]), point))
    return out


def _alphas(ratings: Ratings, names: tuple[str, ...], section: Section) -> list[AlphaRow]:
    out = []
    for condition in ratings.conditions:
        for name in names:
            matrix = unit_values(ratings, name, condition)
            matrix = matrix.loc[:, matrix.notna().all(axis=0)]
            res = attempt(section, f"Cronbach's alpha, {name}, condition {condition}",
                          cronbach_alpha, matrix.to_numpy(dtype=float))
            if res is not None:
                out.append(AlphaRow(condition, name, res.alpha, res.ci_low, res.ci_high,
                                    res.n_cases, res.n_items))
    return out


def _mann_whitney(ratings: Ratings, names: tuple[str, ...], section: Section
                  ) -> list[MannWhitneyRow]:
    sources = sorted({ratings.source(s) for s in set(ratings.rows["stimulus"])})
    if len(sources) < 2:
        section.skip("Mann-Whitney U between sources", f"every stimulus rated has one source "
                     f"({sources[0] if sources else 'none'})")
        return []
    out = []
    for name in names:
        values = unit_values(ratings, name)
        by_source = {src: finite(values.loc[[s for s in values.index
                                              if ratings.source(s) == src]].to_numpy())
                     for src in sources}
        for x, y in itertools.combinations(sources, 2):
            res = attempt(section, f"Mann-Whitney U, {name}, {x or '(none)'} vs "
                          f"{y or '(none)'}", mann_whitney_u, by_source[x], by_source[y])
            if res is not None:
                out.append(MannWhitneyRow(name, x, y, res.statistic, res.p_value, res.n_x,
                                          res.n_y, res.rank_biserial))
    return out


def _ci_text(mean: float, ci: tuple[float, float]) -> str:
    if np.isnan(mean):
        return "-"
    if np.isnan(ci[0]):
        return fmt(mean, 2)
    return f"{mean:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]"


def affect_section(ratings: Ratings, out: Path, section: Section
                   ) -> tuple[list[StimulusAffect], list[AlphaRow], list[MannWhitneyRow]]:
    """Valence and arousal per stimulus, Cronbach's alpha, Mann-Whitney U and the grid plot.

    Alemi et al. 2015, section V.D: means with 95% intervals (their Figure 7), inter-rater
    reliability by Cronbach's alpha with the raters as items and the stimuli as cases (per
    condition: raters who rated every stimulus of it), recorded against generated movements by
    the Mann-Whitney U test for valence and arousal separately (here every pair of sources;
    a sample is one value per rater and stimulus, passes averaged).
    """
    names = affect_names(ratings)
    scales = numeric_scales(ratings.study)
    mapped = [n for n in names if scales[n] != (-1.0, 1.0)]
    note = (f" Likert {', '.join(mapped)} mapped linearly from "
            f"{scales[mapped[0]][0]:g}..{scales[mapped[0]][1]:g} to -1..1." if mapped else "")
    section.add("Mean perceived valence and arousal per stimulus on -1..1 with 95% t-intervals "
                f"over raters (Alemi et al. 2015, section V.D).{note}", "")
    points = _stimulus_affect(ratings, names)
    if not points:
        section.skip("valence and arousal", "no ratings")
        return [], [], []
    section.add(*table(
        ["stimulus", "source", "intended (v, a)", "raters", "valence [95% CI]",
         "arousal [95% CI]"],
        [[p.stimulus, p.source or "-",
          "-" if p.intended is None else f"{p.intended[0]:.2f}, {p.intended[1]:.2f}", p.raters,
          _ci_text(p.mean[0], p.ci[0]), _ci_text(p.mean[1], p.ci[1])] for p in points]))
    if len(names) == 2:
        plot = plot_affect(out, [(p.stimulus, p.source, None if p.intended is None else
                                  np.array(p.intended), np.array(p.mean)) for p in points])
        if plot is not None:
            section.plots.append(plot)
            section.add(f"![Mean perceived (filled) and intended (hollow) points]({plot.name})",
                        "")
    alphas = _alphas(ratings, names, section)
    if alphas:
        section.add("Cronbach's alpha, raters as items and stimuli as cases (Alemi et al. "
                    "report 0.89 for valence and 0.98 for arousal):", "", *table(
                        ["condition", "value", "alpha", "95% CI", "stimuli", "raters"],
                        [[a.condition, a.value, fmt(a.alpha), f"[{a.ci_low:.3f}, "
                          f"{a.ci_high:.3f}]", a.stimuli, a.raters] for a in alphas]))
    tests = _mann_whitney(ratings, names, section)
    if tests:
        section.add("Mann-Whitney U between sources (two-sided; r: rank-biserial, positive "
                    "when the first source rates higher):", "", *table(
                        ["value", "sources", "U", "p", "N1", "N2", "r"],
                        [[t.value, f"{t.source_x or '(none)'} vs {t.source_y or '(none)'}",
                          f"{t.u:.1f}", fmt_p(t.p_value), t.n_x, t.n_y, fmt(t.rank_biserial, 2)]
                         for t in tests]))
    return points, alphas, tests


# --------------------------------------------------------------------------------------------
# Mixed ANOVA


@dataclass(frozen=True)
class AnovaRow:
    """The mixed ANOVA of one measure.

    Attributes:
        measure: ``accuracy``, ``valence`` or ``arousal``.
        result: the ANOVA (:func:`emotive.eval.anova.mixed_anova`).
        dropped: raters left out for lacking a level of intended emotion.
    """

    measure: str
    result: MixedAnovaResult
    dropped: int


def _measures(ratings: Ratings) -> list[tuple[str, pd.DataFrame]]:
    """``(measure, rows with a numeric column y)`` for accuracy, valence and arousal."""
    out = []
    choice = emotion_choice(ratings.study)
    if choice is not None:
        rows = choice_rows(ratings, choice)
        out.append(("accuracy", rows.assign(y=rows["correct"])))
    for name in affect_names(ratings):
        rows = ratings.of(name)
        out.append((name, rows.assign(y=rows["num"])))
    return out


def _anova_data(ratings: Ratings, rows: pd.DataFrame, measure: str, between: str
                ) -> tuple[pd.DataFrame, int]:
    """One row per rater and intended emotion (their mean), complete raters only."""
    study = ratings.study
    levels = {s.id: intended_label(study, s.intended) for s in study.stimuli}
    rows = rows.assign(intended=rows["stimulus"].map(levels)).dropna(subset=["intended", "y"])
    cells = rows.groupby(["participant", "condition", "intended"], as_index=False)["y"].mean()
    per_rater = cells.groupby("participant")["intended"].nunique()
    full = per_rater.index[per_rater == cells["intended"].nunique()]
    data = cells[cells["participant"].isin(full)]
    return data.rename(columns={"y": measure, "condition": between}), len(per_rater) - len(full)


def _effect_rows(row: AnovaRow) -> list[list[str]]:
    out = []
    for effect in (row.result.within, row.result.between, row.result.interaction):
        name = "intended emotion" if effect is row.result.within else effect.source
        out.append([row.measure, name, f"F({effect.df1:g}, {effect.df2:g}) = {effect.f:.2f}",
                    fmt_p(effect.p_unc), fmt_p(effect.p_gg), fmt(effect.eps, 2),
                    fmt(effect.partial_eta_sq), fmt(effect.generalized_eta_sq)])
    return out


def anova_section(ratings: Ratings, section: Section) -> list[AnovaRow]:
    """Two-way mixed ANOVA of accuracy, valence and arousal (Carreno-Medrano et al. 2018).

    Within-subject factor: the intended emotion (dominant label); between-subject factor: the
    condition (the study's ``between``). Each rater's mean per intended emotion, raters
    lacking a level left out; Greenhouse-Geisser corrected p-values
    (:func:`emotive.eval.anova.mixed_anova`).
    """
    study = ratings.study
    label = study.between or "condition"
    between = label if label not in {"participant", "intended", "accuracy", *GRID_VALUES} \
        else "condition"
    section.add(f"Within: intended emotion (dominant label); between: `{label}` (the "
                "conditions). Each rater's mean per intended emotion; Greenhouse-Geisser "
                "correction (Carreno-Medrano et al. 2018, sections 7.1.3 and 7.2.2).", "")
    if len(ratings.conditions) < 2:
        section.skip("mixed ANOVA", f"the raters kept are all in one condition "
                     f"({', '.join(ratings.conditions) or 'none'}); the between factor "
                     f"`{label}` needs at least 2")
        return []
    results, lines = [], []
    for measure, rows in _measures(ratings):
        data, dropped = _anova_data(ratings, rows, measure, between)
        res = attempt(section, f"mixed ANOVA, {measure}", mixed_anova, data, dv=measure,
                      within="intended", between=between, subject="participant")
        if res is None:
            continue
        row = AnovaRow(measure, res, dropped)
        results.append(row)
        lines += _effect_rows(row)
    if results:
        section.add(*table(["measure", "effect", "F", "p", "p (GG)", "epsilon",
                            "partial eta²", "generalized eta²"], lines))
        for r in results:
            sphericity = ("Mauchly's test not available" if np.isnan(r.result.sphericity_p)
                          else f"Mauchly's W = {r.result.sphericity_w:.3f}, p = "
                          f"{fmt_p(r.result.sphericity_p)}"
                          + (" (violated: read p (GG))" if r.result.sphericity_violated
                             else ""))
            section.add(f"- {r.measure}: {r.result.n_subjects} raters in {r.result.n_groups} "
                        f"groups, {r.result.n_levels} intended emotions; {sphericity}"
                        + (f"; {r.dropped} rater(s) left out, lacking an intended emotion"
                           if r.dropped else "") + ".")
        section.add("")
    return results


# --------------------------------------------------------------------------------------------
# Repeats


def _pass_pairs(rows: pd.DataFrame, column: str) -> pd.DataFrame:
    """Per participant and stimulus, the value of pass 0 and of pass 1 (complete pairs)."""
    first = rows[rows["repeat"] == 0].groupby(["participant", "stimulus"])[column].first()
    second = rows[rows["repeat"] == 1].groupby(["participant", "stimulus"])[column].first()
    return first.to_frame("a").join(second.to_frame("b"), how="inner").dropna()


def repeats_section(ratings: Ratings, section: Section) -> dict[str, float]:
    """Each rater's consistency between the first and the second rating of a stimulus.

    Carreno-Medrano et al. 2018, section 7.2.1 showed every clip twice. A choice question: the
    share of stimuli given the same answer twice; a likert or grid value: the mean absolute
    difference (in the scale's units).

    Returns:
        Stored value name -> its mean over raters (share, or mean absolute difference).
    """
    names = [(name, q.kind) for q in ratings.study.questions for name in q.stored]
    section.add("Each rater's first (pass 0) against second (pass 1) rating of a stimulus: "
                "share of identical answers for a choice, mean absolute difference for a "
                "scale (Carreno-Medrano et al. 2018, section 7.2.1).", "")
    per_name: dict[str, dict[str, float]] = {}
    pairs_of: dict[str, int] = {}
    for name, kind in names:
        rows = ratings.of(name)
        pairs = _pass_pairs(rows, "value" if kind == "choice" else "num")
        for pid, group in pairs.groupby(level="participant"):
            same = group["a"] == group["b"] if kind == "choice" else None
            value = float(same.mean()) if same is not None else float(
                np.abs(group["a"].astype(float) - group["b"].astype(float)).mean())
            per_name.setdefault(name, {})[str(pid)] = value
            pairs_of[str(pid)] = max(pairs_of.get(str(pid), 0), len(group))
    if not pairs_of:
        section.skip("repeat consistency", "no rater kept rated a stimulus in both passes")
        return {}
    kinds = dict(names)
    headers = ["participant", "condition", "stimuli twice"] + [
        f"{n} ({'same' if kinds[n] == 'choice' else 'mean abs. diff.'})" for n in per_name]
    condition = ratings.rows.groupby("participant")["condition"].first()

    def cell(name: str, value: float | None) -> str:
        if value is None:
            return "-"
        return pct(value) if kinds[name] == "choice" else fmt(value, 2)

    lines = [[pid, condition.get(pid, ""), pairs_of[pid],
              *(cell(n, per_name[n].get(pid)) for n in per_name)] for pid in sorted(pairs_of)]
    means = {n: float(np.mean(list(v.values()))) for n, v in per_name.items()}
    lines.append(["**mean**", "", "", *(f"**{cell(n, means[n])}**" for n in per_name)])
    section.add(*table(headers, lines))
    return means
