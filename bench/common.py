"""Shared benchmark helpers: timing medians, machine facts, result records."""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy
import torch

from emotive.io.atomic import atomic_output


def median_seconds(fn: Callable[[], Any], repeats: int = 5, warmup: int = 1) -> float:
    """Median wall time of ``fn()`` over ``repeats`` runs after ``warmup`` untimed runs."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


#: Torch intra-op threads every benchmark row runs on unless it says otherwise.
PINNED_THREADS = 1
#: Torch's thread count when the benchmarks started (its default on this machine).
DEFAULT_THREADS = torch.get_num_threads()


@contextmanager
def pinned_threads(count: int = PINNED_THREADS) -> Iterator[None]:
    """Run the block on ``count`` torch threads, then restore the previous count."""
    before = torch.get_num_threads()
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)


@contextmanager
def unpinned_threads() -> Iterator[None]:
    """Run the block on torch's own default thread count (for rows comparing with it)."""
    with pinned_threads(DEFAULT_THREADS):
        yield


def resident_mb() -> float:
    """Resident memory of this process, MB (Linux ``/proc``; 0 elsewhere)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def machine_info() -> dict[str, Any]:
    """Facts that make numbers comparable across runs."""
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "torch_default_threads": DEFAULT_THREADS,
        "pinned_threads": PINNED_THREADS,
        "numpy": numpy.__version__,
        "torch": torch.__version__,
    }


def comparison(
    name: str, unit: str, ours: float, baseline: float, baseline_name: str,
    higher_is_better: bool = True,
) -> dict:
    """One side-by-side record; ``ratio`` > 1 always means emotive does better.

    For rates (``higher_is_better``) the ratio is ``ours / baseline``; for times it is
    ``baseline / ours``.
    """
    num, den = (ours, baseline) if higher_is_better else (baseline, ours)
    return {
        "name": name,
        "unit": unit,
        "ours": ours,
        "baseline": baseline,
        "baseline_name": baseline_name,
        "higher_is_better": higher_is_better,
        "ratio": num / den if den else float("inf"),
    }


def write_record(path: Any, record: dict[str, Any]) -> None:
    """Write a result record as indented JSON, atomically, and say where."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(record, indent=1, default=float))
    print(f"\nwrote {path}")


def print_rows(run: Callable[[], list[dict]]) -> None:
    """Run one benchmark module's ``run``, print each row and the total time."""
    start = time.perf_counter()
    for row in run():
        print(row)
    print(f"{time.perf_counter() - start:.1f} s")
