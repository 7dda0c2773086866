"""A new user's mistakes, each answered by one line that names it, and nothing written.

Every case runs the command line in-process in a folder of small files (a walk, files that
exist already, broken JSON, a role map naming a joint the rig lacks) and asserts: exit code 2,
nothing on stdout, one ``error:`` line on stderr holding the words that name the offending
input and the fix, no traceback, and the folder byte for byte as it was (no output, no
temporary file). Beside them: ``--force`` replaces, every command that writes files takes
it, a bad path is refused before torch is imported, and the constants the checks repeat to
stay light agree with the modules they stand for.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cli_helpers import run_main

#: A role map naming a joint the synthetic rig (``tests/rigs.py``) lacks.
MISSING_JOINT = {"root": "Hips", "head": "Kopf"}

#: (id, command line, words the one error line must hold). ``walk.bvh`` is a 3 s walk;
#: ``existing.*``, ``oldreport/``, ``oldrun/``, ``oldclf/``, ``oldsite/`` hold earlier outputs.
CASES = [
    # Outputs are what their name says: the format follows the suffix.
    ("features-png", ["features", "walk.bvh", "--out", "m52.png"],
     ["--out m52.png", "'.png' is not a format it writes", ".csv"]),
    ("features-no-suffix", ["features", "walk.bvh", "--out", "table"],
     ["--out table", "no suffix", ".csv"]),
    ("features-plot-jpg", ["features", "walk.bvh", "--out", "f.csv", "--plot", "p.jpg"],
     ["--plot p.jpg", ".png or .pdf or .svg"]),
    ("generate-png", ["generate", "-o", "w.png"], ["--out w.png", ".bvh or .glb"]),
    ("generate-npz-csv", ["generate", "-o", "w.bvh", "--npz", "w.csv"], ["--npz w.csv", ".npz"]),
    ("generate-preview-avi", ["generate", "-o", "w.bvh", "--preview", "w.avi"],
     ["--preview w.avi", ".mp4 or .gif"]),
    ("preview-png", ["preview", "walk.bvh", "--out", "v.png"], ["--out v.png", ".mp4 or .gif"]),
    ("reconstruct-fbx", ["reconstruct", "walk.bvh", "--out", "r.fbx"],
     ["--out r.fbx", ".bvh or .glb or .gltf"]),
    ("retarget-csv", ["retarget", "walk.bvh", "--to", "walk.bvh", "--out", "r.csv"],
     ["--out r.csv", ".bvh"]),
    ("transfer-txt", ["transfer", "walk.bvh", "--style", "proud", "--out", "t.txt"],
     ["--out t.txt", ".bvh"]),
    ("onnx-bin", ["export", "onnx", "--out", "agent.bin"], ["--out agent.bin", ".onnx"]),
    ("web-html", ["export", "web", "--out", "agents.html"],
     ["--out agents.html", "writes a folder", "agents"]),
    ("web-zip", ["export", "web", "--out", "site.zip"], ["--out site.zip", "writes a folder"]),
    ("evaluate-report-md", ["evaluate", "--model", "gait", "--out", "report.md"],
     ["--out report.md", "writes a folder"]),
    ("train-pt", ["train", "gait", "--out", "model.pt"], ["--out model.pt", "writes a folder"]),
    ("train-classifier-pt", ["train", "classifier", "--out", "clf.pt"],
     ["--out clf.pt", "writes a folder"]),
    ("generate-folder", ["generate", "-o", "afolder"], ["--out afolder", "that is a folder"]),
    ("features-folder", ["features", "walk.bvh", "--out", "afolder"],
     ["--out afolder", "that is a folder"]),
    ("generate-same-twice", ["generate", "-o", "w.npz", "--npz", "w.npz"],
     ["--npz w.npz", "the same file as --out"]),
    ("generate-no-folder", ["generate", "-o", "nowhere/w.bvh"],
     ["nowhere/w.bvh", "does not exist"]),
    # An output that exists is replaced only with --force, in every command.
    ("features-existing", ["features", "walk.bvh", "--out", "existing.csv"],
     ["--out existing.csv exists already", "--force"]),
    ("features-plot-existing", ["features", "walk.bvh", "--out", "f.csv", "--plot",
                                "existing.png"], ["--plot existing.png exists already"]),
    ("generate-existing", ["generate", "-o", "existing.bvh"],
     ["--out existing.bvh exists already", "--force"]),
    ("generate-npz-existing", ["generate", "-o", "w.bvh", "--npz", "existing.npz"],
     ["--npz existing.npz exists already"]),
    ("generate-preview-existing", ["generate", "-o", "w.bvh", "--preview", "existing.gif"],
     ["--preview existing.gif exists already"]),
    ("preview-existing", ["preview", "walk.bvh", "--out", "existing.gif"],
     ["--out existing.gif exists already"]),
    ("reconstruct-existing", ["reconstruct", "walk.bvh", "--out", "existing.bvh"],
     ["--out existing.bvh exists already"]),
    ("reconstruct-over-its-input", ["reconstruct", "walk.bvh", "--out", "walk.bvh"],
     ["--out walk.bvh exists already", "--force"]),
    ("retarget-existing", ["retarget", "walk.bvh", "--to", "walk.bvh", "--out", "existing.bvh"],
     ["--out existing.bvh exists already"]),
    ("transfer-existing", ["transfer", "walk.bvh", "--style", "proud", "--out", "existing.bvh"],
     ["--out existing.bvh exists already"]),
    ("onnx-existing", ["export", "onnx", "--out", "existing.onnx"],
     ["--out existing.onnx exists already"]),
    ("web-existing", ["export", "web", "--out", "oldsite"], ["--out", "oldsite", "--force"]),
    ("evaluate-existing", ["evaluate", "--model", "gait", "--out", "oldreport"],
     ["--out oldreport/report.md exists already", "--force"]),
    ("train-existing", ["train", "gait", "--out", "oldrun"],
     ["--out oldrun holds a training run already", "--resume", "--force"]),
    ("train-classifier-existing", ["train", "classifier", "--out", "oldclf"],
     ["--out oldclf holds a training run already", "--force"]),
    # Inputs: a file that is not there, a folder, a format the command does not read.
    ("info-missing", ["info", "nosuch.bvh"], ["nosuch.bvh", "does not exist"]),
    ("info-txt", ["info", "notes.txt"], ["notes.txt", "'.txt' is not a format it reads",
                                         ".bvh or .glb"]),
    ("info-folder", ["info", "afolder"], ["afolder", "is a folder"]),
    ("info-glb-missing", ["info", "nosuch.glb"], ["nosuch.glb", "does not exist"]),
    ("features-missing", ["features", "nosuch.bvh", "--out", "f.csv"],
     ["nosuch.bvh", "does not exist"]),
    ("classify-missing", ["classify", "nosuch.bvh"], ["nosuch.bvh", "does not exist"]),
    ("preview-missing", ["preview", "nosuch.bvh", "--out", "v.gif"],
     ["nosuch.bvh", "does not exist"]),
    ("reconstruct-missing", ["reconstruct", "nosuch.bvh", "--out", "r.bvh"],
     ["nosuch.bvh", "does not exist"]),
    ("retarget-missing", ["retarget", "nosuch.bvh", "--to", "walk.bvh", "--out", "r.bvh"],
     ["nosuch.bvh", "does not exist"]),
    ("retarget-to-missing", ["retarget", "walk.bvh", "--to", "nosuch.bvh", "--out", "r.bvh"],
     ["--to nosuch.bvh", "does not exist"]),
    ("retarget-to-txt", ["retarget", "walk.bvh", "--to", "notes.txt", "--out", "r.bvh"],
     ["--to notes.txt", "'.txt'"]),
    ("transfer-missing", ["transfer", "nosuch.bvh", "--style", "proud", "--out", "t.bvh"],
     ["nosuch.bvh", "does not exist"]),
    ("generate-primer-missing", ["generate", "--primer", "nosuch.bvh", "-o", "w.bvh"],
     ["--primer nosuch.bvh", "does not exist"]),
    ("generate-rig-missing", ["generate", "--rig", "nosuch.glb", "-o", "w.bvh"],
     ["--rig nosuch.glb", "does not exist"]),
    ("generate-rig-txt", ["generate", "--rig", "notes.txt", "-o", "w.bvh"],
     ["--rig notes.txt", "'.txt'"]),
    ("generate-checkpoint-missing", ["generate", "--checkpoint", "nosuch.pt", "-o", "w.bvh"],
     ["--checkpoint nosuch.pt", "does not exist"]),
    ("generate-checkpoint-folder", ["generate", "--checkpoint", "afolder", "-o", "w.bvh"],
     ["--checkpoint afolder", "is a folder"]),
    ("generate-path-missing", ["generate", "--path", "nosuch.json", "-o", "w.bvh"],
     ["--path nosuch.json", "does not exist"]),
    ("generate-path-shape", ["generate", "--path", "spiral", "-o", "w.bvh"],
     ["unknown path 'spiral'", "figure8"]),
    ("preview-path-missing", ["preview", "walk.bvh", "--out", "v.gif", "--path",
                              "nosuch.json"], ["--path nosuch.json", "does not exist"]),
    ("classify-model-missing", ["classify", "walk.bvh", "--model", "nosuch.pt"],
     ["--model nosuch.pt", "does not exist"]),
    ("evaluate-folder-missing", ["evaluate", "--model", "my_generated_walks/"],
     ["my_generated_walks/", "the folder does not exist"]),
    ("evaluate-checkpoint-missing", ["evaluate", "--model", "nosuch.pt"],
     ["--model nosuch.pt", "does not exist"]),
    ("evaluate-typo", ["evaluate", "--model", "gaitt"], ["'gaitt'", "did you mean 'gait'"]),
    ("evaluate-file", ["evaluate", "--model", "notes.txt"], ["--model notes.txt", "is a file"]),
    ("evaluate-classifier-missing", ["evaluate", "--model", "gait", "--classifier",
                                     "nosuch.pt"], ["--classifier nosuch.pt", "does not exist"]),
    ("evaluate-weights-missing", ["evaluate", "--model", "gait", "--weights", "nosuch.pt"],
     ["--weights nosuch.pt", "does not exist"]),
    ("evaluate-suite-typo", ["evaluate", "--model", "gait", "--suite", "tabel1"],
     ["--suite 'tabel1'", "did you mean 'table1'"]),
    ("evaluate-option", ["evaluate", "--model", "gait", "--option", "gibbs"],
     ["--option 'gibbs'", "NAME=VALUE"]),
    ("onnx-weights-missing", ["export", "onnx", "--out", "a.onnx", "--weights", "nosuch.pt"],
     ["--weights nosuch.pt", "does not exist"]),
    ("onnx-step", ["export", "onnx", "--step", "brain", "--out", "a.onnx"],
     ["--step 'brain'", "agent"]),
    ("web-weights-missing", ["export", "web", "--out", "site", "--weights", "nosuch.pt"],
     ["--weights nosuch.pt", "does not exist"]),
    ("fetch-source-missing", ["data", "fetch", "bandai-namco-1", "--source", "missing.tar.gz"],
     ["--source missing.tar.gz does not exist"]),
    ("fetch-unknown", ["data", "fetch", "bandai-namco1"], ["did you mean 'bandai-namco-1'"]),
    ("train-config-missing", ["train", "gait", "--config", "nosuch.toml", "--out", "run"],
     ["--config nosuch.toml"]),
    ("transfer-schedule-missing", ["transfer", "walk.bvh", "--style-schedule", "nosuch.json",
                                   "--out", "t.bvh"], ["nosuch.json", "does not exist"]),
    # Emotions are refused, not bent: weights 0..1, valence and arousal -1..1.
    ("weight-2", ["generate", "-e", "happy=2", "-o", "w.bvh"],
     ["--emotion", "'happy=2'", "is 2, outside 0..1"]),
    ("weight-negative", ["generate", "-e", "happy=-0.5,sad=1", "-o", "w.bvh"],
     ["-0.5, outside 0..1"]),
    ("weight-above-one-in-blend", ["generate", "-e", "happy=0.7,sad=1.3", "-o", "w.bvh"],
     ["'sad'", "1.3, outside 0..1"]),
    ("weight-huge", ["generate", "-e", "happy=1e308,sad=1e308", "-o", "w.bvh"],
     ["outside 0..1"]),
    ("valence-1.4", ["generate", "-e", "valence=1.4,arousal=0", "-o", "w.bvh"],
     ["valence=1.4 is outside -1..1"]),
    ("arousal-below", ["generate", "-e", "valence=0,arousal=-1.2", "-o", "w.bvh"],
     ["arousal=-1.2 is outside -1..1"]),
    ("valence-old-scale", ["generate", "-e", "valence=3,arousal=1", "-o", "w.bvh"],
     ["valence=3 is outside -1..1", "subtract 2: valence=1"]),
    ("valence-nan", ["generate", "-e", "valence=nan,arousal=0", "-o", "w.bvh"],
     ["valence=nan", "not finite"]),
    ("valence-alone", ["generate", "-e", "valence=0.5", "-o", "w.bvh"],
     ["both valence and arousal"]),
    ("emotion-typo", ["generate", "-e", "hapy", "-o", "w.bvh"], ["'hapy'", "did you mean"]),
    ("blend-without-weight", ["generate", "-e", "happy=0.7,sad", "-o", "w.bvh"],
     ["'sad'", "has no weight"]),
    ("emotion-empty", ["generate", "-e", "", "-o", "w.bvh"], ["empty emotion"]),
    ("weight-text", ["generate", "-e", "happy=abc", "-o", "w.bvh"], ["'abc'", "not a number"]),
    ("schedule-not-json", ["generate", "--emotion-schedule", "not json", "-o", "w.bvh"],
     ["--emotion-schedule", "'not json' is not valid JSON", "line 1, column 1"]),
    ("schedule-missing", ["generate", "--emotion-schedule", "nosuch.json", "-o", "w.bvh"],
     ["nosuch.json does not exist"]),
    ("schedule-broken", ["generate", "--emotion-schedule", "broken.json", "-o", "w.bvh"],
     ["broken.json is not valid JSON", "line 2, column"]),
    ("schedule-weight", ["generate", "--emotion-schedule", "weights.json", "-o", "w.bvh"],
     ["weights.json", "keyframe 0", "outside 0..1"]),
    ("schedule-old-scale", ["generate", "--emotion-schedule",
                            '[{"t": 0, "valence": 2.5, "arousal": 0}]', "-o", "w.bvh"],
     ["valence=2.5 is outside -1..1", "subtract 2"]),
    ("schedule-folder", ["generate", "--emotion-schedule", "afolder", "-o", "w.bvh"],
     ["afolder is a folder"]),
    ("emotion-and-schedule", ["generate", "-e", "sad", "--emotion-schedule", "weights.json",
                              "-o", "w.bvh"], ["--emotion or --emotion-schedule, not both"]),
    ("transfer-weight", ["transfer", "walk.bvh", "--style", "proud=2", "--out", "t.bvh"],
     ["--style", "outside 0..1"]),
    ("transfer-typo", ["transfer", "walk.bvh", "--style", "prout", "--out", "t.bvh"],
     ["--style", "'prout'", "did you mean 'proud'"]),
    ("transfer-no-style", ["transfer", "walk.bvh", "--out", "t.bvh"],
     ["exactly one of --style and --style-schedule"]),
    # Numbers: windows longer than the clip, out-of-range options.
    ("window-1e9", ["classify", "walk.bvh", "--window", "1e9"],
     ["--window 1e+09 s is longer than walk.bvh", "3.00 s"]),
    ("window-10", ["classify", "walk.bvh", "--window", "10"],
     ["--window 10 s is longer than walk.bvh", "0.8 s"]),
    ("window-0", ["classify", "walk.bvh", "--window", "0"], ["--window", "above 0"]),
    ("hop-negative", ["classify", "walk.bvh", "--hop", "-1"], ["--hop", "above 0"]),
    ("seconds-0", ["generate", "--seconds", "0", "-o", "w.bvh"], ["--seconds", "above 0"]),
    ("preview-width", ["preview", "walk.bvh", "--out", "v.gif", "--width", "10"], ["--width"]),
    ("seed-negative", ["generate", "--seed", "-1", "-o", "w.bvh"], ["--seed"]),
    ("unit", ["info", "walk.bvh", "--unit", "furlong"], ["'furlong'", "not a length unit"]),
    # Role maps: named joints, JSON that parses, a family or a file.
    ("roles-nosuch", ["info", "walk.bvh", "--roles", "nosuch"],
     ["--roles nosuch", "does not exist", "bandai"]),
    ("roles-broken", ["info", "walk.bvh", "--roles", "broken.json"],
     ["--roles broken.json is not valid JSON", "line 2, column"]),
    ("roles-missing-joint", ["info", "walk.bvh", "--roles", "missing_joint.json"],
     ["missing_joint.json", "'Kopf' (role head)"]),
    ("roles-folder", ["info", "walk.bvh", "--roles", "afolder"], ["--roles afolder",
                                                                  "is a folder"]),
    ("roles-unknown-role", ["info", "walk.bvh", "--roles", "unknown_role.json"],
     ["unknown_role.json", "unknown roles ['pelvis']"]),
    ("features-roles-joint", ["features", "walk.bvh", "--out", "f.csv", "--roles",
                              "missing_joint.json"], ["'Kopf' (role head)"]),
    ("classify-roles-joint", ["classify", "walk.bvh", "--roles", "missing_joint.json"],
     ["'Kopf' (role head)"]),
    ("reconstruct-roles-joint", ["reconstruct", "walk.bvh", "--out", "r.bvh", "--roles",
                                 "missing_joint.json"], ["'Kopf' (role head)"]),
    ("retarget-to-roles-joint", ["retarget", "walk.bvh", "--to", "walk.bvh", "--out", "r.bvh",
                                 "--to-roles", "missing_joint.json"],
     ["--to-roles missing_joint.json", "'Kopf' (role head)"]),
    ("retarget-roles-nosuch", ["retarget", "walk.bvh", "--to", "walk.bvh", "--out", "r.bvh",
                               "--roles", "nosuch"], ["--roles nosuch", "does not exist"]),
    ("transfer-roles-nosuch", ["transfer", "walk.bvh", "--style", "proud", "--out", "t.bvh",
                               "--roles", "nosuch.json"], ["--roles nosuch.json",
                                                          "does not exist"]),
    ("generate-rig-roles", ["generate", "--rig", "walk.bvh", "--rig-roles", "nosuch", "-o",
                            "w.bvh"], ["--rig-roles nosuch", "does not exist"]),
    ("generate-primer-roles", ["generate", "--primer", "walk.bvh", "--primer-roles",
                               "broken.json", "-o", "w.bvh"],
     ["--primer-roles broken.json is not valid JSON"]),
    # Models and flags.
    ("model-typo", ["generate", "--model", "gaitt", "-o", "w.bvh"], ["unknown model 'gaitt'"]),
    ("model-flag", ["generate", "--gibbs", "3", "-o", "w.bvh"], ["--gibbs", "model 'gait'"]),
    ("model-not-generator", ["generate", "--model", "classifier", "-o", "w.bvh"],
     ["--model classifier", "makes no new motion"]),
    ("unknown-flag", ["info", "walk.bvh", "--no-such-flag"], ["--no-such-flag"]),
]


@pytest.fixture
def workdir(tmp_path, monkeypatch, clip) -> Path:
    """The current folder: a walk, earlier outputs, broken and wrong JSON files."""
    (tmp_path / "walk.bvh").write_bytes(clip.read_bytes())
    (tmp_path / "notes.txt").write_text("not motion\n")
    (tmp_path / "afolder").mkdir()
    for name in ("existing.csv", "existing.bvh", "existing.npz", "existing.gif",
                 "existing.png", "existing.onnx"):
        (tmp_path / name).write_text(f"earlier {name}\n")
    for folder, name in (("oldreport", "report.md"), ("oldrun", "last.pt"),
                         ("oldclf", "emotion-classifier.pt"), ("oldsite", "index.html")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / name).write_text("earlier\n")
    (tmp_path / "broken.json").write_text('{"head":\n  }\n')
    (tmp_path / "missing_joint.json").write_text(json.dumps(MISSING_JOINT))
    (tmp_path / "unknown_role.json").write_text(json.dumps({"pelvis": "Hips"}))
    (tmp_path / "weights.json").write_text(json.dumps([{"t": 0, "emotion": "happy=2"}]))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every file and folder under ``folder`` (hidden ones included), files with their bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None
            for p in sorted(folder.rglob("*"))}


def test_the_campaign_has_at_least_90_distinct_mistakes():
    assert len(CASES) >= 90
    assert len({c[0] for c in CASES}) == len(CASES)
    assert len({tuple(c[1]) for c in CASES}) == len(CASES)


@pytest.mark.parametrize(("args", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_a_mistake_is_one_line_naming_it_and_writes_nothing(workdir, monkeypatch, capsys, args,
                                                            words):
    before = snapshot(workdir)
    code, out, err = run_main(monkeypatch, capsys, *args)
    assert code == 2, (code, out, err)
    assert out == "", out
    assert "Traceback" not in err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert all(w in err for w in words), err
    assert snapshot(workdir) == before


def test_force_replaces_an_existing_output(workdir, monkeypatch, capsys):
    code, _, err = run_main(monkeypatch, capsys, "features", "walk.bvh", "--out", "existing.csv",
                            "--force")
    assert code in (0, None), err
    assert (workdir / "existing.csv").read_text().startswith("time,")


def test_every_command_that_writes_files_takes_force():
    import typer

    from emotive.cli import app

    writers = {"generate", "features", "preview", "reconstruct", "retarget", "transfer",
               "evaluate", "resample", "export onnx", "export web", "train gait",
               "train quaternet", "train fcrbm", "train classifier", "fcrbm generate",
               "fcrbm train"}
    click_app = typer.main.get_command(app)
    found = set()
    for name in writers:
        command = click_app
        for part in name.split():
            command = command.commands[part]
        options = {o for p in command.params for o in p.opts}
        assert "--force" in options, name
        found.add(name)
    assert found == writers


#: Bad paths given to each command that reads or writes files; each must be refused before
#: torch is imported (a check that does not depend on the machine's speed).
FAST_FAILURES = [
    ["generate", "--checkpoint", "nosuch.pt", "-o", "w.bvh"],
    ["generate", "--primer", "nosuch.bvh", "-o", "w.bvh"],
    ["generate", "-e", "happy=2", "-o", "w.bvh"],
    ["generate", "--emotion-schedule", "not json", "-o", "w.bvh"],
    ["info", "nosuch.bvh"],
    ["info", "walk.bvh", "--roles", "nosuch"],
    ["features", "nosuch.bvh", "--out", "f.csv"],
    ["features", "walk.bvh", "--out", "m52.png"],
    ["classify", "nosuch.bvh"],
    ["preview", "nosuch.bvh", "--out", "v.gif"],
    ["reconstruct", "nosuch.bvh", "--out", "r.bvh"],
    ["retarget", "walk.bvh", "--to", "nosuch.bvh", "--out", "r.bvh"],
    ["transfer", "nosuch.bvh", "--style", "proud", "--out", "t.bvh"],
    ["evaluate", "--model", "my_generated_walks/"],
    ["export", "onnx", "--out", "a.onnx", "--weights", "nosuch.pt"],
    ["export", "web", "--out", "agents.html"],
    ["train", "gait", "--config", "nosuch.toml", "--out", "run"],
    ["data", "fetch", "bandai-namco-1", "--source", "missing.tar.gz"],
]

_IMPORTS = """
import json, sys
from emotive.cli import main
heavy = []
for args in json.loads(sys.argv[1]):
    try:
        main(args)
    except SystemExit as exc:
        assert exc.code == 2, (args, exc.code)
    heavy.append([m for m in ("torch", "scipy", "matplotlib") if m in sys.modules])
