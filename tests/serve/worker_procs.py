"""The step worker processes of a server, found in ``/proc`` (Linux), and waiting for them.

Waiting is on the processes themselves (a pidfd becomes readable when its process ends), not
a polling loop.
"""

from __future__ import annotations

import os
import select
from pathlib import Path


def step_workers(parent: int) -> set[int]:
    """Live (not zombie) step workers whose parent is ``parent``."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        # Fields after the command name (in parentheses): state, parent pid, ...
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if int(ppid) == parent and b"emotive.serve.worker_process" in cmdline and state != "Z":
            found.add(int(entry.name))
    return found


def wait_gone(pids: set[int], seconds: float) -> set[int]:
    """Wait up to ``seconds`` for every process of ``pids`` to end; returns those still there."""
    left = set()
    for pid in pids:
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue  # already gone
        try:
            ready, _, _ = select.select([fd], [], [], seconds)
            if not ready:
                left.add(pid)
        finally:
            os.close(fd)
    return left
