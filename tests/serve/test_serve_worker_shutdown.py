"""``emotive serve --workers 2 --worker-kind processes`` as users run it: Ctrl-C, or a killed
server, leaves no worker.

The server runs as its own process group (as in a terminal); the test sends what a terminal
does (SIGINT to the whole group) or kills the server outright, then waits, within a hang
guard, for its step workers to be gone. Nothing is asserted about time.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import httpx
import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="finds the worker processes in /proc (Linux)")

#: Wall seconds the server may take to start, or its workers to go: hang guards.
HANG_SECONDS = 180.0
_URL = re.compile(r"app:\s+(http://\S+?)/")


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _workers(parent: int) -> set[int]:
    """The step workers whose parent is ``parent``."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == parent and (
                b"emotive.serve.worker_process" in cmdline):
            found.add(int(entry.name))
    return found


def _until(check, what: str) -> None:
    deadline = time.monotonic() + HANG_SECONDS
    while not check():
        assert time.monotonic() < deadline, f"{what} within {HANG_SECONDS:.0f} s"
        time.sleep(0.1)


@contextmanager
def _server() -> Iterator[tuple[subprocess.Popen, set[int]]]:
    """``emotive serve --workers 2 --worker-kind processes`` in its own process group, once
    it answers."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "from emotive.cli import main; main()", "serve", "--port", "0",
         "--workers", "2", "--worker-kind", "processes"], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, start_new_session=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True).start()
    try:
        _until(lambda: any(_URL.search(line) for line in list(lines)) or proc.poll() is not None,
               "the server printed no URL")
        url = next(m.group(1) for m in map(_URL.search, list(lines)) if m)

        def answers() -> bool:
            try:
                return httpx.get(f"{url}/api/health", timeout=HANG_SECONDS).status_code == 200
            except httpx.HTTPError:
                return proc.poll() is not None

        _until(answers, "the server did not answer")
        assert proc.poll() is None, "".join(lines)
        workers = _workers(proc.pid)
        yield proc, workers
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


def test_ctrl_c_stops_the_server_and_its_workers():
    with _server() as (proc, workers):
        assert len(workers) == 2
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal sends
        assert proc.wait(HANG_SECONDS) == 0
        _until(lambda: not any(map(_alive, workers)), "workers outlived the server")


def test_workers_of_a_killed_server_exit_by_themselves():
    with _server() as (proc, workers):
        assert len(workers) == 2
        proc.kill()  # no shutdown at all: the workers see their socket close
        proc.wait()
        _until(lambda: not any(map(_alive, workers)), "workers outlived a killed server")
