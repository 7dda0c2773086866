"""Hostile clients against ``emotive serve``: the watcher's absolute frame rate, 25 a second.

Runs the hostile campaign of ``tests/serve/serve_hostile.py`` (26 hostile connections in their
own process beside one watcher; the server as its own process, ``--workers 2``, a quota of one
agent per connection; see that module for the attackers) ``repeats`` times and prints for each
run: the scene's frames per second just before the flood and during it, the watcher's frames
in its worst and its median wall second of the flood, the seconds below :data:`FLOOR`, the
frames the server made until it had closed both slow readers, and the server's memory before,
at its peak and after. ``tests/serve/test_serve_hostile.py`` checks what holds on any machine
(the watcher gets every frame the scene makes; the scene keeps 80 % of its quiet rate); this
checks the absolute floor, which depends on the machine's load: run it on an idle machine.

``python -m bench.bench_hostile [--repeats 1] [--seconds 20] [-- SERVER ARGS]``; the exit
status is 1 when a run had a second below :data:`FLOOR`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import sys
from pathlib import Path
from typing import Any

#: Frames the watcher must get in every second of the flood.
FLOOR = 25
#: The server's arguments of the test's campaign.
SERVER_ARGS = ("--max-agents-per-client", "1", "--max-agents", "100", "--workers", "2")
#: Where the campaign lives.
CAMPAIGN = Path(__file__).resolve().parents[1] / "tests" / "serve"


def row(result: dict[str, Any]) -> str:
    """One run's line."""
    got = result["per_second"]
    below = sum(g < FLOOR for g in got)
    growth = result["rss_after_mb"] - result["rss_before_mb"]
    return (f"quiet {result['quiet_fps']:.1f} fps, flood {result['flood_fps']:.1f} fps; watcher "
            f"worst second {min(got)}, median {statistics.median(got):.0f}, {below} of "
            f"{len(got)} seconds below {FLOOR}; slow readers closed after "
            f"{result['slow_closed_after']} frames; RSS {result['rss_before_mb']:.0f} MB, peak "
            f"{result['rss_peak_mb']:.0f}, after {result['rss_after_mb']:.0f} (+{growth:.0f}); "
            f"load {os.getloadavg()[0]:.1f}")


def main(argv: list[str] | None = None) -> int:
    """Run the campaigns; print a row each; 1 if a second fell below :data:`FLOOR`."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1, help="campaigns run")
    parser.add_argument("--seconds", type=float, default=20.0, help="seconds of flood")
    parser.add_argument("server_args", nargs="*", help="the server's arguments (after --)")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(CAMPAIGN))
    campaign = importlib.import_module("serve_hostile").campaign
    worst = []
    for _ in range(args.repeats):
        result = campaign(args.seconds, quiet=1.5,
                          server_args=tuple(args.server_args) or SERVER_ARGS)
        print(row(result), flush=True)
        worst.append(min(result["per_second"]))
    return int(min(worst) < FLOOR)


if __name__ == "__main__":
    sys.exit(main())
