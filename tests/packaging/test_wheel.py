"""The wheel: built from the source tree, installed outside the repository, run from anywhere.

What this catches: an asset the package reads at run time (weights, model cards, the browser
app and its vendored three.js) missing from the wheel, a console script that does not start
outside a checkout, a default path that only exists in the repository.

How the clean environment gets its dependencies. ``pip install emotive-*.whl[serve,onnx]``
with ``torch==2.13.0`` (the CPU build) into a fresh venv took 4 min 26 s on a busy 2-core
machine from the local package index (measured 2026-12-04), too long for a suite that must
stay fast. So the venv is made with this interpreter and its site-packages gets one
``.pth`` line naming the dev venv's site-packages, *after* its own: the dependencies come from
there, but the wheel's emotive is installed into the venv itself (``--no-deps``), and the dev
venv's editable-install finder (a ``.pth`` file of its own) is not run, because Python only
processes ``.pth`` files of site directories, not of folders a ``.pth`` line adds. The tests
check that ``emotive`` is imported from the clean venv and that the checkout's ``src`` is not
on ``sys.path``. Nothing here skips: ``make test`` installs the dev extra (``build``) and the
``serve`` and ``onnx`` extras the commands need.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import sysconfig
import threading
import zipfile
from pathlib import Path

import httpx
import pytest

REPO = Path(__file__).resolve().parents[2]
SRC = REPO / "src" / "emotive"
#: Hang guards only (a busy 2-core machine is slow); nothing is asserted about time.
BUILD_TIMEOUT_S = 600
RUN_TIMEOUT_S = 300
SERVE_WAIT_S = 300

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel of the working tree, built by ``python -m build`` (sdist, then wheel from it)."""
    out = tmp_path_factory.mktemp("dist")
    result = subprocess.run([sys.executable, "-m", "build", "--outdir", str(out), str(REPO)],
                            capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    (found,) = out.glob("emotive-*.whl")
    return found


@pytest.fixture(scope="module")
def venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A venv outside the repository with the wheel installed and the dev venv's dependencies."""
    root = tmp_path_factory.mktemp("venv") / "env"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True,
                   timeout=RUN_TIMEOUT_S)
    python = root / "bin" / "python"
    site = Path(subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True, timeout=RUN_TIMEOUT_S).stdout.strip())
    (site / "zz_dev_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    result = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps",
         "--no-index", "--quiet", str(wheel)],
        capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    return root


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    return {**env, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1"}


def _run(venv: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    result = subprocess.run([str(venv / "bin" / args[0]), *args[1:]], cwd=cwd, env=_env(),
                            capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, f"{' '.join(args)}:\n{result.stdout}\n{result.stderr}"
    return result


def test_the_wheel_holds_every_file_of_the_package(wheel: Path):
    names = set(zipfile.ZipFile(wheel).namelist())
    tree = {f"emotive/{p.relative_to(SRC).as_posix()}" for p in SRC.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and p.suffix != ".pyc"}
    assert tree - names == set()
    for asset in ("emotive/assets/gait/emotive-gait.pt", "emotive/assets/gait/MODEL_CARD.md",
                  "emotive/serve/static/index.html",
                  "emotive/serve/static/vendor/three/three.module.js",
                  "emotive/web/static/index.html",
                  "emotive/assets/onnxruntime-web/ort-wasm-simd-threaded.wasm",
                  "emotive/study/static/index.html", "emotive/study/migrations/env.py",
                  "emotive/study/migrations/versions/0001_initial.py"):
        assert asset in names


def test_emotive_is_imported_from_the_clean_venv(venv: Path, tmp_path: Path):
    code = ("import sys, emotive; print(emotive.__file__); "
            f"print({str(REPO / 'src')!r} in [p.rstrip('/') for p in sys.path])")
    where, src_on_path = _run(venv, tmp_path, "python", "-c", code).stdout.split()
    assert Path(where).resolve().is_relative_to(venv.resolve()), where
    assert not Path(where).resolve().is_relative_to(REPO), where
    assert src_on_path == "False"


def test_the_training_recipes_come_with_the_wheel(venv: Path, tmp_path: Path):
    code = ("from emotive.configs import resolve_config; "
            "from emotive.models.gait.training import load_gait_settings; "
            "path = resolve_config('gait-finetune'); print(path); "
            "print(load_gait_settings(path)[1].init_from)")
    recipe, start = _run(venv, tmp_path, "python", "-c", code).stdout.split()
    for path in (Path(recipe), Path(start)):
        assert path.is_file() and path.resolve().is_relative_to(venv.resolve()), path
    assert "--config" in _run(venv, tmp_path, "emotive", "train", "gait", "--help").stdout


def test_generate_writes_a_bvh_that_parses(venv: Path, tmp_path: Path):
    from emotive.io.bvh import read_bvh

    _run(venv, tmp_path, "emotive", "generate", "--emotion", "happy", "--seconds", "2",
         "--out", "walk.bvh")
    motion = read_bvh(tmp_path / "walk.bvh")
    assert motion.num_frames == 61 and motion.fps == 30    # frames at 0, 1/30, ..., 2 s


def test_export_onnx_writes_a_model(venv: Path, tmp_path: Path):
    import onnx

    _run(venv, tmp_path, "emotive", "export", "onnx", "--out", "gait.onnx")
    onnx.checker.check_model(str(tmp_path / "gait.onnx"))


def test_export_web_writes_the_page_from_the_wheel(venv: Path, tmp_path: Path):
    _run(venv, tmp_path, "emotive", "export", "web", "--out", "site")
    site = tmp_path / "site"
    for name in ("index.html", "app.js", "figures.js", "agent.onnx", "agent.json",
                 "mannequin.glb", "vendor/three/three.module.js",
                 "vendor/onnxruntime-web/ort-wasm-simd-threaded.wasm"):
        assert (site / name).is_file(), name


def _lines(stream, out: queue.Queue) -> None:
    """Put each line of ``stream`` on ``out``, then ``None`` at its end."""
    for line in stream:
        out.put(line)
    out.put(None)


def test_a_study_is_made_and_its_database_migrated_from_the_wheel(venv: Path, tmp_path: Path):
    _run(venv, tmp_path, "emotive", "study", "init", "walkers", "--count", "1", "--seconds",
         "2")
    done = _run(venv, tmp_path, "emotive", "study", "export", "walkers", "--out", "r.csv")
    assert "0 responses" in done.stdout
    assert (tmp_path / "r.csv").read_text().startswith("participant,condition,stimulus,")
    assert (tmp_path / "walkers" / "study.db").is_file()


def test_serve_answers_health_and_the_app(venv: Path, tmp_path: Path):
    server = subprocess.Popen([str(venv / "bin" / "emotive"), "serve", "--port", "0"],
                              cwd=tmp_path, env=_env(), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=_lines, args=(server.stdout, lines), daemon=True).start()
    try:
        # The command prints its URLs once its socket listens and its engine is loaded.
        seen, url = [], None
        while url is None:
            line = lines.get(timeout=SERVE_WAIT_S)
            assert line is not None, "emotive serve exited:\n" + "".join(seen)
            seen.append(line)
            if line.strip().startswith("app:"):
                url = line.split()[1].rstrip("/")
        health = httpx.get(f"{url}/api/health", timeout=SERVE_WAIT_S).json()
        assert health["status"] == "ok" and health["model"] == "gait"
        page = httpx.get(f"{url}/", timeout=30)
        assert page.status_code == 200 and "<html" in page.text.lower()
        three = httpx.get(f"{url}/static/vendor/three/three.module.js", timeout=30)
        assert three.status_code == 200, three.status_code
    finally:
        server.terminate()
        server.wait(timeout=60)
