"""``emotive serve --scene`` on the command line: a bad scene fails in one line, exit code 2,
before anything binds; options a scene cannot run with are named; --help stays light."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")

import emotive.serve.server
from cli_helpers import run_main

GOOD = """
[area]
polygon = [[0, 0], [8, 0], [8, 4], [0, 4]]

[[groups]]
name = "waiting"
spawn = [[0.3, 0.3], [1.6, 0.3], [1.6, 1.6], [0.3, 1.6]]
count = 2
goal = { waypoints = [[1.0, 1.0]] }
emotion = "{emotion}"
"""


@pytest.fixture
def no_bind(monkeypatch):
    """Fail the test if the command binds a socket."""
    calls = []
    monkeypatch.setattr(emotive.serve.server, "bind",
                        lambda *args: calls.append(args) or pytest.fail("the command bound"))
    return calls


@pytest.mark.parametrize(("text", "words"), [
    (None, "cannot read the scene"),
    ("[area\n", "not valid TOML"),
    (GOOD.replace("[8, 0], [8, 4]", "[8, 4], [8, 0]"), "crosses itself"),
    (GOOD.replace("[[1.0, 1.0]]", "[[9.0, 1.0]]"), "goal waypoint 1"),
    (GOOD.replace("{emotion}", "gleeful"), "group 'waiting' emotion"),
])
def test_a_bad_scene_exits_2_in_one_line_before_binding(monkeypatch, capsys, tmp_path, no_bind,
                                                        text, words):
    path = tmp_path / "scene.toml"
    if text is not None:
        path.write_text(text.replace("{emotion}", "neutral"), encoding="utf-8")
    code, out, err = run_main(monkeypatch, capsys, "serve", "--scene", path, "--port", "0")
    assert code == 2 and out == "" and no_bind == []
    assert err.startswith("error: ") and words in err, err
    assert len(err.strip().splitlines()) == 1


def test_options_a_scene_cannot_run_with_are_named(monkeypatch, capsys, tmp_path, no_bind):
    path = tmp_path / "scene.toml"
    path.write_text(GOOD.replace("{emotion}", "neutral"), encoding="utf-8")
    code, _, err = run_main(monkeypatch, capsys, "serve", "--scene", path, "--workers", "2")
    assert code == 2 and "--workers 1" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_main(monkeypatch, capsys, "serve", "--scene", path, "--model", "fcrbm")
    assert code == 2 and "gait network on torch" in err
    assert no_bind == []


def test_help_names_the_scene_and_loads_no_crowd():
    code = ("import sys; import emotive; from emotive.cli import main\n"
            "try:\n    main(['serve', '--help'])\nexcept SystemExit:\n    pass\n"
            "assert 'jupedsim' not in sys.modules, 'jupedsim imported'\n"
            "assert 'emotive.crowd.crowd' not in sys.modules, 'the crowd imported'\n"
            "assert 'emotive.serve.crowd_engine' not in sys.modules\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert "--scene" in result.stdout
