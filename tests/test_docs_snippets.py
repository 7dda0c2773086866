"""The newcomer's pages: every shell snippet of the README and the command pages runs.

Each ```sh block of README.md, docs/getting-started.md, docs/cli.md, docs/rigs.md and
docs/serve.md runs as a bash script with ``set -e`` in an empty folder, with only the venv's
``bin`` (and the system's) on ``PATH``, as a user who typed ``source .venv/bin/activate``
would run it. The files a snippet expects the user to have (:data:`USER_FILES`: their
character as BVH, glTF and FBX, a CMU-named clip, a schedule, data-set clips) are first made
with emotive itself (``generate``, :func:`emotive.core.rig_layouts.to_layout`, Blender for
FBX) or copied from the data set when it is there. Lines that install
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
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tools import bvh_to_fbx, require_tool

REPO = Path(__file__).resolve().parents[1]
PAGES = [REPO / "README.md", *(REPO / "docs" / f"{page}.md"
                                for page in ("getting-started", "cli", "rigs", "serve"))]
BLOCK = re.compile(r"^```(?:sh|bash)[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)
BIN = Path(sys.executable).parent
#: Hang guard per block only; nothing is asserted about time.
TIMEOUT_S = 1200
#: Commands whose real run takes minutes or needs the data: run as ``--help`` instead.
EXPENSIVE = ("emotive train", "emotive evaluate", "emotive serve", "emotive reconstruct",
             "emotive study serve", "emotive study simulate", "emotive synth",
             "emotive transfer", "emotive data", "--model lgb", "--weights models/")
#: Seconds of motion ``emotive generate`` makes here, whatever length the snippet asks.
QUICK_SECONDS = "2"
#: Files the snippets name as the user's own, made with emotive in the scratch folder: the
#: user's character and clips (a generated walk), a CMU-named clip, a schedule.
USER_FILES = ("my_character.bvh", "walk.bvh", "character.bvh", "my_rig.bvh", "generated.bvh",
              "tiny_robot.bvh", "my_character.glb", "my_clip.bvh", "my_cmu_clip.bvh",
              "schedule.json", "waypoints.json", *(f"dataset-1_walk_{c}.bvh" for c in
                                                    ("happy_001", "sad_001", "angry_002")))
#: The user's FBX files, made by Blender from the generated walk (only where Blender is).
FBX_FILES = ("my_character.fbx", "my_capture.fbx")


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
    from emotive.core.rig_layouts import to_layout
    from emotive.io.bvh import read_bvh, write_bvh

    folder = tmp_path_factory.mktemp("user_files")
    with ThreadPoolExecutor(max_workers=2) as pool:
        for made in [pool.submit(subprocess.run, ["emotive", "generate", "--emotion", "neutral",
                                                  "--seconds", "3", "--out", out],
                                 cwd=folder, env=_env(), check=True, timeout=TIMEOUT_S)
                     for out in ("my_character.bvh", "my_character.glb")]:
            made.result()
    for name in ("walk.bvh", "character.bvh", "my_rig.bvh", "generated.bvh", "tiny_robot.bvh"):
        shutil.copy(folder / "my_character.bvh", folder / name)
    cmu = to_layout(read_bvh(folder / "my_character.bvh"), "cmu")
    for name in ("my_clip.bvh", "my_cmu_clip.bvh"):
        write_bvh(cmu, folder / name)
    shutil.copy(REPO / "examples" / "angry-to-happy.json", folder / "schedule.json")
    shutil.copy(REPO / "examples" / "waypoints.json", folder / "waypoints.json")
    data = _dataset1()
    for name in USER_FILES:
        if name.startswith("dataset-1_"):
            real = data / name if data else None
            shutil.copy(real if real and real.is_file() else folder / "walk.bvh", folder / name)
    blender = shutil.which("blender")
    if blender:
        with ThreadPoolExecutor(max_workers=2) as pool:
            for made in [pool.submit(bvh_to_fbx, blender, folder / "walk.bvh", folder / name)
                         for name in FBX_FILES]:
                made.result()
    return folder


def _dataset1() -> Path | None:
    """The unpacked dataset-1 BVH folder, or ``None`` (stand-ins are generated walks)."""
    try:
        result = subprocess.run(["emotive", "data", "path", "bandai-namco-1"], env=_env(),
                                capture_output=True, text=True, timeout=TIMEOUT_S)
    except OSError:
        return None
    path = Path(result.stdout.strip()) / "data"
    return path if result.returncode == 0 and path.is_dir() else None


def test_the_pages_have_shell_snippets():
    commands = [c for _, cs in BLOCKS for c in cs]
    assert len(BLOCKS) >= 8 and len(commands) >= 15
    assert any(where.startswith("docs/getting-started.md") for where, _ in BLOCKS)


def test_no_snippet_names_a_file_only_the_repository_has():
    for where, commands in BLOCKS:
        for command in commands:
            assert "examples/" not in command and "configs/" not in command, (where, command)


def test_expensive_commands_are_listed():
    expensive = [c for _, cs in BLOCKS for c in cs if any(e in c for e in EXPENSIVE)]
    assert any("emotive train gait" in c for c in expensive)
    assert any("emotive serve" in c for c in expensive)


def _needs_blender(commands: list[str]) -> bool:
    return any(name in command for command in commands for name in FBX_FILES)


def _run_block(commands: list[str], user_files: Path, folder: Path
               ) -> tuple[list[str], subprocess.CompletedProcess[str]]:
    """Run one block in its own empty folder with the user's files: (script, result)."""
    folder.mkdir()
    for name in (*USER_FILES, *FBX_FILES):
        if (user_files / name).is_file():
            shutil.copy(user_files / name, folder / name)
    script = ["set -euo pipefail", *map(_quick, commands)]
    result = subprocess.run(["bash", "-c", "\n".join(script)], cwd=folder, env=_env(),
                            capture_output=True, text=True, timeout=TIMEOUT_S)
    return script, result


@pytest.fixture(scope="module")
def block_runs(user_files: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Every block's (script, result), two at a time (each command runs on one thread).

    The blocks with the most commands run as written start first, so that the two workers
    finish together rather than one waiting on the longest block at the end.
    """
    root = tmp_path_factory.mktemp("blocks")
    have_blender = shutil.which("blender") is not None
    order = sorted(enumerate(BLOCKS), key=lambda item: -sum(
        not any(e in c for e in EXPENSIVE) for c in item[1][1]))
    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {where: pool.submit(_run_block, commands, user_files, root / f"b{i}")
                   for i, (where, commands) in order
                   if have_blender or not _needs_blender(commands)}
        return {where: future.result() for where, future in futures.items()}


@pytest.mark.slow
@pytest.mark.parametrize(("where", "commands"), BLOCKS, ids=[w for w, _ in BLOCKS])
def test_snippet_runs_from_an_empty_folder(where: str, commands: list[str], block_runs: dict):
    if _needs_blender(commands):
        require_tool(shutil.which("blender") is not None,
                     "Blender is not installed (apt-get install blender): the block reads FBX")
    script, result = block_runs[where]
    assert result.returncode == 0, (
        "snippet failed:\n" + "\n".join(script) + f"\n--- stderr ---\n{result.stderr[-3000:]}")
