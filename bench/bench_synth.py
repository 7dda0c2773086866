"""``emotive synth`` on Ray: walks/s, the paper's recipe end to end, a cluster's projection.

Usage: ``python -m bench.bench_synth [--quick] [--out bench/results/bench_synth.json]``. Needs no
data (the novelty check runs when the data is there, and is part of the timed command).

Rows:

* ``synth_walks_per_s[2 workers vs 1]``: walks made per second by a local Ray of 2 workers
  against 1, on a recipe of :data:`SCALING` walks of 10 s (shards of 100; the rate of the
  engine, from the first task to the last shard written, worker start-up included);
  ``synth_walks_per_s_started[...]``: the same after the first shard is written (the workers
  started);
* ``synth_paper_recipe[3000 walks x 10 s]``: the wall time of ``emotive synth --out DIR`` with
  its defaults (the paper's recipe, section 5.2) as a user runs it, against the target of 3
  minutes on this machine (skipped by ``--quick``);
* ``synth_start_up[1 walk]``: the wall time of ``emotive synth`` making one walk (Ray,
  workers loading the model, the novelty check, the manifest);
* ``synth_shard_cost[100 walks x 10 s]``: one shard (one task: 100 walks stepped in one batch,
  measured, hashed, packed) in this process on one thread, warm, median of
  :data:`REPEATS`;
* ``synth_cluster_projection[K nodes x C cores]``: the paper's recipe on ``K`` machines of
  ``C`` cores stated from that cost: ``start + ceil(shards / (K C)) x shard cost``, against
  the measured time on this machine; ``start`` is ``synth_start_up[1 walk]``. A projection,
  not a measurement: it assumes the shard cost of this machine, no other load, and a head
  that keeps up (it writes about 20 MB per shard).
"""

from __future__ import annotations

import argparse
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import comparison, machine_info, write_record
from emotive.synth import Recipe, synthesize
from emotive.synth.build import recipe_values
from emotive.synth.shards import make_shard

HERE = Path(__file__).resolve().parent
#: Walks of the scaling rows (12 shards of 100).
SCALING = 1200
#: The issue's target for the paper's recipe on this 2-core machine, seconds.
TARGET_SECONDS = 180.0
#: Timed repeats of one shard.
REPEATS = 3
#: Cluster sizes of the projection: (nodes, cores per node).
CLUSTERS = ((1, 2), (2, 2), (4, 2), (8, 2), (8, 16))


def scaling(workers: int, folder: Path) -> tuple[float, float]:
    """Walks/s of a local Ray with ``workers`` on :data:`SCALING` walks of 10 s.

    Returns:
        The rate over the whole run (workers' start-up included) and after the first shard.
    """
    recipe = Recipe(paths=SCALING // 100, emotions=100, transitions=0, seconds=10.0)
    report = synthesize(folder / f"scaling-{workers}", recipe, workers=workers, progress=False)
    print(f"{workers} worker(s): {report.summary()}; {report.steady_walks_per_second:.1f} "
          "walks/s after the first shard", flush=True)
    return report.walks_per_second, report.steady_walks_per_second


def paper_recipe(folder: Path) -> float:
    """Wall time (s) of ``emotive synth --out DIR`` with its defaults, as a user runs it."""
    emotive = str(Path(sys.executable).parent / "emotive")
    start = time.perf_counter()
    subprocess.run([emotive, "synth", "--out", str(folder / "paper"), "--no-progress"],
                   check=True)
    return time.perf_counter() - start


def start_up(folder: Path) -> float:
    """Wall time (s) of ``emotive synth`` making one walk: Ray, workers, checks, manifest."""
    emotive = str(Path(sys.executable).parent / "emotive")
    start = time.perf_counter()
    subprocess.run([emotive, "synth", "--out", str(folder / "one"), "--paths", "1",
                    "--emotions", "1", "--transitions", "0", "--workers", "1",
                    "--no-progress"], check=True)
    return time.perf_counter() - start


def shard_cost() -> float:
    """Median seconds of one warm shard of the paper's recipe in this process."""
    values = recipe_values(Recipe())
    draws = (0,) * Recipe().paths           # the paper's trajectories are their first draws
    make_shard(values, None, draws, 29)     # warm: the model and the classifier loaded
    times = []
    for k in range(REPEATS):
        start = time.perf_counter()
        make_shard(values, None, draws, k)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run(quick: bool = False, details: dict | None = None) -> list[dict]:
    """The rows of the module docstring (``quick``: without the paper's recipe end to end).

    Args:
        quick: skip the 3,000-walk run; the projection then starts from the start-up of the
            scaling run.
        details: if given, every measured number is stored in it.
    """
    out = []
    with tempfile.TemporaryDirectory(prefix="bench-synth-") as tmp:
        folder = Path(tmp)
        (one, one_steady), (two, two_steady) = scaling(1, folder), scaling(2, folder)
        out.append(comparison("synth_walks_per_s[2 workers vs 1]", "walks/s", two, one,
                              "1 worker, same recipe"))
        out.append(comparison("synth_walks_per_s_started[2 workers vs 1]", "walks/s",
                              two_steady, one_steady, "1 worker, after the first shard"))
        cost = shard_cost()
        start = start_up(folder)
        shards = Recipe().shards
        measured = None if quick else paper_recipe(folder)
    if measured is not None:
        out.append(comparison("synth_paper_recipe[3000 walks x 10 s]", "s", measured,
                              TARGET_SECONDS, "target: 3 minutes on this 2-core machine",
                              higher_is_better=False))
    out.append(comparison("synth_shard_cost[100 walks x 10 s]", "s", cost, cost * 100 / 30.0,
                          "real time of its 100 walks on one core", higher_is_better=False))
    out.append(comparison("synth_start_up[1 walk]", "s", start, TARGET_SECONDS,
                          "target of the whole recipe", higher_is_better=False))
    local = measured if measured is not None else start + shards * 100 / two_steady
    for nodes, cores in CLUSTERS:
        projected = start + math.ceil(shards / (nodes * cores)) * cost
        out.append(comparison(f"synth_cluster_projection[{nodes} nodes x {cores} cores]", "s",
                              projected, local, "measured on this machine (2 workers)",
                              higher_is_better=False))
    if details is not None:
        details.update({"walks_per_s_1": one, "walks_per_s_2": two,
                        "walks_per_s_started_1": one_steady, "walks_per_s_started_2": two_steady,
                        "shard_seconds": cost,
                        "paper_recipe_seconds": measured, "start_seconds": start})
    print(f"shard of 100 walks: {cost:.2f} s on one core; start-up {start:.1f} s", flush=True)
    return out


def main() -> None:
    """Run the benchmark from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 3,000-walk run")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "bench_synth.json")
    args = parser.parse_args()
    details: dict = {}
    results = run(args.quick, details)
    print(f"\n{'benchmark':52} {'unit':8} {'emotive':>9} {'baseline':>9} {'ratio':>6}  baseline")
    for r in results:
        print(f"{r['name']:52} {r['unit']:8} {r['ours']:9.2f} {r['baseline']:9.2f} "
              f"{r['ratio']:6.2f}  {r['baseline_name']}")
    write_record(args.out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                            "machine": machine_info(), "results": results, "details": details})


if __name__ == "__main__":
    main()
