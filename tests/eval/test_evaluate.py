"""``emotive evaluate``: sources, suites, reports and the command, on real clips."""

from __future__ import annotations

import json
import shutil
import sys

import numpy as np
import pytest

from emotive.cli import main
from emotive.data.emotion import DEFAULT_LABELS, EmotionSchedule
from emotive.eval import report as report_mod
from emotive.eval import suites
from emotive.eval.classifier import load_default_classifier
from emotive.eval.evaluate import EvaluationError, Subject, resolve_subject, run_suites
from emotive.eval.sources import (
    EvaluatedMotion,
    SourceError,
    from_generator,
    read_folder,
    standard_requests,
)
from emotive.io.bvh import read_bvh
from emotive.models.api import Capabilities, Generated, GenerationRequest

#: The classifier's held-out test clips (see its model card).
#: The classifier's held-out dataset-1 locomotion clips of its four labels.
TEST_CLIPS = ("walk-left_normal_001", "walk-right_sad_001", "walk_angry_002", "walk_happy_002")


@pytest.fixture
def folder(bandai1_dir, tmp_path):
    out = tmp_path / "clips"
    out.mkdir()
    for name in TEST_CLIPS:
        shutil.copy(bandai1_dir / "data" / f"dataset-1_{name}.bvh", out)
    return out


@pytest.fixture(scope="module")
def classifier():
    return load_default_classifier()


@pytest.mark.data
class TestSources:
    def test_bandai_names_and_labels_json(self, folder, bandai1_dir):
        shutil.copy(bandai1_dir / "data" / "dataset-1_walk_sad_002.bvh", folder / "mine.bvh")
        shutil.copy(bandai1_dir / "data" / "dataset-1_walk_proud_001.bvh", folder)
        (folder / "labels.json").write_text(json.dumps({"mine.bvh": {
            "schedule": [{"t": 0, "emotion": "sad"}, {"t": 2, "emotion": "happy"}],
            "path": [[0, 0], [1, 5], [0, 10]],
        }}))
        items = {i.name: i for i in read_folder(folder)}
        # proud is not one of the four labels: left out.
        assert sorted(items) == sorted([f"dataset-1_{n}.bvh" for n in TEST_CLIPS] + ["mine.bvh"])
        happy = items["dataset-1_walk_happy_002.bvh"]
        assert happy.labels == DEFAULT_LABELS and happy.path is None
        np.testing.assert_array_equal(happy.intended, np.tile([1.0, 0, 0, 0], (135, 1)))
        mine = items["mine.bvh"]
        assert mine.intended.shape == (mine.motion.num_frames, 4)
        np.testing.assert_allclose(mine.intended[0], [0, 1, 0, 0])
        np.testing.assert_allclose(mine.intended[30], [0.5, 0.5, 0, 0])
        # At 1 s the weights tie and the first label (happy) wins: the change is at frame 30.
        assert list(mine.changes) == [30] and mine.path is not None

    @pytest.mark.parametrize(("labels", "words"), [
        ("not json", "not valid JSON"),
        ('{"ghost.bvh": {"emotion": "sad"}}', "not there"),
        ('{"x.bvh": {"mood": "sad"}}', '"emotion" or "schedule"'),
        ('{"x.bvh": {"emotion": "sadd"}}', "sadd"),
        ('{"x.bvh": {"emotion": "sad", "path": "nowhere"}}', "unknown path"),
    ])
    def test_bad_labels_json(self, folder, labels, words):
        shutil.copy(folder / "dataset-1_walk_happy_002.bvh", folder / "x.bvh")
        (folder / "labels.json").write_text(labels)
        with pytest.raises(SourceError, match=words):
            read_folder(folder)

    def test_unlabelled_files_are_named(self, folder):
        shutil.copy(folder / "dataset-1_walk_happy_002.bvh", folder / "walk.bvh")
        with pytest.raises(SourceError, match=r"no intended emotion for \['walk.bvh'\]"):
            read_folder(folder)

    def test_not_a_folder(self, tmp_path):
        with pytest.raises(SourceError, match="not a folder"):
            read_folder(tmp_path / "nope")
        with pytest.raises(SourceError, match=r"no \.bvh files"):
            read_folder(tmp_path)


@pytest.mark.data
def test_emotion_suite_on_the_classifiers_own_test_clips_matches_its_card(folder, classifier):
    result = suites.emotion_suite(read_folder(folder), classifier)
    test = classifier.metrics["test_by_dataset"]["bandai-namco-1"]
    assert result["windows"] == test["windows"]
    assert result["confusion"] == test["confusion"]
    assert result["share_of_real_accuracy"] == pytest.approx(1.0)
    for row in result["items"]:
        assert set(row["table3"]) >= {"statistic", "p_value", "reject"}