print(json.dumps(heavy))
"""


def test_a_bad_path_is_refused_before_heavy_imports(workdir):
    proc = subprocess.run([sys.executable, "-c", _IMPORTS, json.dumps(FAST_FAILURES)],
                          capture_output=True, text=True, timeout=300, cwd=workdir)
    assert proc.returncode == 0, proc.stderr
    heavy = json.loads(proc.stdout.strip().splitlines()[-1])
    assert dict(zip(map(" ".join, FAST_FAILURES), heavy, strict=True)) == {
        " ".join(a): [] for a in FAST_FAILURES}


def test_the_constants_the_checks_repeat_agree_with_their_modules():
    from emotive.commands import generate, options
    from emotive.core.rig_names import FAMILIES
    from emotive.io import bvh_limits, motion_files
    from emotive.paths import SHAPES
    from emotive.render.outputs import OUT_SUFFIXES

    assert options.MOTION_IN == motion_files.READ_SUFFIXES
    assert options.MOTION_OUT == motion_files.MOTION_SUFFIXES
    assert generate.GENERATE_OUT == OUT_SUFFIXES
    assert generate.PATH_SHAPES == tuple(SHAPES)
    assert options.ROLE_FAMILIES == tuple(FAMILIES)
    assert options.UNITS == tuple(bvh_limits.UNITS)
