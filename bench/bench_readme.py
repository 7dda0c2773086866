"""The README's Python snippet pasted into a fresh interpreter, against the benchmark's rate.

The snippet that animates agents with ``GaitGenerator`` (the first README block naming it)
runs as pasted in a fresh ``python -c``, with its 60-step loop made 600 steps long and timed;
beside it, in a fresh interpreter too, the benchmark's generator for the same agent count
(:func:`bench.bench_gait._generator`, one torch thread). Rounds alternate the two and the
medians are compared (target: the snippet reaches at least 0.8 of the benchmark's rate).
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

from bench.common import comparison, print_rows

ROOT = Path(__file__).resolve().parents[1]
STEPS = 600

_BENCH = """
import time
import torch
from bench.bench_gait import _generator, default_model
torch.set_num_threads(1)
gen = _generator(default_model(), {agents})
start = time.perf_counter()
for _ in range({steps}):
    gen.step()
print("RATE", {agents} * {steps} / (time.perf_counter() - start))
"""


def readme_snippet() -> tuple[str, int]:
    """The README's generator snippet, its loop timed, and its number of agents."""
    text = (ROOT / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "GaitGenerator" in b)
    lines = block.splitlines()
    agents = sum(ln.count("gen.add_agent(") for ln in lines)
    loops = [k for k, ln in enumerate(lines) if ln.startswith("for _ in range(60):")]
    if len(loops) != 1 or agents < 1:
        raise ValueError("the README's GaitGenerator snippet changed: update bench/bench_readme.py")
    k = loops[0]
    end = k + 1
    while end < len(lines) and lines[end].startswith("    "):
        end += 1
    timed = [*lines[:k], "import time as _time", "_start = _time.perf_counter()",
             lines[k].replace("range(60)", f"range({STEPS})", 1), *lines[k + 1:end],
             f"print('RATE', {agents} * {STEPS} / (_time.perf_counter() - _start))",
             *lines[end:]]
    return "\n".join(timed) + "\n", agents


def _rate(code: str) -> float:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join((str(ROOT), str(ROOT / "src")))}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env=env, timeout=600, check=True)
    return float(next(ln.split()[1] for ln in out.stdout.splitlines() if ln.startswith("RATE")))


def run(rounds: int = 3) -> list[dict]:
    """One row: the snippet's rate against the benchmark's, medians of ``rounds`` each."""
    snippet, agents = readme_snippet()
    bench = _BENCH.format(agents=agents, steps=STEPS)
    ours, theirs = [], []
    for _ in range(rounds):
        ours.append(_rate(snippet))
        theirs.append(_rate(bench))
    return [comparison(f"readme_snippet[{agents} agents, fresh interpreter]", "agent-frames/s",
                       statistics.median(ours), statistics.median(theirs),
                       f"bench generator, {agents} agents (target ratio >= 0.8)")]


def main() -> None:
    """Print the row and the total time."""
    print_rows(run)


if __name__ == "__main__":
    main()
