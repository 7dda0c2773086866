"""``emotive study analyze``: the statistics of a perceptual study, as ``report.md`` and plots.

:func:`analyze_study` reads the export table (one row per stored answer value, the CSV of
``emotive study export``) and the classifier's readings of the stimuli, and writes into one
folder ``report.md`` and PNG plots, all or none (:func:`emotive.io.atomic.output_transaction`).
What the report holds depends on the study's questions (found by kind and id, not by template,
so custom studies work):

1. **Participants**: who joined and completed; careless raters (a failed attention check) and
   outlier raters (Tukey fences of their agreement with their condition, Carreno-Medrano et
   al. 2018, section 7.1.2), both excluded from the statistics with the admin's exclusions.
2. **Intended vs perceived emotion** (likert questions named after emotion labels): the
   2-sample Anderson-Darling test per stimulus and the k-sample test across raters
   (Bhattacharya et al. 2020, sections 6.3.1 and 6.3.3); **naturalness** (a likert question
   ``naturalness``; section 6.3.4).
3. **Forced choice** (a choice question whose options are emotion labels): accuracy per
   intended emotion, confusion matrix, Fleiss' kappa; the **mixed ANOVA** of accuracy, valence
   and arousal, intended emotion within and the conditions between subjects (Carreno-Medrano
   et al. 2018, sections 7.1.3 and 7.2.2).
4. **Valence and arousal** (a grid question, or likert ``valence``/``arousal``): means with
   95% intervals, Cronbach's alpha, Mann-Whitney U between sources (Alemi et al. 2015,
   section V.D).
5. **Repeated ratings** (``repeats > 1``): each rater's consistency between the passes.
6. **Classifier beside the humans**: the classifier's perceived label against the raters'.

A statistic that cannot be computed on the data (too few raters, constant ratings, one
condition) is one line of the report saying why, and is listed in
:attr:`AnalysisSummary.skipped`; it never raises.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.data.circumplex import VALENCE_AROUSAL, canonical_label, label_points
from emotive.io.atomic import atomic_output, output_error, output_transaction
from emotive.study.analysis_affect import (
    AlphaRow,
    AnovaRow,
    MannWhitneyRow,
    StimulusAffect,
    affect_names,
    affect_section,
    anova_section,
    repeats_section,
    unit_values,
)
from emotive.study.analysis_data import (
    OutlierGroup,
    Participation,
    Ratings,
    careless_raters,
    outlier_raters,
    participation,
    prepare_frame,
)
from emotive.study.analysis_emotion import (
    ConsistencyTest,
    EmotionTest,
    KappaRow,
    choice_section,
    consistency_section,
    emotion_choice,
    emotion_likerts,
    gaits_section,
    naturalness_section,
    perceived_vectors,
)
from emotive.study.analysis_text import Section, fmt, fmt_p, pct, plural, table
from emotive.study.config import StudyConfig

if TYPE_CHECKING:
    import pandas as pd

#: The report's file name in the output folder.
REPORT_FILE = "report.md"


@dataclass(frozen=True)
class ClassifierRow:
    """The classifier's reading of one stimulus beside the raters' label.

    Attributes:
        stimulus: the stimulus.
        humans: the raters' label(s): most frequent choice, most intense perceived label or the
            label nearest their mean valence/arousal; several when tied, ``()`` when unrated.
        classifier: the classifier's perceived label, ``unsure``, or ``""`` without a reading.
        unsure: the classifier was unsure of the clip.
        agree: whether the classifier's label is the raters' (``None`` when not compared).
    """

    stimulus: str
    humans: tuple[str, ...]
    classifier: str
    unsure: bool
    agree: bool | None


@dataclass(frozen=True)
class AnalysisSummary:
    """What :func:`analyze_study` found, for tests and the command line.

    Attributes:
        report: the ``report.md`` written.
        plots: the PNG plots written.
        participants: participants with at least one answer.
        completed: participants who answered every item of their plan.
        responses: items answered (submissions).
        admin_excluded: participants the admin excluded.
        careless: participants who failed an attention check.
        outliers: raters outside the Tukey fences of their condition (screened after the
            admin-excluded and careless ones were removed).
        kept: the raters whose answers enter the statistics.
        emotion_tests: the 2-sample Anderson-Darling test per stimulus (gaits design).
        not_rejected: how many of ``emotion_tests`` do not reject at 0.05.
        consistency: the k-sample Anderson-Darling tests across raters.
        naturalness: source -> share of naturalness ratings at least the scale's middle
            (``None``: no ``naturalness`` question).
        accuracy: intended option -> forced-choice accuracy, all conditions (``None``: no
            choice question with emotion options).
        kappas: Fleiss' kappa per condition.
        anova: the mixed ANOVA per measure.
        affect: mean valence/arousal per stimulus (-1..1).
        alphas: Cronbach's alpha per condition and value.
        mann_whitney: Mann-Whitney U per value and pair of sources.
        repeat_consistency: stored value -> mean over raters of their pass-to-pass
            consistency: share of identical choices, or mean absolute difference in scale
            units (``None``: one pass).
        classifier: the classifier's reading beside the raters', per stimulus.
        classifier_agreement: share of compared stimuli where they agree (``None``: none).
        classifier_unsure: stimuli the classifier was unsure of (left out of the share).
        readings_missing: stimuli without a classifier reading.
        skipped: ``"what: why"`` of every statistic not computed.
    """

    report: Path
    plots: tuple[Path, ...]
    participants: int
    completed: int
    responses: int
    admin_excluded: tuple[str, ...]
    careless: tuple[str, ...]
    outliers: tuple[str, ...]
    kept: tuple[str, ...]
    emotion_tests: tuple[EmotionTest, ...] = ()
    not_rejected: int = 0
    consistency: tuple[ConsistencyTest, ...] = ()
    naturalness: Mapping[str, float] | None = None
    accuracy: Mapping[str, float] | None = None
    kappas: tuple[KappaRow, ...] = ()
    anova: tuple[AnovaRow, ...] = ()
    affect: tuple[StimulusAffect, ...] = ()
    alphas: tuple[AlphaRow, ...] = ()
    mann_whitney: tuple[MannWhitneyRow, ...] = ()
    repeat_consistency: Mapping[str, float] | None = None
    classifier: tuple[ClassifierRow, ...] = ()
    classifier_agreement: float | None = None
    classifier_unsure: int = 0
    readings_missing: tuple[str, ...] = ()
    skipped: tuple[str, ...] = ()


# --------------------------------------------------------------------------------------------
# Participants


@dataclass(frozen=True)
class _Screen:
    """The raters removed before the statistics, and why."""

    admin: tuple[str, ...]
    careless: dict[str, tuple[str, ...]]
    groups: list[OutlierGroup]
    kept: tuple[str, ...]

    @property
    def outliers(self) -> tuple[str, ...]:
        return tuple(sorted(p for g in self.groups for p in g.flagged))


def _screen(study: StudyConfig, rows: pd.DataFrame, notes: Section) -> _Screen:
    admin = tuple(sorted(set(rows.loc[rows["excluded"] == 1, "participant"])))
    careless = careless_raters(study, rows)
    rated = rows[rows["check"] == ""]
    screened = rated[~rated["participant"].isin(set(admin) | set(careless))]
    groups = outlier_raters(study, screened, notes)
    flagged = {p for g in groups for p in g.flagged}
    kept = tuple(sorted(set(screened["participant"]) - flagged))
    return _Screen(admin, careless, groups, kept)


def _listed(ids: list[str], limit: int = 30) -> str:
    shown = ", ".join(f"`{i}`" for i in ids[:limit])
    return shown + (f" and {len(ids) - limit} more" if len(ids) > limit else "")


def _participants_lines(study: StudyConfig, people: Participation, screen: _Screen,
                        rows: pd.DataFrame, notes: Section, section: Section) -> None:
    kept_by = rows[rows["participant"].isin(screen.kept)].groupby("condition")["participant"]
    kept_n = kept_by.nunique().to_dict()
    lines = [[c, j, d, r, kept_n.get(c, 0)] for c, j, d, r in people.per_condition]
    section.add(
        *table(["condition", "joined", "completed", "items answered", "kept"], lines),
        f"- Joined (at least one answer): **{people.joined}**; completed: **{people.completed}**"
        f"; items answered: {people.responses} ({people.values} stored values).",
        f"- Excluded by the admin: {len(screen.admin)}"
        + (f" ({_listed(list(screen.admin))})." if screen.admin else "."))
    if not study.checks:
        section.add("- Careless raters: the study has no attention checks.")
    else:
        failed = [f"`{p}` ({', '.join(c)})" for p, c in sorted(screen.careless.items())]
        section.add(f"- **Careless raters** (answered an attention check otherwise than it "
                    f"instructed): **{len(failed)}**" + (f": {', '.join(failed)}." if failed
                                                         else "."))
    for g in screen.groups:
        flagged = [f"`{p}` ({fmt(g.agreement[g.tested.index(p)], 2)})" for p in g.flagged]
        section.add(f"- **Outlier raters**, condition {g.condition}: **{len(flagged)}** of "
                    f"{plural(len(g.tested), 'rater')} below Tukey's lower fence (Q1 - 1.5 IQR "
                    f"= {fmt(g.lower, 2)}; median agreement {np.nanmedian(g.agreement):.2f})"
                    + (f": {', '.join(flagged)}" if flagged else "")
                    + (f"; {len(g.untested)} not screened (rated only some stimuli)"
                       if g.untested else "") + ".")
    section.lines += notes.lines
    section.skipped += notes.skipped
    unknown = sorted(set(rows["stimulus"]) - {s.id for s in study.stimuli})
    if unknown:
        section.add(f"- Answers about stimuli not in study.toml (left out of the per-stimulus "
                    f"tables): {_listed(unknown)}.")
    total = len(set(screen.admin) | set(screen.careless) | set(screen.outliers))
    section.add(
        f"- **Kept for the statistics: {plural(len(screen.kept), 'rater')}** ({total} "
        f"removed: {len(screen.admin)} by the admin, {len(screen.careless)} careless, "
        f"{plural(len(screen.outliers), 'outlier')}).", "",
        "Careless raters are screened first; the outlier screen (Carreno-Medrano et al. 2018, "
        "section 7.1.2) then runs per condition on the others: a rater's agreement is the "
        "Spearman correlation of all their ratings (each scale scaled by its range and centred "
        "on the rater's own mean, each choice option as 0/1) with the mean of the other "
        "raters, and raters below Tukey's lower fence are outliers (a rater with constant "
        "answers has no correlation and is one).", "")


# --------------------------------------------------------------------------------------------
# Classifier


def _human_labels(ratings: Ratings, labels: list[str]) -> tuple[dict[str, tuple[str, ...]], str]:
    """Stimulus -> the raters' label(s), and how they were found."""
    study = ratings.study
    choice = emotion_choice(study)
    if choice is not None:
        out = {}
        for sid, group in ratings.of(choice.id).groupby("stimulus"):
            counts = group["value"].map(canonical_label).value_counts()
            out[str(sid)] = tuple(sorted(counts.index[counts == counts.max()]))
        return out, f"the raters' most frequent answer to `{choice.id}`"
    likerts = emotion_likerts(study)
    if likerts:
        names = [canonical_label(q.id) for q in likerts]
        means = {sid: v.mean(axis=0) for sid, v in perceived_vectors(ratings, likerts).items()}
        return ({sid: tuple(n for n, x in zip(names, m, strict=True) if x >= m.max() - 1e-9)
                 for sid, m in means.items()},
                "the most intense label of the raters' perceived emotion vector")
    known = [lab for lab in labels if lab in VALENCE_AROUSAL]
    if len(affect_names(ratings)) == 2 and known:
        points = label_points(known)
        va = np.stack([unit_values(ratings, n).mean(axis=1) for n in ("valence", "arousal")],
                      axis=1)
        sids = unit_values(ratings, "valence").index
        return ({str(sid): (known[int(np.argmin(((points - p) ** 2).sum(axis=1)))],)
                 for sid, p in zip(sids, va, strict=True) if np.all(np.isfinite(p))},
                "the label whose circumplex point is nearest the raters' mean valence/arousal")
    return {}, ""


