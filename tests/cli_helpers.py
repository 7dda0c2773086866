"""Helpers of the command tests: run one sub-command, check a one-line failure that wrote
nothing, write a BVH file with a NaN frame."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from emotive.cli import main


def run_main(monkeypatch, capsys, *args) -> tuple[int, str, str]:
    """Run the console entry point in-process; return exit code, stdout and stderr."""
    monkeypatch.setattr(sys, "argv", ["emotive", *map(str, args)])
    monkeypatch.setenv("COLUMNS", "200")
    with pytest.raises(SystemExit) as exc:
        main()
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


def invoke_command(name: str, command: Callable, *args: object):
    """Run ``command`` as the sub-command ``name`` of a small app, as :mod:`emotive.cli`
    registers it, with ``args`` as its command line."""
    app = typer.Typer()

    @app.callback()
    def _root() -> None:
        """A group, so that the sub-command is called by name."""

    app.command(name)(command)
    return CliRunner().invoke(app, [name, *map(str, args)], env={"COLUMNS": "200"})


def assert_failed_cleanly(result, error: type, words, folder: Path, before: list) -> None:
    """The command failed with ``error``, whose one-line message holds every one of ``words``,
    and ``folder`` holds what it held ``before`` (no output, no temporary file left)."""
    assert result.exit_code != 0
    assert isinstance(result.exception, error), result.exception
    message = str(result.exception)
    assert "\n" not in message and all(w in message for w in words), message
    assert sorted(folder.iterdir()) == before


def nan_copy(bvh_file: Path) -> Path:
    """A copy of a BVH file (``nan.bvh`` beside it) with one channel of frame 6 set to NaN."""
    lines = bvh_file.read_text().splitlines()
    first = lines.index("MOTION") + 3
    values = lines[first + 5].split()
    values[4] = "nan"
    lines[first + 5] = " ".join(values)
    bad = bvh_file.with_name("nan.bvh")
    bad.write_text("\n".join(lines) + "\n")
    return bad
