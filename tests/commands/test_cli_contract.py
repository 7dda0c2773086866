"""The command line as a whole: verb-first commands, one-line errors with exit code 2, the
deprecated spellings, and a ``--help`` that imports no torch."""

from __future__ import annotations

import subprocess
import sys

import pytest

from cli_helpers import run_main


@pytest.mark.parametrize(("args", "words"), [
    (["generate", "--seconds", "0", "-o", "w.bvh"], ["--seconds", "above 0"]),
    (["generate", "--seconds", "nan", "-o", "w.bvh"], ["--seconds", "above 0"]),
    (["generate", "--seconds", "5000", "-o", "w.bvh"], ["--seconds 5000", "at most 3600"]),
    (["preview", "clip.bvh", "--width", "100000", "-o", "v.gif"], ["--width", "3840"]),
    (["classify", "clip.bvh", "--window", "0"], ["--window", "above 0"]),
    (["classify", "clip.bvh", "--hop", "0"], ["--hop", "above 0"]),
    (["generate", "--model", "gaitt", "-o", "w.bvh"], ["unknown model 'gaitt'", "gait"]),
    (["generate", "--gibbs", "3", "-o", "w.bvh"], ["--gibbs", "model 'gait'"]),
    (["generate", "--model", "fcrbm", "--raw", "-o", "w.bvh"], ["--raw", "model 'fcrbm'",
                                                                 "--gibbs"]),
    (["generate", "--emotion", "valence=3,arousal=1", "-o", "w.bvh"],
     ["valence=3 is outside -1..1", "old FCRBM 1..3 scale, subtract 2: valence=1"]),
    (["generate", "--no-such-flag"], ["--no-such-flag"]),
    (["reconstruct", "clip.bvh", "--role-map", "bandai", "-o", "r.bvh"], ["--role-map"]),
    (["generate", "--seed", "-1", "-o", "w.bvh"], ["--seed", "greater than or equal to 0"]),
    (["generate", "--model", "lgb", "--seed", "-1", "-o", "w.bvh"], ["--seed", "0"]),
    (["generate", "--model", "fcrbm", "--seed", "-1", "-o", "w.bvh"], ["--seed", "0"]),
    (["generate", "--seed", str(2**32), "-o", "w.bvh"], ["--seed", "4294967295"]),
    (["fcrbm", "generate", "--seed", "-1", "-o", "w.bvh"], ["--seed", "0"]),
    (["serve", "--seed", "-1"], ["--seed", "greater than or equal to 0"]),
    (["train", "classifier", "--seed", "-1"], ["--seed", "0"]),
    (["generate", "--emotion", "happy=0.7,sad", "-o", "w.bvh"],
     ["'sad'", "has no weight", "sad=0.3"]),
    (["generate", "-o", "/proc/w.bvh"], ["cannot write /proc", "virtual file system"]),
    (["generate", "--raw", "true", "-o", "w.bvh"], ["true"]),
])
def test_invalid_values_are_one_error_line_with_exit_code_2(monkeypatch, capsys, tmp_path,
                                                             args, words):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_main(monkeypatch, capsys, *args)
    assert code == 2 and out == ""
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert all(w in err for w in words), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("old", "new"), [
    (["resample", "-e", "sad", "--seconds", "0", "-o", "w.bvh"],
     "`emotive resample` is now `emotive generate --model lgb`"),
    (["fcrbm", "generate", "--valence", "3", "--arousal", "1", "-o", "w.bvh"],
     "`emotive fcrbm generate` is now `emotive generate --model fcrbm`"),
])
def test_deprecated_spellings_print_one_line_and_do_the_same(monkeypatch, capsys, tmp_path,
                                                              old, new):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(monkeypatch, capsys, *old)
    lines = err.strip().splitlines()
    if old[0] == "resample":  # a range error comes before the command runs
        assert code == 2 and len(lines) == 1 and "--seconds" in lines[0]
        return
    assert code == 2 and len(lines) == 2
    assert lines[0] == f"deprecated: {new}; the old spelling goes in 0.3"
    assert "subtract 2: valence=1" in lines[1]


def test_the_deprecated_fcrbm_generate_makes_the_new_commands_file(monkeypatch, capsys,
                                                                   tmp_path):
    code, _, err = run_main(monkeypatch, capsys, "fcrbm", "generate", "--valence", "0.5",
                           "--arousal", "-0.5", "--seconds", "0.5", "-o", tmp_path / "old.bvh")
    assert code == 0, err
    assert err.count("deprecated:") == 1
    code, _, err = run_main(monkeypatch, capsys, "generate", "--model", "fcrbm", "--emotion",
                           "valence=0.5,arousal=-0.5", "--seconds", "0.5", "-o",
                           tmp_path / "new.bvh")
    assert code == 0 and "deprecated:" not in err
    assert (tmp_path / "old.bvh").read_bytes() == (tmp_path / "new.bvh").read_bytes()


def test_help_lists_the_verbs_and_hides_the_old_spellings(monkeypatch, capsys):
    code, out, _ = run_main(monkeypatch, capsys, "--help")
    assert code == 0
    for verb in ("generate", "train", "transfer", "reconstruct", "evaluate", "models", "info",
                 "features", "preview", "classify", "data", "serve", "export"):
        assert verb in out
    assert "resample" not in out and "fcrbm " not in out
    code, out, _ = run_main(monkeypatch, capsys, "train", "--help")
    assert code == 0 and all(m in out for m in ("gait", "quaternet", "fcrbm", "classifier"))


def test_help_imports_no_torch():
    code = ("import sys; from emotive.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print('torch' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr


def test_boolean_options_come_in_pairs_and_show_no_value(monkeypatch, capsys):
    code, out, _ = run_main(monkeypatch, capsys, "generate", "--help")
    assert code == 0
    line = next(x for x in out.splitlines() if "--raw" in x)
    assert "--no-raw" in line and "<bool>" not in line, line
