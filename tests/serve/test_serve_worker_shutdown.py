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
from collections.abc import Iterator
from contextlib import contextmanager

import httpx
import pytest
from worker_procs import step_workers, wait_gone

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="finds the worker processes in /proc (Linux)")

#: Wall seconds the server may take to start, or its workers to go: hang guards.
HANG_SECONDS = 180.0
_URL = re.compile(r"app:\s+(http://\S+?)/")


@contextmanager
def _server() -> Iterator[tuple[subprocess.Popen, set[int]]]:
    """``emotive serve --workers 2 --worker-kind processes`` in its own process group, once
    it answers."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "from emotive.cli import main; main()", "serve", "--port", "0",
         "--workers", "2", "--worker-kind", "processes"], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, start_new_session=True)
    lines: list[str] = []
    printed = threading.Event()

    def read() -> None:
        for line in proc.stdout:
            lines.append(line)
            if _URL.search(line):
                printed.set()
        printed.set()  # the server ended without a URL

    threading.Thread(target=read, daemon=True).start()
    try:
        assert printed.wait(HANG_SECONDS), "the server printed no URL"
        url = next((m.group(1) for m in map(_URL.search, list(lines)) if m), None)
        assert url is not None, "".join(lines)
        # The socket is bound before the URL is printed: this call waits for the answer.
        assert httpx.get(f"{url}/api/health", timeout=HANG_SECONDS).status_code == 200
        assert proc.poll() is None, "".join(lines)
        workers = step_workers(proc.pid)
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
        assert not wait_gone(workers, HANG_SECONDS), "workers outlived the server"


def test_workers_of_a_killed_server_exit_by_themselves():
    with _server() as (proc, workers):
        assert len(workers) == 2
        proc.kill()  # no shutdown at all: the workers see their socket close
        proc.wait()
        assert not wait_gone(workers, HANG_SECONDS), "workers outlived a killed server"