def _number(value: Any) -> float:
    """A reading's number, NaN when it is missing or not a number."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def _classifier_rows(ratings: Ratings, readings: Mapping[str, Any]
                     ) -> tuple[list[ClassifierRow], list[list[str]], str]:
    labels = [canonical_label(str(x)) for x in readings.get("labels", [])]
    humans, how = _human_labels(ratings, labels)
    read = readings.get("stimuli", {}) or {}
    rows, lines = [], []
    for s in ratings.study.stimuli:
        reading = read.get(s.id)
        human = humans.get(s.id, ())
        if reading is None:
            rows.append(ClassifierRow(s.id, human, "", False, None))
            lines.append([s.id, s.source or "-", s.intended or "-", "/".join(human) or "-",
                          "(no reading)", "-", "-", "-"])
            continue
        perceived = str(reading.get("perceived", ""))
        unsure = bool(reading.get("unsure", False)) or perceived == "unsure"
        agree = None if unsure or not human else canonical_label(perceived) in human
        rows.append(ClassifierRow(s.id, human, perceived, unsure, agree))
        probs = reading.get("probabilities", {}) or {}
        top = max((_number(p) for p in probs.values()), default=float("nan"))
        va = f"{fmt(_number(reading.get('valence')), 2)}, " \
             f"{fmt(_number(reading.get('arousal')), 2)}"
        lines.append([s.id, s.source or "-", s.intended or "-", "/".join(human) or "-",
                      perceived + (" (unsure)" if unsure and perceived != "unsure" else ""),
                      fmt(top, 2), va, "-" if agree is None else ("yes" if agree else "**no**")])
    return rows, lines, how


def _classifier_section(ratings: Ratings, readings: Mapping[str, Any] | None,
                        section: Section) -> tuple[list[ClassifierRow], float | None, int,
                                                   tuple[str, ...]]:
    """The classifier's perceived label of each stimulus beside the raters' label."""
    if readings is None:
        section.skip("classifier agreement", "no classifier readings (stimuli/readings.json); "
                     "make them with `emotive study init` or give the readings")
        return [], None, 0, ()
    rows, lines, how = _classifier_rows(ratings, readings)
    section.add(f"The classifier's label of each stimulus (`stimuli/readings.json`) beside the "
                f"raters' label: {how or 'none (the study has no emotion question)'}. p: the "
                "classifier's probability of its most likely label.", "")
    section.add(*table(["stimulus", "source", "intended", "raters", "classifier", "p",
                        "classifier v, a", "agree"], lines))
    compared = [r for r in rows if r.agree is not None]
    unsure = sum(r.unsure for r in rows)
    missing = tuple(r.stimulus for r in rows if not r.classifier)
    share = float(np.mean([r.agree for r in compared])) if compared else None
    if compared:
        section.add(f"- Agreement: **{sum(bool(r.agree) for r in compared)} of "
                    f"{len(compared)}** stimuli ({pct(share)}).")
    else:
        section.skip("classifier agreement", "no stimulus has both a sure classifier reading "
                     "and a label from the raters")
    section.add(f"- Left out, the classifier unsure: {unsure}.")
    if missing:
        section.add(f"- **No classifier reading** for "
                    f"{plural(len(missing), 'stimulus', 'stimuli')}: {_listed(list(missing))}.")
    section.add("")
    return rows, share, unsure, missing


# --------------------------------------------------------------------------------------------
# The report


def _analyses(ratings: Ratings, readings: Mapping[str, Any] | None, out: Path
              ) -> tuple[list[Section], dict[str, Any], list[str]]:
    """Run every analysis the study's questions allow; sections, summary fields, not applicable."""
    study, found, sections, absent = ratings.study, {}, [], []
    if emotion_likerts(study):
        sec = Section("Intended vs perceived emotion")
        found["emotion_tests"] = tuple(gaits_section(ratings, out, sec))
        found["not_rejected"] = sum(not t.rejected for t in found["emotion_tests"])
        found["consistency"] = tuple(consistency_section(ratings, sec))
        sections.append(sec)
    else:
        absent.append("intended vs perceived emotion (no likert questions named after emotion "
                      "labels)")
    likert_ids = {q.id: q for q in study.questions if q.kind == "likert"}
    if "naturalness" in likert_ids:
        sec = Section("Naturalness")
        found["naturalness"] = naturalness_section(ratings, likert_ids["naturalness"], sec)
        sections.append(sec)
    choice = emotion_choice(study)
    if choice is not None:
        sec = Section("Forced choice")
        found["accuracy"], kappas = choice_section(ratings, choice, out, sec)
        found["kappas"] = tuple(kappas)
        sections.append(sec)
    else:
        absent.append("forced choice (no choice question with emotion labels as options)")
    if choice is not None or affect_names(ratings):
        sec = Section("Mixed ANOVA")
        found["anova"] = tuple(anova_section(ratings, sec))
        sections.append(sec)
    if affect_names(ratings):
        sec = Section("Valence and arousal")
        points, alphas, tests = affect_section(ratings, out, sec)
        found.update(affect=tuple(points), alphas=tuple(alphas), mann_whitney=tuple(tests))
        sections.append(sec)
    else:
        absent.append("valence and arousal (no grid question, no likert valence/arousal)")
    if study.repeats > 1:
        sec = Section("Repeated ratings")
        found["repeat_consistency"] = repeats_section(ratings, sec)
        sections.append(sec)
    else:
        absent.append("repeated ratings (each stimulus is rated once)")
    sec = Section("Classifier beside the humans")
    rows, share, unsure, missing = _classifier_section(ratings, readings, sec)
    found.update(classifier=tuple(rows), classifier_agreement=share, classifier_unsure=unsure,
                 readings_missing=missing)
    sections.append(sec)
    return sections, found, absent


