"""Load on ``emotive study serve``: 100 simulated participants at once, SQLite and PostgreSQL.

A ``gaits`` study (8 stimuli of 10 s and one attention check: 9 items of 5 values per
participant; 4 stimuli of 5 s with ``quick``) is made in a temporary folder and served by
``emotive study serve --port 0`` in its own process, as users run it, so that the simulated
participants (``emotive.study.simulate`` in this process, one event loop) do not share its
interpreter lock; on the 2-core development machine they still share its cores. Each backend
first takes 10 participants (warm-up: connections, caches), then 100 at once (concurrency
100), every one through consent, plan, one submission per item and completion.

* SQLite: the study folder's ``study.db`` (WAL mode);
* PostgreSQL: a throwaway cluster in a temporary folder (``tests/study/postgres_cluster.py``:
  ``initdb`` with trust authentication, 127.0.0.1 at a free port, run as the ``postgres``
  user when root), a fresh database ``emotive``; skipped with the reason printed when
  PostgreSQL is not installed or does not start.

Rows per backend: acknowledged values per second against the demand of 100 real participants
(one item per ``seconds * 1.5 + 5`` s, the simulated careful raters' mean response time); the
p50 and p99 of the submission round trip with all 100 at once, answering with no pause (a
saturated closed loop: latency is queueing, about participants / throughput) against the 1 s
a page change may take without breaking the participant's flow (Nielsen); the p99 with one
participant at a time (10 after the loaded run) against the 100 ms that feels instant; then
PostgreSQL's throughput against SQLite's, measured in the same run. At 100 at once the
simulator itself (httpx's connection pool) takes about one core, so on 2 cores the numbers
are a lower bound for the server.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

from sqlalchemy import create_engine, text

from bench.common import PINNED_THREADS, comparison, print_rows
from emotive.study.config import load_study
from emotive.study.create import create_study
from emotive.study.simulate import run_simulation
from emotive.study.stimuli import load_readings

#: Seconds the server may take to start or stop.
START_TIMEOUT = 120.0
#: A reply that feels instant, milliseconds (Nielsen's 0.1 s limit).
INSTANT_MS = 100.0
#: A page change that keeps the participant's flow of thought, milliseconds (Nielsen's 1 s).
FLOW_MS = 1000.0
#: Participants of the warm-up before each measured run.
WARMUP = 10
#: Participants of the unloaded run, one at a time.
ALONE = 10
#: Values one gaits item stores (four emotion scales and naturalness).
VALUES_PER_ITEM = 5
_URL = re.compile(r"participants:\s+(http://\S+?)/?$")
ROOT = Path(__file__).resolve().parents[1]


@contextmanager
def study_server(folder: Path, db_url: str | None = None) -> Iterator[str]:
    """Run ``emotive study serve FOLDER --port 0`` in a subprocess; yield its URL; stop it."""
    cmd = [sys.executable, "-c", "from emotive.cli import main; main()", "study", "serve",
           str(folder), "--port", "0"]
    if db_url:
        cmd += ["--db", db_url]
    env = {**os.environ, "OMP_NUM_THREADS": str(PINNED_THREADS),
           "MKL_NUM_THREADS": str(PINNED_THREADS)}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env)
    lines: list[str] = []
    found = threading.Event()

    def drain() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if _URL.search(line.strip()):
                found.set()
        found.set()

    threading.Thread(target=drain, daemon=True).start()
    try:
        found.wait(START_TIMEOUT)
        urls = [m.group(1) for m in map(_URL.search, (x.strip() for x in lines)) if m]
        if not urls:
            raise RuntimeError(f"emotive study serve did not start: {''.join(lines)[-2000:]}")
        yield urls[0]
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(START_TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _postgres_cluster() -> ModuleType:
    path = ROOT / "tests" / "study" / "postgres_cluster.py"
    spec = importlib.util.spec_from_file_location("postgres_cluster", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@contextmanager
def postgres_database() -> Iterator[str | None]:
    """A fresh PostgreSQL database's URL on a throwaway cluster, or ``None`` (reason printed)."""
    cluster = _postgres_cluster()
    if cluster.bin_dir() is None:
        print("  postgresql: skipped (not installed: apt-get install postgresql)", flush=True)
        yield None
        return
    folder = Path(tempfile.mkdtemp(prefix="emotive-bench-pg-"))
    folder.chmod(0o755)
    try:
        try:
            server = cluster.start(folder / "cluster")
        except (OSError, RuntimeError, subprocess.CalledProcessError) as exc:
            detail = getattr(exc, "stderr", "") or exc
            print(f"  postgresql: skipped (the cluster did not start: {detail})", flush=True)
            yield None
            return
        admin = server.replace("postgresql://", "postgresql+psycopg://", 1)
        engine = create_engine(admin, isolation_level="AUTOCOMMIT")
        with engine.connect() as conn:
            conn.execute(text('CREATE DATABASE "emotive"'))
        engine.dispose()
        yield server.rsplit("/", 1)[0] + "/emotive"
    finally:
        cluster.stop(folder / "cluster")
        shutil.rmtree(folder, ignore_errors=True)


