"""The README and the docs: every Python snippet runs as pasted, and the front page stays short.

Each ```python block of README.md and docs/**/*.md runs in a fresh interpreter, in an empty
folder, with a timeout. A block whose first line is ``# needs the data`` is skipped when the
Bandai Namco data is absent (and fails under ``EMOTIVE_REQUIRE_DATA=1``, as every data test).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
DOCS = REPO / "docs"
NEEDS_DATA = "# needs the data"
#: A snippet still running after this long has hung (a hang detector, not a speed check: the
#: slowest snippets took over 180 s on a 2-core machine with a load average of 17).
TIMEOUT_S = 900
BLOCK = re.compile(r"^```python[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)


def _snippets() -> list[tuple[str, str]]:
    found = []
    for path in [README, *sorted(DOCS.rglob("*.md"))]:
        text = path.read_text(encoding="utf-8")
        for match in BLOCK.finditer(text):
            line = text.count("\n", 0, match.start()) + 1
            found.append((f"{path.relative_to(REPO)}:{line}", match.group(1)))
    return found


SNIPPETS = _snippets()


def test_snippets_were_found():
    assert len(SNIPPETS) >= 5
    assert any(where.startswith("README.md") for where, _ in SNIPPETS)


@pytest.mark.slow
@pytest.mark.parametrize("code", [c for _, c in SNIPPETS], ids=[w for w, _ in SNIPPETS])
def test_snippet_runs_as_pasted(code: str, tmp_path: Path, request: pytest.FixtureRequest):
    if code.lstrip().startswith(NEEDS_DATA):
        # Skips without the data, or fails under EMOTIVE_REQUIRE_DATA=1 (tests/conftest.py).
        request.getfixturevalue("bandai1_dir")
        request.getfixturevalue("bandai2_dir")
    env = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}
    result = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=TIMEOUT_S)
    assert result.returncode == 0, f"snippet failed:\n{code}\n--- stderr ---\n{result.stderr}"


def test_readme_is_a_front_page():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 350, f"README.md has {len(lines)} lines; move detail into docs/"
    text = "\n".join(lines)
    for must in ("make demo", "make test", "MIT", "CC BY-NC 4.0", "torch==2.13.0"):
        assert must in text


def test_every_shipped_model_has_a_card():
    cards = sorted((REPO / "src" / "emotive" / "assets").glob("*/MODEL_CARD.md"))
    assert len(cards) >= 5, [c.parent.name for c in cards]
    assert {"gait", "fcrbm", "classifier", "mar", "lgb"} <= {c.parent.name for c in cards}


def test_every_registered_model_is_documented():
    from emotive.models.registry import REGISTRY

    page = (REPO / "docs" / "models" / "index.md").read_text(encoding="utf-8")
    missing = [name for name in REGISTRY if f"`{name}`" not in page]
    assert not missing, f"docs/models/index.md does not name {missing}"
    for entry in REGISTRY.values():
        if entry.card is not None:
            assert (REPO / "src" / "emotive" / entry.card).is_file(), entry.card


def test_every_registered_model_is_in_the_evaluate_help():
    from typer.testing import CliRunner

    from emotive.cli import app
    from emotive.models.registry import REGISTRY

    result = CliRunner().invoke(app, ["evaluate", "--help"], env={"COLUMNS": "300"})
    assert result.exit_code == 0, result.output
    flat = " ".join(result.output.split())
    assert all(name in flat for name in REGISTRY), flat
