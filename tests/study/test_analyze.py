"""``emotive study analyze`` on synthetic studies: simulated raters, their export, the report.

Each study is a ``StudyConfig`` from :func:`parse_study`; participants follow their real plans
(:func:`plan_for`) and answer by a rule drawn with a numpy seed; the export table goes through
a CSV round trip as ``emotive study export`` and ``pandas.read_csv`` would give it.
"""

from __future__ import annotations

import dataclasses
import io
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies

pd = pytest.importorskip("pandas")
pytest.importorskip("pingouin")
pytest.importorskip("statsmodels")
pytest.importorskip("matplotlib")

from emotive.data.emotion import Emotion, coerce_emotion  # noqa: E402
from emotive.study.analysis_data import (  # noqa: E402
    EXPORT_COLUMNS,
    agreement_matrix,
    careless_raters,
    prepare_frame,
)
from emotive.study.analyze import REPORT_FILE, AnalysisSummary, analyze_study  # noqa: E402
from emotive.study.config import (  # noqa: E402
    Question,
    Stimulus,
    StudyConfig,
    parse_study,
    stored_values,
)
from emotive.study.design import PlanItem, plan_for  # noqa: E402
from emotive.study.errors import StudyError  # noqa: E402

LABELS = ("happy", "sad", "angry", "neutral")
Answer = Callable[[np.random.Generator, int, PlanItem, Stimulus, Question], Any]


# ---------------------------------------------------------------------------------------------
# Synthetic studies and raters


def make_study(tmp_path: Path, questions: list[dict], stimuli: list[dict], *,
               checks: list[dict] | None = None, conditions: list[dict] | None = None,
               repeats: int = 1, between: str = "", title: str = "Synthetic") -> StudyConfig:
    data: dict[str, Any] = {
        "title": title, "completion_code": "EMO-TEST", "consent": "ok", "repeats": repeats,
        "between": between, "questions": questions, "stimuli": stimuli,
        "attention_checks": checks or [],
    }
    if conditions:
        data["conditions"] = conditions
    return parse_study(tmp_path, data, tmp_path / "study.toml")


def likert(qid: str, high: int = 5) -> dict:
    return {"id": qid, "kind": "likert", "prompt": qid, "min": 1, "max": high}


def _text(value: float | str) -> str:
    if isinstance(value, str):
        return value
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def simulate(study: StudyConfig, n: int, answer: Answer, seed: int,
             excluded: frozenset[int] = frozenset()) -> pd.DataFrame:
    """The export table of ``n`` participants, as read back from its CSV."""
    rng = np.random.default_rng(seed)
    rows = []
    for k in range(n):
        plan = plan_for(study, k)
        for it in plan.items:
            stimulus = study.stimulus(it.stimulus)
            for q in study.questions:
                value = answer(rng, k, it, stimulus, q)
                if q.kind == "grid":
                    value = dict(zip(("valence", "arousal"), value, strict=True))
                for name, stored in stored_values(q, value).items():
                    rows.append({
                        "participant": f"p-{k:03d}", "condition": plan.condition,
                        "stimulus": it.stimulus, "question": name, "value": _text(stored),
                        "time": "2025-01-01T00:00:00.000Z", "item": it.item,
                        "repeat": it.repeat, "check": it.check, "source": stimulus.source,
                        "intended": stimulus.intended, "rt_ms": 4000,
                        "excluded": int(k in excluded),
                    })
    csv = io.StringIO()
    pd.DataFrame(rows, columns=list(EXPORT_COLUMNS)).to_csv(csv, index=False)
    csv.seek(0)
    return pd.read_csv(csv)


def expected(study: StudyConfig, it: PlanItem, q: Question) -> Any:
    """The answer an attention check instructs, or ``None`` when it names no such question."""
    check = {c.id: c for c in study.checks}[it.check]
    return check.expect.get(q.id)


def read_report(summary: AnalysisSummary) -> str:
    assert summary.report.name == REPORT_FILE
    return summary.report.read_text(encoding="utf-8")


def assert_clean_folder(out: Path) -> None:
    """Only finished files: no temporary file of the atomic writes is left."""
    names = sorted(p.name for p in out.iterdir())
    assert REPORT_FILE in names
    assert not [n for n in names if n.startswith(".")], names