def _measure(folder: Path, db_url: str | None, participants: int
             ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Summaries of ``participants`` at once and of :data:`ALONE` one at a time."""
    study = load_study(folder)
    readings = load_readings(study.folder)
    with study_server(folder, db_url) as url:
        run_simulation(study, url, WARMUP, WARMUP, seed=1, readings=readings, progress=False)
        loaded = run_simulation(study, url, participants, participants, seed=2,
                                readings=readings, progress=False)
        alone = run_simulation(study, url, ALONE, 1, seed=3, readings=readings, progress=False)
    for summary, n in ((loaded, participants), (alone, ALONE)):
        if summary["server_gone"] or summary["rejected"] or summary["completed"] != n:
            raise RuntimeError(f"the simulation did not complete: {summary}")
    return loaded, alone


def _rows(backend: str, loaded: dict[str, Any], alone: dict[str, Any], demand: float
          ) -> list[dict]:
    n = loaded["participants"]
    label = f"study_{backend}[{n} at once]"
    return [
        comparison(f"{label}: responses/s", "values/s", loaded["responses_per_s"], demand,
                   f"demand of {n} real participants"),
        comparison(f"{label}: submit p50", "ms", loaded["p50_ms"], FLOW_MS,
                   "1 s: a Next that keeps the flow", higher_is_better=False),
        comparison(f"{label}: submit p99", "ms", loaded["p99_ms"], FLOW_MS,
                   "1 s: a Next that keeps the flow", higher_is_better=False),
        comparison(f"study_{backend}[1 at a time]: submit p99", "ms", alone["p99_ms"],
                   INSTANT_MS, "100 ms: feels instant", higher_is_better=False),
    ]


def run(participants: int = 100, stimuli: int = 8, seconds: float = 10.0) -> list[dict]:
    """The load rows (see the module docstring); prints each backend's summary as it goes."""
    work = Path(tempfile.mkdtemp(prefix="emotive-bench-study-"))
    work.chmod(0o755)
    try:
        template = create_study(work / "template", "gaits", count=stimuli, seconds=seconds,
                                seed=0)
        item_seconds = seconds * 1.5 + 5.0
        demand = participants * VALUES_PER_ITEM / item_seconds
        shutil.copytree(template, work / "sqlite")
        sqlite, sqlite_alone = _measure(work / "sqlite", None, participants)
        print(f"  sqlite: {sqlite}\n  sqlite, one at a time: {sqlite_alone}", flush=True)
        rows = _rows("sqlite", sqlite, sqlite_alone, demand)
        with postgres_database() as db_url:
            if db_url is not None:
                shutil.copytree(template, work / "postgresql")
                pg, pg_alone = _measure(work / "postgresql", db_url, participants)
                print(f"  postgresql: {pg}\n  postgresql, one at a time: {pg_alone}", flush=True)
                rows += _rows("postgresql", pg, pg_alone, demand)
                rows.append(comparison(f"study_postgresql[{participants} at once]: responses/s, "
                                       "vs SQLite", "values/s", pg["responses_per_s"],
                                       sqlite["responses_per_s"], "SQLite, same run"))
        return rows
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> None:
    """Print the benchmark rows and the total time."""
    print_rows(run)


if __name__ == "__main__":
    main()