@pytest.mark.data
def test_path_suite_on_a_clips_own_track(folder):
    from scipy.ndimage import uniform_filter1d

    item = next(i for i in read_folder(folder) if "walk_angry" in i.name)
    track = item.motion.positions_with_end_sites()[:, 1][:, [0, 2]]
    on_path = EvaluatedMotion(item.name, item.motion, item.intended, item.labels, track)
    # The track smoothed over a second and moved 0.5 m sideways: the hips sway a few cm.
    smooth = uniform_filter1d(track, 30, axis=0, mode="nearest")
    tangent = np.gradient(smooth, axis=0)
    normal = np.stack((-tangent[:, 1], tangent[:, 0]), 1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    beside = EvaluatedMotion("beside", item.motion, item.intended, item.labels,
                             smooth + 0.5 * normal)
    rows = suites.path_suite([on_path, beside])["items"]
    assert rows[0]["mean_position_deviation"] < 0.01
    assert rows[1]["mean_position_deviation"] == pytest.approx(0.5, abs=0.05)
    assert rows[1]["mean_heading_deviation"] < 20.0


@pytest.mark.data
def test_longrun_flags_a_frozen_clip(folder, classifier):
    item = read_folder(folder)[3]
    still = item.motion.replace(rotations=np.repeat(item.motion.rotations[:1], 300, 0),
                                positions=np.repeat(item.motion.positions[:1], 300, 0))
    frozen = EvaluatedMotion("frozen", still, np.tile(item.intended[:1], (300, 1)), item.labels)
    reference = suites.real_reference(classifier.labels)
    rows = suites.longrun_suite([item, frozen], reference)["items"]
    assert rows[0]["stable"] and rows[0]["share_in_real_band"] > 0.5
    assert not rows[1]["stable"] and rows[1]["collapsed_at"] == 0.0
    assert rows[1]["share_in_real_band"] == 0.0


class ReplayGenerator:
    """Plays a real clip of the request's first intended emotion (a stand-in generator)."""

    name = "replay"
    labels = DEFAULT_LABELS
    capabilities = Capabilities(paths=True, blends=True, schedules=True, valence_arousal=False,
                                primer=False, max_seconds=60.0)

    def __init__(self, clips: dict[str, object]) -> None:
        self.clips = clips

    def generate(self, request: GenerationRequest, progress: bool = False) -> Generated:
        label = request.schedule.labels[int(request.schedule.weights[0].argmax())]
        motion = self.clips[label]
        emotion = request.schedule.sample(motion.fps, num_frames=motion.num_frames)
        return Generated(motion, emotion, request.schedule.labels, request.path)


@pytest.mark.data
def test_a_generator_is_evaluated_like_a_folder(folder, classifier):
    clips = {"happy": "walk_happy_002", "sad": "walk-right_sad_001", "angry": "walk_angry_002",
             "neutral": "walk-left_normal_001"}
    generator = ReplayGenerator({k: read_bvh(folder / f"dataset-1_{v}.bvh")
                                 for k, v in clips.items()})
    requests = standard_requests(seconds=4.0)
    assert [r.name for r in requests] == [*DEFAULT_LABELS, "angry-to-happy", "sad-to-happy"]
    items = from_generator(generator, requests)
    assert items[-1].changes.size == 1 and items[0].path is not None
    results, info = run_suites(Subject("replay", generator=generator), "all", classifier)
    assert set(results) == {"emotion", "transition", "path", "longrun", "quality", "affect",
                            "speed"}
    assert [r["agents"] for r in results["speed"]["rows"]] == [1, 10]
    assert results["speed"]["rows"][0]["agent_frames_per_second"] > 0
    assert len(results["transition"]["items"]) == 2
    assert info["model"] == "replay"


def test_subjects_and_suites_are_checked(tmp_path):
    with pytest.raises(EvaluationError, match="zero-velocity"):
        resolve_subject(tmp_path / "missing")
    folder_subject = Subject("f", read_motions=list)
    with pytest.raises(EvaluationError, match="needs a predictor"):
        run_suites(folder_subject, "table1")
    with pytest.raises(EvaluationError, match="needs a generator"):
        run_suites(folder_subject, "speed")
    with pytest.raises(EvaluationError, match="unknown suite"):
        run_suites(folder_subject, "everything")


@pytest.mark.data
def test_cli_writes_a_complete_report(folder, tmp_path, monkeypatch, capsys):
    out = tmp_path / "report"
    monkeypatch.setattr(sys, "argv", ["emotive", "evaluate", "--model", str(folder), "--out",
                                      str(out)])
    with pytest.raises(SystemExit) as exc:
        main()
    assert exc.value.code in (0, None), capsys.readouterr().err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["confusion.png", "energy.png", "intended_vs_perceived.png", "metrics.json",
                     "report.md"]
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics["suites"]) == {"emotion", "transition", "path", "longrun", "quality",
                                      "affect"}
    text = (out / "report.md").read_text()
    for heading in ("## emotion", "## longrun", "## quality", "![confusion.png]"):
        assert heading in text