# ---------------------------------------------------------------------------------------------
# Gaits design: likert per emotion label, naturalness, an attention check

GAIT_INTENDED = ("happy", "sad", "angry", "neutral", "happy=0.5,neutral=0.5",
                 "sad=0.5,angry=0.5", "angry=0.5,happy=0.5", "sad=0.5,neutral=0.5")
CARELESS = frozenset({3, 7, 11})


def make_gaits(tmp_path: Path, repeats: int = 1) -> StudyConfig:
    stimuli = [{"id": f"s{i + 1:02d}", "file": f"stimuli/s{i + 1:02d}.glb",
                "source": "gait" if i < 6 else "recorded", "intended": text}
               for i, text in enumerate(GAIT_INTENDED)]
    check = {"id": "check-1", "stimulus": "s01", "position": 3,
             "instruction": "answer 1 on every emotion and 5 for naturalness",
             "expect": {**dict.fromkeys(LABELS, 1), "naturalness": 5}}
    return make_study(tmp_path, [*(likert(x) for x in LABELS), likert("naturalness")], stimuli,
                      checks=[check], repeats=repeats, title="Gaits")


@pytest.fixture
def gaits(tmp_path: Path) -> StudyConfig:
    return make_gaits(tmp_path)


def gait_rater(study: StudyConfig, careless: frozenset[int] = CARELESS,
               random_passing: frozenset[int] = frozenset(),
               misread: dict[str, str] | None = None) -> Answer:
    """Raters near the intended emotion; ``careless`` answer at random and fail the check,
    ``random_passing`` answer at random but pass it; every rater sees the stimuli of
    ``misread`` as that emotion instead."""

    def answer(rng: np.random.Generator, k: int, it: PlanItem, st: Stimulus, q: Question) -> Any:
        if it.check:
            return 3 if k in careless else expected(study, it, q)
        if k in careless or k in random_passing:
            return int(rng.integers(1, 6))
        if q.id == "naturalness":
            return int(rng.choice([2, 3, 4, 4, 5, 5]))
        weight = Emotion.parse((misread or {}).get(st.id, st.intended))[q.id]
        return int(np.clip(round(1 + 4 * weight + rng.normal(0, 0.5)), 1, 5))

    return answer


def run_gaits(study: StudyConfig, tmp_path: Path, n: int = 16, seed: int = 1,
              readings: dict | None = None, **kwargs: Any) -> AnalysisSummary:
    frame = simulate(study, n, gait_rater(study, **kwargs), seed, excluded=frozenset({5}))
    return analyze_study(study, frame, readings, tmp_path / "analysis")


def test_gaits_flags_careless_raters_exactly_and_keeps_intended_emotions(
        gaits: StudyConfig, tmp_path: Path) -> None:
    summary = run_gaits(gaits, tmp_path, misread={"s04": "sad"})
    assert summary.careless == ("p-003", "p-007", "p-011")
    assert summary.admin_excluded == ("p-005",)
    assert not set(summary.outliers) & set(summary.careless)
    removed = set(summary.careless) | set(summary.admin_excluded) | set(summary.outliers)
    assert set(summary.kept) == {f"p-{k:03d}" for k in range(16)} - removed
    assert (summary.participants, summary.completed) == (16, 16)
    assert summary.responses == 16 * (8 + 1)
    # Raters near the intended emotion: the 2-sample test rejects for few stimuli, and the
    # perceived vector's dominant label is the intended one for the single emotions.
    assert len(summary.emotion_tests) == 8
    assert summary.not_rejected >= 6
    tests = {t.stimulus: t for t in summary.emotion_tests}
    for sid in ("s01", "s02", "s03", "s05", "s06", "s07", "s08"):
        assert tests[sid].same_dominant and tests[sid].distance < 0.2
        assert tests[sid].raters == len(summary.kept)
    # The raters saw the neutral s04 as sad: the Anderson-Darling test compares the sets of
    # values, not label by label, so it cannot tell; the label-wise columns do.
    assert not tests["s04"].same_dominant and tests["s04"].distance > 0.8
    assert not tests["s04"].rejected
    assert set(summary.naturalness) == {"gait", "recorded"}
    assert all(0.5 < share <= 1.0 for share in summary.naturalness.values())
    # One rating per rater and stimulus: the k-sample tests pool stimuli by intended emotion.
    assert summary.consistency and all(t.unit.startswith("intended ") for t in summary.consistency)
    text = read_report(summary)
    assert "Careless raters" in text and "`p-003` (check-1)" in text
    assert "| s01 | gait |" in text
    assert summary.plots and all(p.is_file() for p in summary.plots)
    assert_clean_folder(tmp_path / "analysis")


