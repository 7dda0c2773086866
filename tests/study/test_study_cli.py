"""``emotive study init|serve|export|analyze`` as a user calls them: outputs, and one-line
errors that write nothing."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from cli_helpers import run_main
from emotive.io.motion_files import read_motion
from emotive.study.config import load_study


def test_init_makes_a_study_that_loads(study_template: Path):
    study = load_study(study_template)
    assert study.template == "gaits" and len(study.stimuli) == 3
    assert [q.id for q in study.questions] == ["happy", "sad", "angry", "neutral",
                                               "naturalness"]
    assert study.checks and study.completion_code.startswith("EMO-")
    for stimulus in study.stimuli:
        motion = read_motion(study.stimulus_path(stimulus.id))
        assert motion.num_frames == round(3.0 * motion.fps)
        assert stimulus.intended and stimulus.recipe["model"] == "gait"
    readings = json.loads((study_template / "stimuli" / "readings.json").read_text())
    assert set(readings["stimuli"]) == {s.id for s in study.stimuli}
    for reading in readings["stimuli"].values():
        assert abs(sum(reading["probabilities"].values()) - 1.0) < 1e-2


def test_init_shows_given_clips_with_their_intended_emotion(monkeypatch, capsys, tmp_path,
                                                            study_template):
    clips = tmp_path / "clips"
    clips.mkdir()
    for name in ("a.glb", "b.glb"):
        shutil.copy(study_template / "stimuli" / "s01.glb", clips / name)
    (clips / "labels.json").write_text(json.dumps({"a.glb": {"emotion": "sad"},
                                                   "b.glb": {"emotion": "happy=0.6,neutral=0.4"}}))
    code, _, err = run_main(monkeypatch, capsys, "study", "init", tmp_path / "mine",
                            "--stimuli", clips, "--seconds", "2")
    assert code == 0, err
    study = load_study(tmp_path / "mine")
    assert [(s.source, s.intended) for s in study.stimuli] == [
        ("given", "sad=1"), ("given", "happy=0.6,neutral=0.4")]
    code, _, err = run_main(monkeypatch, capsys, "study", "init", tmp_path / "long",
                              "--stimuli", clips, "--seconds", "30")
    assert code == 2 and "shorter than the study's 30 s" in err
    assert not (tmp_path / "long").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".long")]


@pytest.mark.parametrize(("args", "words"), [
    (["--template", "survey"], "--template 'survey' is not one of gaits, affect-grid, sources"),
    (["--count", "0"], "--count 0: give 1 to 100"),
    (["--seconds", "0.5"], "--seconds 0.5: give 1 to 120"),
])
def test_init_refuses_bad_options_in_one_line(monkeypatch, capsys, tmp_path, args, words):
    code, _, err = run_main(monkeypatch, capsys, "study", "init", tmp_path / "s", *args)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists()


def test_init_never_writes_into_a_folder_that_holds_files(monkeypatch, capsys, tmp_path):
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "notes.txt").write_text("mine")
    code, _, err = run_main(monkeypatch, capsys, "study", "init", tmp_path / "s")
    assert code == 2 and "not empty" in err
    assert [p.name for p in (tmp_path / "s").iterdir()] == ["notes.txt"]


def test_serve_needs_an_admin_token_beyond_loopback(monkeypatch, capsys, study_folder):
    code, _, err = run_main(monkeypatch, capsys, "study", "serve", study_folder, "--host",
                            "0.0.0.0", "--port", "0")
    assert code == 2 and "--admin-token" in err
    code, _, err = run_main(monkeypatch, capsys, "study", "serve", study_folder,
                            "--admin-token", "short")
    assert code == 2 and "at least 12 characters" in err
    code, _, err = run_main(monkeypatch, capsys, "study", "serve", study_folder, "--db",
                            "mysql://me@host/db")
    assert code == 2 and "only SQLite" in err


def test_export_and_analyze_of_a_study_without_answers(monkeypatch, capsys, study_folder,
                                                       tmp_path):
    code, out, err = run_main(monkeypatch, capsys, "study", "export", study_folder, "--out",
                              tmp_path / "r.csv")
    assert code == 0 and "0 responses" in out, err
    with (tmp_path / "r.csv").open() as fh:
        assert csv.reader(fh).__next__()[:6] == ["participant", "condition", "stimulus",
                                                 "question", "value", "time"]
    code, out, err = run_main(monkeypatch, capsys, "study", "analyze", study_folder, "--out",
                              tmp_path / "report")
    assert code == 0, err
    assert (tmp_path / "report" / "report.md").is_file()


def test_a_missing_study_names_the_fix(monkeypatch, capsys, tmp_path):
    code, _, err = run_main(monkeypatch, capsys, "study", "export", tmp_path, "--out",
                            tmp_path / "r.csv")
    assert code == 2 and "emotive study init" in err
    assert not (tmp_path / "r.csv").exists()


@pytest.fixture
def copied_stimuli(monkeypatch, study_template):
    """Templates' stimuli as copies of one GLB: their designs are tested here, the models'
    generation by their own tests (the FCRBM takes seconds a clip)."""
    import emotive.study.create as create

    def fake_stimuli(recipes, folder, seconds, given=None, advance=None):
        (folder / "stimuli").mkdir()
        for r in recipes:
            shutil.copy(study_template / "stimuli" / "s01.glb", folder / "stimuli" /
                        f"{r.id}.glb")
        return {r.id: f"stimuli/{r.id}.glb" for r in recipes}

    monkeypatch.setattr(create, "write_stimuli", fake_stimuli)
    monkeypatch.setattr(create, "judge_stimuli", lambda *a: None)
    return create


@pytest.mark.parametrize("recorded", [True, False])
def test_the_affect_grid_template_asks_one_grid_of_recorded_and_generated_movement(
        monkeypatch, tmp_path, copied_stimuli, recorded):
    monkeypatch.setattr(copied_stimuli, "_data_present", lambda: recorded)
    study = load_study(copied_stimuli.create_study(tmp_path / "grid", "affect-grid"))
    assert [(q.id, q.kind, q.size) for q in study.questions] == [("affect", "grid", 9)]
    assert study.render == "sticks"
    sources = [s.source for s in study.stimuli]
    assert sources == ["fcrbm"] * 9 + ["recorded" if recorded else "gait"] * 4
    points = {s.intended for s in study.stimuli[:9]}
    assert len(points) == 9 and "valence=-0.8,arousal=0.8" in points
    assert all(s.intended_emotion() is not None for s in study.stimuli)
    assert study.checks[0].expect == {"affect": [5, 5]}


def test_the_sources_template_puts_each_source_in_its_own_condition(monkeypatch, tmp_path,
                                                                    copied_stimuli):
    create = copied_stimuli
    monkeypatch.setattr(create, "_data_present", lambda: True)
    study = load_study(create.create_study(tmp_path / "src", "sources", count=1,
                                           seconds=2.0))
    assert study.between == "source" and study.repeats == 2
    assert [c.name for c in study.conditions] == ["recorded", "reconstructed", "resampled"]
    for condition in study.conditions:
        shown = [study.stimulus(s) for s in condition.stimuli]
        assert {s.source for s in shown} == {condition.name}
        assert sorted(s.intended for s in shown) == ["angry", "happy", "neutral", "sad"]
    assert [q.id for q in study.questions] == ["emotion", "confidence", "valence", "arousal"]
    monkeypatch.setattr(create, "_data_present", lambda: False)
    with pytest.raises(create.StudyError, match="emotive data fetch"):
        create.create_study(tmp_path / "src2", "sources")