@pytest.mark.data
def test_a_failed_report_leaves_the_old_one(folder, tmp_path, monkeypatch, classifier):
    out = tmp_path / "report"
    results, info = run_suites(resolve_subject(folder), "emotion", classifier)
    report_mod.write_report(out, "first", results, info)
    before = (out / "report.md").read_text()

    def broken(result, where):
        raise RuntimeError("plot failed")

    monkeypatch.setitem(report_mod._PLOTS, "emotion", broken)
    with pytest.raises(RuntimeError, match="plot failed"):
        report_mod.write_report(out, "second", results, info)
    assert (out / "report.md").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clips", "report"]


def test_schedule_requests_switch_in_the_middle():
    requests = standard_requests(seconds=10.0)
    transition = next(r for r in requests if r.name == "angry-to-happy")
    assert isinstance(transition.schedule, EmotionSchedule)
    np.testing.assert_allclose(transition.schedule.at(4.0), [0, 0, 1, 0])
    np.testing.assert_allclose(transition.schedule.at(6.0), [1, 0, 0, 0])


@pytest.mark.data
def test_table1_suite_for_a_predictor(bandai1_dir, bandai2_dir, classifier, monkeypatch):
    subject = resolve_subject("zero-velocity")
    assert [b.name for b in suites.table1_baselines(subject.predictor)] == ["QuaterNet"]
    # QuaterNet on every window at two rates takes a minute; the suite's real numbers are
    # checked by test_headline_numbers.py.
    monkeypatch.setattr(suites, "table1_baselines", lambda predictor: [])
    results, _ = run_suites(subject, "all", classifier)
    assert list(results) == ["table1"]
    by_set = results["table1"]["results"]["10 fps"]
    assert list(by_set) == ["dataset 1", "dataset 2", "both"]
    at10 = by_set["dataset 1"]
    assert (at10["primer_frames"], at10["predicted_frames"]) == (18, 42)
    assert list(at10["predictors"]) == ["Zero velocity"]
    zero = at10["predictors"]["Zero velocity"]["overall"]
    assert zero["windows"] == at10["windows"] > 0
    assert 0 < zero["pose"] < 1 and zero["rotation"] > 0
    assert by_set["both"]["windows"] == at10["windows"] + by_set["dataset 2"]["windows"]
    horizon = results["table1"]["horizon"]["both"]
    assert horizon["frames"][-1] == 42 and len(horizon["pose"]["Zero velocity"]) == 8
    assert "| Zero velocity |" in results["table1"]["markdown"]


@pytest.mark.data
def test_affect_suite_distances_and_diversity(folder, classifier):
    from dataclasses import replace

    items = [i for i in read_folder(folder) if "walk_angry" in i.name or "happy" in i.name]
    reference = suites.real_reference(classifier.labels)
    angry = next(i for i in items if "angry" in i.name)
    own = suites.affect_features(angry.motion)
    shift = np.linspace(0.1, 0.3, own.shape[1])
    # Real "held-out" angry motion equal to the item, and happy equal to it shifted by a
    # constant: same covariance, so the Fréchet distance is |shift|^2.
    fake = replace(reference, held_out={**reference.held_out, "angry": own,
                                        "happy": suites.affect_features(items[-1].motion)
                                        + shift})
    rows = {r["label"]: r for r in suites.affect_suite(items, fake)["labels"]}
    assert rows["angry"]["frechet_to_real"] == pytest.approx(0.0, abs=1e-6)
    assert rows["happy"]["frechet_to_real"] == pytest.approx(float(shift @ shift), rel=1e-6)
    assert "diversity" not in rows["angry"]
    twice = [items[-1], replace(items[-1], name="again")]
    row = suites.affect_suite(twice, fake)["labels"][0]
    assert row["diversity"] == pytest.approx(0.0) and len(row["items"]) == 2


@pytest.mark.data
def test_quality_suite_jerk_and_skate_against_real(folder, classifier):
    reference = suites.real_reference(classifier.labels)
    result = suites.quality_suite(read_folder(folder), reference)
    assert result["real_jerk"] == pytest.approx(reference.jerk)
    assert result["jerk_vs_real"] == pytest.approx(result["mean_jerk"] / reference.jerk)
    assert all(r["jerk"] > 0 and r["skate_speed"] >= 0 for r in result["items"])


