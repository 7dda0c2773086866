"""``emotive export onnx``: the file, what it prints, and one-line failures that write nothing."""

from __future__ import annotations

import onnx
from typer.testing import CliRunner

from cli_helpers import assert_failed_cleanly
from emotive.commands.export import app
from emotive.errors import ConfigError, OutputError
from emotive.models.gait.model import default_checkpoint_path


def _invoke(*args: object):
    return CliRunner().invoke(app, ["onnx", *map(str, args)], env={"COLUMNS": "200"})


def test_export_onnx_writes_a_checked_file_and_prints_its_inputs_and_outputs(tmp_path):
    out = tmp_path / "gait.onnx"
    result = _invoke("--out", out, "--weights", default_checkpoint_path())
    assert result.exit_code == 0, result.output
    onnx.checker.check_model(onnx.load(str(out)))
    lines = result.output.splitlines()
    assert lines[0].startswith(f"wrote {out} (") and "opset 15" in lines[0]
    assert "input  rotations       (B, 22, 4)" in result.output
    assert "input  state           (1, B, 192)" in result.output
    assert "output next_root       (B, 3)" in result.output
    assert sorted(tmp_path.iterdir()) == [out]


def test_bad_outputs_and_weights_fail_in_one_line_and_write_nothing(tmp_path):
    before = sorted(tmp_path.iterdir())
    assert_failed_cleanly(_invoke("--out", tmp_path / "gait.pt"), OutputError,
                          ["--out", "gait.pt", ".onnx"], tmp_path, before)
    assert_failed_cleanly(_invoke("--out", tmp_path / "no" / "gait.onnx"), OutputError,
                          ["folder", "does not exist"], tmp_path, before)
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a checkpoint")
    before = sorted(tmp_path.iterdir())
    assert_failed_cleanly(_invoke("--out", tmp_path / "gait.onnx", "--weights", bad),
                          ConfigError, ["bad.pt"], tmp_path, before)


def test_export_the_whole_agent_step_prints_its_inputs_and_outputs(tmp_path):
    out = tmp_path / "agent.onnx"
    result = _invoke("--step", "agent", "--out", out)
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert lines[0].startswith(f"wrote {out} (agent step,")
    assert "input  path            (B, 15, 2)" in result.output
    assert "output world           (B, 27, 3)" in result.output
    assert sorted(tmp_path.iterdir()) == [out]


def test_an_unknown_step_fails_in_one_line_and_writes_nothing(tmp_path):
    before = sorted(tmp_path.iterdir())
    assert_failed_cleanly(_invoke("--step", "body", "--out", tmp_path / "a.onnx"), ConfigError,
                          ["--step 'body'", "agent", "network"], tmp_path, before)