def _p_text(p: float) -> str:
    text = fmt_p(p)
    return text if text.startswith("<") else f"= {text}"


def _glance(screen: _Screen, found: Mapping[str, Any]) -> list[str]:
    """The headline numbers, one bullet each."""
    out = [f"- Raters kept: **{len(screen.kept)}**."]
    if found.get("emotion_tests"):
        out.append(f"- Intended vs perceived emotion (Anderson-Darling): not rejected for "
                   f"**{found['not_rejected']} of {len(found['emotion_tests'])}** stimuli.")
    if found.get("accuracy"):
        out.append("- Forced-choice accuracy: " + ", ".join(
            f"{k} {pct(v)}" for k, v in found["accuracy"].items()) + ".")
    if found.get("kappas"):
        out.append("- Fleiss' kappa: " + ", ".join(
            f"{k.kappa:.3f} ({k.condition})" for k in found["kappas"]) + ".")
    if found.get("alphas"):
        out.append("- Cronbach's alpha: " + ", ".join(
            f"{a.value} {a.alpha:.3f} ({a.condition})" for a in found["alphas"]) + ".")
    for row in found.get("anova", ()):
        effect = row.result.within
        out.append(f"- Mixed ANOVA, {row.measure}: intended emotion F({effect.df1:g}, "
                   f"{effect.df2:g}) = {effect.f:.2f}, p (GG) {_p_text(effect.p_gg)}; "
                   f"{row.result.between.source} p {_p_text(row.result.between.p_unc)}.")
    if found.get("mann_whitney"):
        out.append("- Mann-Whitney U between sources: " + ", ".join(
            f"{t.value} {t.source_x} vs {t.source_y} p {_p_text(t.p_value)}"
            for t in found["mann_whitney"]) + ".")
    if found.get("classifier_agreement") is not None:
        out.append(f"- Classifier agrees with the raters on "
                   f"{pct(found['classifier_agreement'])} of the stimuli it was sure of.")
    return [*out, ""]


