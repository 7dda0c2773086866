"""The newcomer's pages: every shell snippet of README.md and docs/getting-started.md runs.

Each ```sh block runs as a bash script with ``set -e`` in an empty folder, with only the
venv's ``bin`` (and the system's) on ``PATH``, as a user who typed ``source .venv/bin/activate``
would run it. The files a snippet expects the user to have (``my_character.bvh``, a
``walk.bvh`` to retarget) are first made with ``emotive generate``. Lines that install
(``make``, ``pip``, ``python3.11 -m venv``) are not run here; tests/packaging/test_wheel.py
checks the wheel. Expensive commands (training, evaluation suites, the server, a 600 s LGB
clip, the data-set commands) run as ``COMMAND --help``, which checks that the command and the
options the snippet names exist. To keep the suite fast, ``emotive generate`` makes
:data:`QUICK_SECONDS` seconds instead of the snippet's length (the same options otherwise), and
a command that two pages share runs once. Every command as written, from an empty folder, is
the newcomer run of the packaging work (its report gives the count).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", REPO / "docs" / "getting-started.md"]
BLOCK = re.compile(r"^```(?:sh|bash)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)
BIN = Path(sys.executable).parent
#: Hang guard per block only; nothing is asserted about time.
TIMEOUT_S = 600
#: Commands whose real run takes minutes or needs the data: run as ``--help`` instead.
EXPENSIVE = ("emotive train", "emotive evaluate", "emotive serve", "emotive reconstruct",
             "emotive transfer", "emotive data", "--model lgb")
#: Seconds of motion ``emotive generate`` makes here, whatever length the snippet asks.
QUICK_SECONDS = "2"
#: Files the snippets name as the user's own, made with emotive in the scratch folder.
USER_FILES = ("my_character.bvh", "walk.bvh")


def _commands(block: str) -> list[str]:
    """The block's command lines, backslash continuations joined, comment lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", block)
    return [line.strip() for line in joined.splitlines()
            if line.strip() and not line.lstrip().startswith("#")]


def _program(command: str) -> str:
    """The first word that is not an environment assignment (``OMP_NUM_THREADS=1``)."""
    words = shlex.split(command, comments=True)
    return next((w for w in words if not re.fullmatch(r"[A-Z_]+=\S*", w)), "")


def _as_help(command: str) -> str:
    """``emotive train gait --config x`` -> ``emotive train gait --help`` (verbs kept)."""
    words = shlex.split(command, comments=True)
    start = next(i for i, w in enumerate(words) if w == "emotive")
    verbs = []
    for word in words[start + 1:]:
        if not re.fullmatch(r"[a-z][a-z0-9-]*", word):
            break
        verbs.append(word)
    return shlex.join(["emotive", *verbs, "--help"])


def _quick(command: str) -> str:
    """The command as run here: ``--help`` if expensive, ``generate`` shortened."""
    if any(e in command for e in EXPENSIVE):
        return _as_help(command)
    words = shlex.split(command, comments=True)
    if words[1:2] != ["generate"]:
        return command
    if "--seconds" in words:
        words[words.index("--seconds") + 1] = QUICK_SECONDS
    else:
        words += ["--seconds", QUICK_SECONDS]
    return shlex.join(words)


def _blocks() -> list[tuple[str, list[str]]]:
    found, seen = [], set()
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for match in BLOCK.finditer(text):
            commands = [c for c in _commands(match.group(1))
                        if _program(c) == "emotive" and c not in seen]
            seen.update(commands)
            if commands:
                line = text.count("\n", 0, match.start()) + 1
                found.append((f"{page.relative_to(REPO)}:{line}", commands))
    return found


BLOCKS = _blocks()


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return {**env, "PATH": f"{BIN}:/usr/bin:/bin", "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}


@pytest.fixture(scope="module")
def user_files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("user_files")
    subprocess.run(["emotive", "generate", "--emotion", "neutral", "--seconds", "3", "--out",
                    "my_character.bvh"], cwd=folder, env=_env(), check=True, timeout=TIMEOUT_S)
    shutil.copy(folder / "my_character.bvh", folder / "walk.bvh")
    return folder


def test_the_pages_have_shell_snippets():
    commands = [c for _, cs in BLOCKS for c in cs]
    assert len(BLOCKS) >= 8 and len(commands) >= 15
    assert any(where.startswith("docs/getting-started.md") for where, _ in BLOCKS)


def test_no_snippet_names_a_file_only_the_repository_has():
    for where, commands in BLOCKS:
        for command in commands:
            if "emotive train" in command:
                continue    # training is shown for a clone of the repository, and says so
            assert "examples/" not in command and "configs/" not in command, (where, command)


def test_expensive_commands_are_listed():
    expensive = [c for _, cs in BLOCKS for c in cs if any(e in c for e in EXPENSIVE)]
    assert any("emotive train gait" in c for c in expensive)
    assert any("emotive serve" in c for c in expensive)


@pytest.mark.slow
@pytest.mark.parametrize("commands", [c for _, c in BLOCKS], ids=[w for w, _ in BLOCKS])
def test_snippet_runs_from_an_empty_folder(commands: list[str], user_files: Path,
                                           tmp_path: Path):
    for name in USER_FILES:
        shutil.copy(user_files / name, tmp_path / name)
    script = ["set -euo pipefail", *map(_quick, commands)]
    result = subprocess.run(["bash", "-c", "\n".join(script)], cwd=tmp_path, env=_env(),
                            capture_output=True, text=True, timeout=TIMEOUT_S)
    assert result.returncode == 0, (
        "snippet failed:\n" + "\n".join(script) + f"\n--- stderr ---\n{result.stderr[-3000:]}")