def test_registered_models_resolve_by_their_kinds():
    from emotive.models.gait.model import default_checkpoint_path

    gait = resolve_subject("gait")
    assert gait.provides() == {"motions", "paths", "transitions", "predictor", "generator"}
    assert gait.predictor.name == "Ours" and gait.name == "gait"
    assert resolve_subject("gait-no-root-loss").predictor.name == "gait-no-root-loss"
    assert resolve_subject("quaternet").provides() == {"predictor"}
    assert resolve_subject("zero-velocity").provides() == {"predictor"}
    # The FCRBM follows no path; the LGB makes neither paths nor transitions.
    assert resolve_subject("fcrbm").provides() == {"motions", "transitions", "generator"}
    assert resolve_subject("lgb", workers=1).provides() == {"motions", "generator"}
    assert resolve_subject(str(default_checkpoint_path())).provides() == gait.provides()
    with pytest.raises(EvaluationError, match=r"'fcrmb' \(did you mean 'fcrbm'\?\)"):
        resolve_subject("fcrmb")
    with pytest.raises(EvaluationError, match="gait, gait-no-affective"):
        resolve_subject("no-such-model")


def test_suites_follow_the_capabilities():
    fcrbm = resolve_subject("fcrbm")
    with pytest.raises(EvaluationError, match="suite 'path' needs motions along paths"):
        run_suites(fcrbm, "path")
    lgb = resolve_subject("lgb")
    with pytest.raises(EvaluationError, match="needs motions whose emotion changes"):
        run_suites(lgb, "transition")


def test_requests_are_reduced_to_what_a_generator_honours():
    from emotive.eval.sources import requests_for
    from emotive.models.fcrbm.adapter import CAPABILITIES as FCRBM
    from emotive.models.lgb.adapter import CAPABILITIES as LGB

    requests = standard_requests(seconds=4.0)
    lgb = requests_for(LGB, requests)
    assert [r.name for r in lgb] == list(DEFAULT_LABELS)
    assert all(r.path is None for r in lgb)
    fcrbm = requests_for(FCRBM, requests)
    assert [r.name for r in fcrbm] == [r.name for r in requests]
    assert all(r.path is None and r.seconds == 4.0 for r in fcrbm)


def test_fcrbm_quality_report_through_the_api(tmp_path, classifier):
    from emotive.eval.report import write_report

    subject = resolve_subject("fcrbm")
    requests = standard_requests(classifier.labels, seconds=2.0)[:2]
    results, info = run_suites(subject, "quality", classifier, requests=requests)
    write_report(tmp_path / "out", subject.name, results, info)
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert [r["name"] for r in metrics["suites"]["quality"]["items"]] == ["happy", "sad"]
    assert info["model"] == "fcrbm"


def test_the_evaluate_command_on_the_fcrbm(tmp_path):
    import typer
    from typer.testing import CliRunner

    from emotive.commands.evaluate import SUITE_NAMES, evaluate
    from emotive.eval.evaluate import SUITES
    from emotive.models.registry import REGISTRY

    assert SUITE_NAMES == tuple(SUITES)
    app = typer.Typer()
    app.command()(evaluate)
    app.command("unused")(lambda: None)
    helped = CliRunner().invoke(app, ["evaluate", "--help"], terminal_width=400)
    for name in (*REGISTRY, *SUITE_NAMES):
        assert name in helped.output
    out = tmp_path / "report"
    run = CliRunner().invoke(app, ["evaluate", "--model", "fcrbm", "--suite", "quality",
                                   "--out", str(out), "--seconds", "2", "--option",
                                   "gibbs=None"])
    assert run.exit_code == 0, run.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert len(metrics["suites"]["quality"]["items"]) == 6


class Restyle:
    """A stand-in transfer model: the input, relabelled."""

    name = "restyle"
    labels = ("happy", "sad")

    def transfer(self, motion, style, progress=False) -> Generated:
        return Generated(motion, style.sample(motion.fps, num_frames=motion.num_frames),
                         style.labels)


def test_a_transfer_model_is_judged_on_clips_in_each_label(random_motion, classifier):
    from emotive.eval.evaluate import transfer_subject

    clip = random_motion(frames=40)
    item = EvaluatedMotion("clip", clip, np.tile([0, 0, 0, 1.0], (40, 1)), DEFAULT_LABELS)
    subject = transfer_subject(Restyle(), DEFAULT_LABELS, clips=lambda: [item])
    assert subject.provides() == {"motions"}
    motions = subject.read_motions()
    assert [m.name for m in motions] == ["clip -> happy", "clip -> sad"]
    np.testing.assert_array_equal(motions[1].intended, np.tile([0, 1.0], (40, 1)))


def test_the_classifier_and_mar_are_evaluable_subjects():
    subject = resolve_subject("classifier")
    assert subject.provides() == {"motions"} and subject.classifier is not None
    from emotive.models.registry import REGISTRY

    for name in REGISTRY:
        if name not in ("mar", "classifier"):
            assert resolve_subject(name).provides(), name