def _write(out: Path, study: StudyConfig, screen: _Screen, people: Section,
           sections: list[Section], found: Mapping[str, Any], absent: list[str]) -> Path:
    lines = [f"# Study analysis: {study.title}", "",
             f"Study `{study.folder.name}` (template `{study.template}`, "
             f"{plural(len(study.stimuli), 'stimulus', 'stimuli')}, "
             f"{plural(len(study.conditions), 'condition')}, "
             f"{plural(study.repeats, 'pass', 'passes')}). Only "
             "the kept raters' answers enter the statistics below; attention-check items are "
             "left out of them.", "", "## At a glance", "", *_glance(screen, found)]
    for section in [people, *sections]:
        lines += section.markdown()
    if absent:
        lines += ["## Not applicable to this study", "", *(f"- {a}" for a in absent), ""]
    path = out / REPORT_FILE
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(lines).rstrip() + "\n", encoding="utf-8")
    return path


def analyze_study(study: StudyConfig, frame: pd.DataFrame, readings: Mapping[str, Any] | None,
                  out: str | Path) -> AnalysisSummary:
    """Analyse a study's answers: write ``out/report.md`` and its plots, return the summary.

    The sections and the papers they follow are listed in the module docstring. Every file is
    written atomically, and all of them together or none
    (:func:`emotive.io.atomic.output_transaction`); files of the same names are replaced.

    Args:
        study: the study's design (``study.toml``).
        frame: the export table, columns
            :data:`~emotive.study.analysis_data.EXPORT_COLUMNS`, one row per stored value
            (e.g. ``pandas.read_csv`` of ``emotive study export``; text or parsed numbers).
        readings: the classifier's readings (``stimuli/readings.json``:
            ``{"labels": [...], "stimuli": {id: {"probabilities", "valence", "arousal",
            "unsure", "perceived"}}}``), or ``None`` when there are none.
        out: the output folder (made if missing).

    Returns:
        The summary: participants, raters removed and kept, and every statistic computed.

    Raises:
        StudyError: the table lacks an export column.
        OutputError: a file could not be written (then none is).
    """
    rows = prepare_frame(frame)
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc) from exc
    people, notes = Section("Participants"), Section("")
    counts = participation(study, rows)
    screen = _screen(study, rows, notes)
    _participants_lines(study, counts, screen, rows, notes, people)
    kept = rows[(rows["check"] == "") & rows["participant"].isin(set(screen.kept))]
    ratings = Ratings(study, kept.reset_index(drop=True))
    with output_transaction():
        sections, found, absent = _analyses(ratings, readings, out)
        report = _write(out, study, screen, people, sections, found, absent)
    return AnalysisSummary(
        report=report, plots=tuple(p for s in sections for p in s.plots),
        participants=counts.joined, completed=counts.completed, responses=counts.responses,
        admin_excluded=screen.admin, careless=tuple(sorted(screen.careless)),
        outliers=screen.outliers, kept=screen.kept,
        skipped=tuple(s for sec in [people, *sections] for s in sec.skipped), **found)
