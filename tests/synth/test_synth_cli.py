"""``emotive synth`` refuses bad input in one line (exit 2) before writing anything; its help
loads neither torch nor Ray."""

from __future__ import annotations

import json
import socket
import subprocess
import sys

import pytest

from cli_helpers import run_main
from emotive.synth import store
from emotive.synth.build import recipe_values
from emotive.synth.recipe import Recipe

SMALL = ["--paths", "2", "--emotions", "3", "--transitions", "1", "--seconds", "4"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _fails(monkeypatch, capsys, out, *args) -> str:
    code, _, err = run_main(monkeypatch, capsys, "synth", "--out", out, *args)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


@pytest.mark.parametrize(("args", "words"), [
    (["--model", "gaitt"], ["unknown model 'gaitt'", "did you mean 'gait'"]),
    (["--model", "quaternet"], ["--model quaternet", "makes no new motion", "gait"]),
    (["--paths", "0"], ["--paths", "greater than or equal to 1"]),
    (["--emotions", "-2"], ["--emotions", "greater than or equal to 1"]),
    (["--transitions", "-1"], ["--transitions", "greater than or equal to 0"]),
    (["--emotions", "3", "--transitions", "2"], ["--transitions 2", "at most 1 disjoint",
                                                  "--transitions 1 or fewer"]),
    (["--seconds", "0"], ["--seconds"]),
    (["--formats", "npz,fbx"], ["--formats npz,fbx", "unknown fbx"]),
    (["--address", "nonsense"], ["--address nonsense", "HOST:PORT"]),
    (["--recipe", "tiny"], ["--recipe tiny: no such recipe", "paper, small"]),
])
def test_bad_input_is_one_line_and_writes_nothing(monkeypatch, capsys, tmp_path, args, words):
    line = _fails(monkeypatch, capsys, tmp_path / "set", *SMALL, *args)
    assert all(w in line for w in words), line
    assert not (tmp_path / "set").exists()


def test_unreachable_address_is_one_line(monkeypatch, capsys, tmp_path):
    port = _free_port()
    line = _fails(monkeypatch, capsys, tmp_path / "set", *SMALL, "--address",
                  f"127.0.0.1:{port}")
    assert f"--address 127.0.0.1:{port}: no Ray cluster answers there" in line
    assert f"ray start --head --port {port}" in line
    assert not (tmp_path / "set").exists()


def test_an_out_folder_of_another_recipe_is_left_alone(monkeypatch, capsys, tmp_path):
    other = recipe_values(Recipe(paths=2, emotions=3, transitions=1, seconds=4.0, seed=1))
    folder = store.open_folder(tmp_path, other)
    store.write_recipe(folder, {"checked": False})
    folder.close()
    before = sorted((p.name, p.read_bytes()) for p in tmp_path.iterdir())
    line = _fails(monkeypatch, capsys, tmp_path, *SMALL)
    assert "holds another recipe (seed 1 there, 0 here)" in line
    assert sorted((p.name, p.read_bytes()) for p in tmp_path.iterdir()) == before
    assert json.loads((tmp_path / "recipe.json").read_text())["seed"] == 1


def test_a_folder_of_other_files_is_refused(monkeypatch, capsys, tmp_path):
    (tmp_path / "thesis.pdf").write_bytes(b"%PDF")
    line = _fails(monkeypatch, capsys, tmp_path, *SMALL)
    assert "holds thesis.pdf and no recipe.json" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thesis.pdf"]


def test_help_and_the_package_load_neither_torch_nor_ray():
    code = ("import sys, emotive.synth\n"
            "from emotive.cli import app\n"
            "from typer.testing import CliRunner\n"
            "r = CliRunner().invoke(app, ['synth', '--help'])\n"
            "assert r.exit_code == 0 and '--transitions' in r.output, r.output\n"
            "print('torch' in sys.modules, 'ray' in sys.modules)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "False"]