def test_a_random_rater_who_passes_the_check_is_a_tukey_outlier(
        gaits: StudyConfig, tmp_path: Path) -> None:
    summary = run_gaits(gaits, tmp_path, n=16, seed=2, random_passing=frozenset({9}))
    assert "p-009" not in summary.careless
    assert "p-009" in summary.outliers
    assert "p-009" not in summary.kept
    assert len(summary.outliers) <= 2


def test_two_passes_test_consistency_per_stimulus_and_per_rater(tmp_path: Path) -> None:
    study = make_gaits(tmp_path, repeats=2)
    frame = simulate(study, 6, gait_rater(study, careless=frozenset()), seed=9)
    summary = analyze_study(study, frame, None, tmp_path / "out")
    assert summary.completed == 6 and summary.responses == 6 * (2 * 8 + 1)
    assert {t.unit for t in summary.consistency} <= {s.id for s in study.stimuli}
    assert len({t.unit for t in summary.consistency}) >= 4
    assert set(summary.repeat_consistency) == {*LABELS, "naturalness"}
    for question, mean_abs_diff in summary.repeat_consistency.items():
        assert 0.0 <= mean_abs_diff < (1.5 if question == "naturalness" else 0.8)
    assert "## Repeated ratings" in read_report(summary)


def test_a_failed_plot_leaves_the_previous_report_in_place(
        gaits: StudyConfig, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "analysis"
    first = run_gaits(gaits, tmp_path)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def broken(*args: Any, **kwargs: Any) -> None:
        raise RuntimeError("plot failed")

    monkeypatch.setattr("emotive.study.analysis_emotion.plot_emotion_bars", broken)
    with pytest.raises(RuntimeError, match="plot failed"):
        run_gaits(gaits, tmp_path, seed=10)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert first.report.is_file()


def test_agreement_ignores_a_raters_leniency(gaits: StudyConfig) -> None:
    frame = prepare_frame(simulate(gaits, 5, gait_rater(gaits, careless=frozenset()), seed=12))
    rated = frame[frame["check"] == ""]
    lenient = rated[rated["participant"] == "p-000"].assign(participant="p-lenient")
    lenient = lenient.assign(num=lenient["num"] + 1.0)
    matrix = agreement_matrix(gaits, pd.concat([rated, lenient]))
    assert matrix.shape == (5 * 8, 6)  # 5 likert questions x 8 stimuli, 6 raters
    np.testing.assert_allclose(matrix["p-lenient"], matrix["p-000"])
    np.testing.assert_allclose(matrix.groupby(level=0).mean(), 0.0, atol=1e-12)


def test_classifier_agreement_beside_the_raters(gaits: StudyConfig, tmp_path: Path) -> None:
    def reading(label: str, unsure: bool = False) -> dict:
        probs = {x: (0.7 if x == label else 0.1) for x in LABELS}
        return {"probabilities": probs, "valence": 0.1, "arousal": 0.2, "unsure": unsure,
                "perceived": "unsure" if unsure else label}

    readings = {"labels": list(LABELS), "stimuli": {
        "s01": reading("happy"), "s02": reading("sad"), "s03": reading("happy"),
        "s04": reading("neutral"), "s05": reading("happy", unsure=True),
        "s06": reading("sad"), "s07": reading("angry")}}  # s08: no reading
    summary = run_gaits(gaits, tmp_path, readings=readings)
    rows = {r.stimulus: r for r in summary.classifier}
    assert summary.readings_missing == ("s08",)
    assert summary.classifier_unsure == 1
    assert rows["s05"].agree is None and rows["s08"].agree is None
    assert rows["s01"].humans == ("happy",) and rows["s01"].agree is True
    assert rows["s03"].humans == ("angry",) and rows["s03"].agree is False
    compared = [r for r in summary.classifier if r.agree is not None]
    assert len(compared) == 6
    assert summary.classifier_agreement == pytest.approx(
        np.mean([r.agree for r in compared]))
    text = read_report(summary)
    assert "No classifier reading" in text and "`s08`" in text
    assert "classifier unsure: 1" in text


def test_without_readings_the_report_says_so(gaits: StudyConfig, tmp_path: Path) -> None:
    summary = run_gaits(gaits, tmp_path)
    assert summary.classifier_agreement is None
    assert any(s.startswith("classifier agreement: no classifier readings")
               for s in summary.skipped)


# ---------------------------------------------------------------------------------------------
# Affect grid: one grid question, generated and recorded sources

GRID_POINTS = ((-0.75, 0.75), (0.0, 0.75), (0.75, 0.75), (-0.75, -0.75), (0.0, -0.75),
               (0.75, -0.75))


def make_affect_grid(tmp_path: Path) -> StudyConfig:
    stimuli = [{"id": f"g{i + 1}", "file": f"stimuli/g{i + 1}.glb", "source": "fcrbm"}
               for i in range(len(GRID_POINTS))]
    stimuli += [{"id": f"r{i + 1}", "file": f"stimuli/r{i + 1}.glb", "source": "recorded",
                 "intended": label} for i, label in enumerate(LABELS)]
    check = {"id": "centre", "stimulus": "g1", "position": 2,
             "instruction": "click the centre cell", "expect": {"affect": [5, 5]}}
    grid = {"id": "affect", "kind": "grid", "prompt": "how does it feel?", "size": 9}
    study = make_study(tmp_path, [grid], stimuli, checks=[check], title="Affect grid")
    # Valence/arousal points as intended emotions (the FCRBM's stimuli).
    points = {f"g{i + 1}": f"valence={v:g},arousal={a:g}" for i, (v, a) in enumerate(GRID_POINTS)}
    return dataclasses.replace(study, stimuli=tuple(
        dataclasses.replace(s, intended=points.get(s.id, s.intended)) for s in study.stimuli))


@pytest.fixture
def affect_grid(tmp_path: Path) -> StudyConfig:
    return make_affect_grid(tmp_path)


def grid_rater(study: StudyConfig, careless: frozenset[int]) -> Answer:
    def cell(x: float) -> int:
        return int(np.clip(round((x + 1) / 2 * 8) + 1, 1, 9))

    def answer(rng: np.random.Generator, k: int, it: PlanItem, st: Stimulus, q: Question) -> Any:
        if it.check:
            return [1, 9] if k in careless else expected(study, it, q)
        if k in careless:
            return [int(rng.integers(1, 10)), int(rng.integers(1, 10))]
        v, a = coerce_emotion(st.intended, LABELS).points[0]
        v = 0.6 * v - (0.25 if st.source == "fcrbm" else 0.0)
        return [cell(v + rng.normal(0, 0.2)), cell(0.8 * a + rng.normal(0, 0.2))]

    return answer


def test_affect_grid_alpha_and_mann_whitney_between_sources(
        affect_grid: StudyConfig, tmp_path: Path) -> None:
    frame = simulate(affect_grid, 14, grid_rater(affect_grid, frozenset({2})), seed=3)
    summary = analyze_study(affect_grid, frame, None, tmp_path / "out")
    assert summary.careless == ("p-002",)  # clicked a corner, not the centre [5, 5]
    values = {a.value: a for a in summary.alphas}
    assert set(values) == {"valence", "arousal"}
    assert values["valence"].alpha > 0.8 and values["arousal"].alpha > 0.8
    assert values["arousal"].raters == len(summary.kept)
    assert values["arousal"].stimuli == 10
    tests = {t.value: t for t in summary.mann_whitney}
    assert set(tests) == {"valence", "arousal"}
    assert {(t.source_x, t.source_y) for t in tests.values()} == {("fcrbm", "recorded")}
    assert tests["valence"].n_x == 6 * len(summary.kept)
    assert tests["valence"].n_y == 4 * len(summary.kept)
    # Generated clips were rated less pleasant (by 0.25 on -1..1), arousal alike.
    assert tests["valence"].p_value < 0.05 and tests["valence"].rank_biserial < 0
    points = {p.stimulus: p for p in summary.affect}
    assert points["g3"].intended == pytest.approx((0.75, 0.75))
    low, high = points["g3"].ci[1]
    assert low < points["g3"].mean[1] < high and 0.3 < points["g3"].mean[1] < 0.9
    text = read_report(summary)
    assert "Cronbach's alpha" in text and "fcrbm vs recorded" in text
    assert "affect_grid.png" in text and (tmp_path / "out" / "affect_grid.png").is_file()
    assert "valence and arousal" not in " ".join(summary.skipped)
    assert any("one condition" in s or "all in one condition" in s for s in summary.skipped)
    assert_clean_folder(tmp_path / "out")


# ---------------------------------------------------------------------------------------------
# Forced choice with valence/arousal scales, two passes, conditions between subjects


def sources_study(tmp_path: Path, conditions: int) -> StudyConfig:
    stimuli, names = [], ("recorded", "resampled")[:conditions]
    for source in names:
        for i, label in enumerate(LABELS * 2):
            sid = f"{source[:3]}{i + 1}"
            stimuli.append({"id": sid, "file": f"stimuli/{sid}.glb", "source": source,
                            "intended": label})
    conds = [{"name": source, "stimuli": [s["id"] for s in stimuli if s["source"] == source]}
             for source in names]
    questions = [{"id": "emotion", "kind": "choice", "prompt": "which?", "options": list(LABELS)},
                 likert("confidence"), likert("valence", 7), likert("arousal", 7)]
    check = {"id": "check-1", "stimulus": stimuli[0]["id"], "position": 2,
             "instruction": "choose sad and 1", "expect": {"emotion": "sad", "valence": 1}}
    return make_study(tmp_path, questions, stimuli, checks=[check], conditions=conds,
                      repeats=2, between="source")


VA7 = {"happy": (6, 6), "sad": (2, 2), "angry": (2, 6), "neutral": (4, 3)}


def choice_rater(study: StudyConfig, careless: frozenset[int]) -> Answer:
    def answer(rng: np.random.Generator, k: int, it: PlanItem, st: Stimulus, q: Question) -> Any:
        if it.check:
            want = expected(study, it, q)
            if k in careless:
                return "happy" if q.kind == "choice" else 4
            return want if want is not None else (1 if q.kind == "likert" else "sad")
        if k in careless:
            return str(rng.choice(LABELS)) if q.kind == "choice" else int(rng.integers(1, 6))
        shift = 1 if st.source == "resampled" else 0
        if q.id == "emotion":
            return st.intended if rng.random() < 0.8 - 0.2 * shift else str(rng.choice(LABELS))
        if q.id == "confidence":
            return int(rng.integers(3, 6))
        base = VA7[st.intended][0 if q.id == "valence" else 1]
        return int(np.clip(base - shift + rng.integers(-1, 2), 1, 7))

    return answer


def test_forced_choice_two_conditions_runs_the_mixed_anova(tmp_path: Path) -> None:
    study = sources_study(tmp_path, conditions=2)
    frame = simulate(study, 20, choice_rater(study, frozenset({4})), seed=4)
    summary = analyze_study(study, frame, None, tmp_path / "out")
    assert summary.careless == ("p-004",)
    assert set(summary.accuracy) == set(LABELS)
    assert all(share > 0.5 for share in summary.accuracy.values())
    assert {k.condition for k in summary.kappas} == {"recorded", "resampled"}
    assert all(0.2 < k.kappa < 1.0 for k in summary.kappas)
    anova = {a.measure: a.result for a in summary.anova}
    assert set(anova) == {"accuracy", "valence", "arousal"}
    for result in anova.values():
        assert result.n_groups == 2 and result.n_levels == 4
        assert result.between.source == "source"
    # Intended emotion drives valence and arousal; resampled clips are one point lower.
    assert anova["valence"].within.p_gg < 0.001 and anova["arousal"].within.p_gg < 0.001
    assert anova["valence"].between.p_unc < 0.05
    # Two passes: each rater's consistency between them.
    assert set(summary.repeat_consistency) == {"emotion", "confidence", "valence", "arousal"}
    assert 0.4 < summary.repeat_consistency["emotion"] <= 1.0
    text = read_report(summary)
    assert "## Mixed ANOVA" in text and "| valence | intended emotion |" in text
    assert "## Repeated ratings" in text and "choice_confusion.png" in text
    assert_clean_folder(tmp_path / "out")


def test_forced_choice_one_condition_skips_the_anova_with_a_reason(tmp_path: Path) -> None:
    study = sources_study(tmp_path, conditions=1)
    frame = simulate(study, 8, choice_rater(study, frozenset()), seed=5)
    summary = analyze_study(study, frame, None, tmp_path / "out")
    assert summary.anova == ()
    reasons = [s for s in summary.skipped if s.startswith("mixed ANOVA")]
    assert len(reasons) == 1 and "one condition (recorded)" in reasons[0]
    assert "*mixed ANOVA*: not computed: the raters kept are all in one condition" in \
        read_report(summary)
    assert summary.kappas and summary.accuracy


# ---------------------------------------------------------------------------------------------
# Degenerate data: the report is still written, with reasons


def test_one_rater_still_writes_the_report_with_reasons(gaits: StudyConfig,
                                                        tmp_path: Path) -> None:
    frame = simulate(gaits, 1, gait_rater(gaits, careless=frozenset()), seed=6)
    summary = analyze_study(gaits, frame, {"labels": list(LABELS), "stimuli": {}},
                            tmp_path / "tiny")
    assert summary.kept == ("p-000",) and summary.outliers == ()
    assert any("Tukey fences need at least 3" in s for s in summary.skipped)
    assert any(s.startswith("consistency across raters") for s in summary.skipped)
    text = read_report(summary)
    for reason in summary.skipped:  # each one line of the report
        what, why = reason.split(": ", 1)
        assert f"- *{what}*: not computed: {why}." in text.splitlines()
    assert len(summary.readings_missing) == 8
    assert_clean_folder(tmp_path / "tiny")


def test_constant_answers_and_an_empty_export(affect_grid: StudyConfig, tmp_path: Path) -> None:
    def centre(rng: np.random.Generator, k: int, it: PlanItem, st: Stimulus, q: Question) -> Any:
        return [5, 5]

    frame = simulate(affect_grid, 4, centre, seed=7)
    summary = analyze_study(affect_grid, frame, None, tmp_path / "constant")
    assert summary.careless == () and summary.alphas == () and summary.mann_whitney == ()
    assert any(s.startswith("Cronbach's alpha, valence") for s in summary.skipped)
    assert any(s.startswith("Mann-Whitney U, arousal") for s in summary.skipped)
    empty = analyze_study(affect_grid, frame.iloc[0:0], None, tmp_path / "empty")
    assert empty.participants == 0 and empty.kept == ()
    assert "Joined (at least one answer): **0**" in read_report(empty)


def test_a_table_without_an_export_column_is_refused(gaits: StudyConfig, tmp_path: Path) -> None:
    frame = pd.DataFrame({c: [] for c in EXPORT_COLUMNS if c != "check"})
    with pytest.raises(StudyError, match=r"lacks the column\(s\) \['check'\]"):
        analyze_study(gaits, frame, None, tmp_path / "out")


def test_text_and_parsed_exports_read_alike(gaits: StudyConfig) -> None:
    frame = simulate(gaits, 3, gait_rater(gaits), seed=8)
    as_text = prepare_frame(frame.astype(str).replace("nan", ""))
    parsed = prepare_frame(frame)
    pd.testing.assert_frame_equal(as_text, parsed)


# ---------------------------------------------------------------------------------------------
# Attention checks, property-based: careless exactly when an answer differs from the instruction


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cells=strategies.lists(strategies.tuples(strategies.integers(1, 9),
                                                strategies.integers(1, 9)),
                             min_size=1, max_size=8))
def test_careless_exactly_when_the_grid_check_is_missed(affect_grid: StudyConfig,
                                                       cells: list[tuple[int, int]]) -> None:
    def answer(rng: np.random.Generator, k: int, it: PlanItem, st: Stimulus, q: Question) -> Any:
        return list(cells[k]) if it.check else [int(rng.integers(1, 10)), 5]

    frame = prepare_frame(simulate(affect_grid, len(cells), answer, seed=11))
    expected_ids = {f"p-{k:03d}" for k, cell in enumerate(cells) if cell != (5, 5)}
    assert set(careless_raters(affect_grid, frame)) == expected_ids
