"""Run every benchmark, print a side-by-side table and save JSON under ``bench/results/``.

Usage: ``python -m bench.run [--out bench/results/NAME.json] [--quick]``. Needs the Bandai Namco
data (``EMOTIVE_DATA`` or ``../shared/data``). Numbers are medians of repeated runs; ratios
compare emotive with a baseline measured in the same run (ratio > 1: emotive does better).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from bench import (
    bench_bvh,
    bench_crowd,
    bench_data,
    bench_ddp,
    bench_fcrbm,
    bench_features,
    bench_gait,
    bench_kinematics,
    bench_lgb,
    bench_mar,
    bench_onnx,
    bench_readme,
    bench_serve,
    bench_step,
    bench_study,
    bench_synth,
)
from bench.common import machine_info, pinned_threads
from emotive.data import dataset_dir
from emotive.io.bvh import read_bvh

HERE = Path(__file__).resolve().parent


def _number(value: float) -> str:
    return f"{value:12,.0f}" if abs(value) >= 100 else f"{value:12.4g}"


def main() -> None:
    """Run the benchmarks from the command line and write their record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--quick", action="store_true", help="dataset 1 only, fewer repeats")
    args = parser.parse_args()

    d1 = sorted((dataset_dir("bandai-namco-1") / "data").glob("*.bvh"))
    clips = d1 if args.quick else d1 + sorted(
        (dataset_dir("bandai-namco-2-locomotion") / "data").glob("*.bvh")
    )
    walk = read_bvh(next(p for p in d1 if "walk_happy_001" in p.name))

    results = []
    for name, fn in (
        ("bvh", lambda: bench_bvh.run(clips, repeats=1 if args.quick else 3)),
        ("kinematics", lambda: bench_kinematics.run(walk)),
        ("features", lambda: bench_features.run(walk)),
        ("data", lambda: bench_data.run(repeats=1 if args.quick else 3)),
        ("gait", lambda: bench_gait.run(
            agents=(1, 10, 100) if args.quick else (1, 10, 100, 1000),
            baseline_agents=(1, 10) if args.quick else (1, 10, 100))),
        ("readme", lambda: bench_readme.run(rounds=1 if args.quick else 3)),
        ("crowds", lambda: bench_gait.crowd_rows(
            bench_gait.default_model(), agents=300 if args.quick else 1000)),
        ("feet", lambda: bench_gait.skate_rows(bench_gait.default_model(), d1)),
        ("step", lambda: bench_step.run(agents=300 if args.quick else 1000,
                                        repeats=3 if args.quick else 5)),
        ("crowd_nav", lambda: bench_crowd.run(agents=(500,) if args.quick else bench_crowd.AGENTS,
                                              frames=10 if args.quick else bench_crowd.FRAMES)),
        ("onnx", lambda: bench_onnx.run(agents=(1, 100) if args.quick else (1, 100, 1000),
                                        repeats=3 if args.quick else 5)),
        ("serve", lambda: bench_serve.run(seconds=5.0 if args.quick else 10.0)),
        ("study", lambda: bench_study.run(stimuli=4 if args.quick else 8,
                                          seconds=5.0 if args.quick else 10.0)),
        ("mar", lambda: bench_mar.run(frames=60 if args.quick else 200,
                                      baseline_frames=10 if args.quick else 20)),
        ("fcrbm", lambda: bench_fcrbm.run(repeats=1 if args.quick else 3)),
        ("fcrbm_stream", lambda: bench_fcrbm.add_tick_rows() + bench_fcrbm.stream_skate_rows(d1)),
        ("lgb", lambda: bench_lgb.run(emotions=("sad",) if args.quick else bench_lgb.EMOTIONS,
                                      repeats=1 if args.quick else 3)),
        ("ddp", lambda: bench_ddp.run(repeats=1 if args.quick else 2,
                                      max_clips=20 if args.quick else 0,
                                      models=("gait",) if args.quick else bench_ddp.MODELS)),
        ("synth", lambda: bench_synth.run(quick=args.quick)),
    ):
        print(f"running {name} ...", flush=True)
        with pinned_threads():
            results += fn()

    print(f"\n{'benchmark':58} {'unit':9} {'emotive':>12} {'baseline':>12} {'ratio':>7}  baseline")
    for r in results:
        print(f"{r['name']:58} {r['unit']:9} {_number(r['ours'])} {_number(r['baseline'])} "
              f"{r['ratio']:7.2f}  {r['baseline_name']}")
    record = {
        "time": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": machine_info(), "results": results
    }
    out = args.out or HERE / "results" / f"bench-{time.strftime('%Y%m%d-%H%M%S')}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp")
    tmp.write_text(json.dumps(record, indent=2))
    os.replace(tmp, out)
    print(f"\nsaved {out}")


if __name__ == "__main__":
    main()
