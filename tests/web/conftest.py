"""The browser runtime's tests share one export, made once by the command line."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest
from typer.testing import CliRunner

from emotive.commands.export import app


@dataclass(frozen=True)
class Exported:
    """The folder of ``emotive export web --out DIR`` and what the command printed."""

    folder: Path
    output: str


@pytest.fixture(scope="session")
def web_export(tmp_path_factory: pytest.TempPathFactory) -> Exported:
    pytest.importorskip("onnx")
    folder = tmp_path_factory.mktemp("web") / "site"
    result = CliRunner().invoke(app, ["web", "--out", str(folder)], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    return Exported(folder, result.output)
