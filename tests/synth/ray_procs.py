"""The processes a run started, found in ``/proc`` (Linux), and waiting for them to end.

A local Ray's processes are the run's children (its GCS server, raylet, workers) and
grandchildren (the raylet's agents); waiting is on the processes themselves (a pidfd becomes
readable when its process ends), not a polling loop.
"""

from __future__ import annotations

import os
import select
import time
from pathlib import Path


def descendants(root: int) -> set[int]:
    """Live (not zombie) processes descended from ``root``."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        # Fields after the command name (in parentheses): state, parent pid, ...
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if state != "Z":
            children.setdefault(int(ppid), []).append(int(entry.name))
    found, todo = set(), [root]
    while todo:
        for child in children.get(todo.pop(), []):
            found.add(child)
            todo.append(child)
    return found


def wait_gone(pids: set[int], seconds: float) -> set[int]:
    """Wait up to ``seconds`` in all for every process of ``pids`` to end; those still there."""
    left, deadline = set(), time.monotonic() + seconds
    for pid in sorted(pids):
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue  # already gone
        try:
            ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                left.add(pid)
        finally:
            os.close(fd)
    return left
