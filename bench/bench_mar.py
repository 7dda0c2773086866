"""Style transfer speed (Xia et al. 2015, MAR): milliseconds per streamed frame.

Ours: :class:`emotive.models.mar.transfer.StyleTransfer` with the k-d tree search of
:mod:`emotive.models.mar.search` (reduced window features, exact equation-1 distance on the
tree candidates). Baseline, in the same run on the same frames: the same stream with
brute-force search (the exact distance to every frame of every allowed class). Both run on one
thread (``torch`` and BLAS), on the default index (both Bandai Namco data sets, at least 80,000
frames), for an unlabeled input and for one labelled with its action. Also: seconds to load
the index and build the trees, and the memory they take (resident set growth and the arrays'
bytes). Numbers are medians over the streamed frames.

Also, the whole clip as ``emotive transfer`` runs it (stream, foot pinning and, on another
rig, retargeting there and back; index already loaded): milliseconds per input frame on the
clip retargeted onto a Mixamo-named rig standing in a T-pose, against the same clip on the
Bandai rig, best of two interleaved rounds each.

Usage: ``python -m bench.bench_mar [--frames N] [--baseline-frames N]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import torch

from bench.common import comparison, machine_info, write_record
from emotive.core.rig_layouts import to_layout
from emotive.data.clips import load_clips
from emotive.models.mar.database import MARDatabase
from emotive.models.mar.default_index import default_index_path, load_default_index
from emotive.models.mar.representation import RigCodec
from emotive.models.mar.search import PointCloudSearch
from emotive.models.mar.transfer import StyleTransfer, transfer_motion
from emotive.retarget import rest_template, retarget

HERE = Path(__file__).resolve().parent

CLIP = "dataset-2_walk_normal_010"


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])

    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def _stream_ms(db, search, motion, frames: int, brute: bool, action: str | None) -> float:
    """Median ms of :meth:`StyleTransfer.push` over ``frames`` frames (after 5 warm-up)."""
    stream = StyleTransfer(db, RigCodec.for_motion(motion), "proud=0.6,angry=0.4",
                           action=action, search=search, brute_force=brute)
    times = []
    for t in range(min(frames + 5, motion.num_frames)):
        start = time.perf_counter()
        stream.push(motion.rotations[t], motion.positions[t])
        if t >= 5:
            times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def _clip_ms(db, search, motion) -> float:
    """Milliseconds per input frame of :func:`transfer_motion` on the whole clip."""
    start = time.perf_counter()
    transfer_motion(motion, db, "proud=0.6,angry=0.4", search=search)
    return 1000.0 * (time.perf_counter() - start) / motion.num_frames


def _other_rig_row(db, search, motion) -> dict:
    """Whole-clip transfer on a Mixamo-named rig against the Bandai rig, same clip."""
    rig = rest_template(to_layout(motion, "mixamo").skeleton)
    other = retarget(motion, rig)
    bandai, mixamo = [], []
    for _ in range(2):
        bandai.append(_clip_ms(db, search, motion))
        mixamo.append(_clip_ms(db, search, other))
    return comparison(f"mar whole-clip ms/frame [Mixamo rig, {motion.num_frames} frames]",
                      "ms", min(mixamo), min(bandai), "the same clip on the Bandai rig",
                      higher_is_better=False)


def run(frames: int = 200, baseline_frames: int = 20) -> list[dict]:
    """The records of the benchmark (see the module docstring)."""
    from threadpoolctl import threadpool_limits  # noqa: PLC0415 (optional threadpoolctl)

    torch.set_num_threads(1)
    load_default_index(progress=True)  # built on first use, outside the timing

    before = _rss_mb()
    start = time.perf_counter()
    db = MARDatabase.load(default_index_path())
    search = PointCloudSearch(db)
    load_s = time.perf_counter() - start
    rss = _rss_mb() - before
    arrays = sum(getattr(db, n).nbytes for n in ("vectors", "points", "features", "prev",
                                                 "frame_class", "tau", "rate", "contacts",
                                                 "track_pose")) / 2**20
    motion = next(c.motion for c in load_clips("bandai-namco-2-locomotion", contents=["walk"])
                  if c.name == CLIP)
    records = []
    with threadpool_limits(1):
        for label, action in (("unlabeled", None), ("action given", "walk")):
            fast = _stream_ms(db, search, motion, frames, False, action)
            slow = _stream_ms(db, search, motion, baseline_frames, True, action)
            records.append(comparison(
                f"mar transfer ms/frame [{label}, {db.num_frames} db frames]", "ms",
                fast, slow, "brute-force exact search", higher_is_better=False))
        records.append(_other_rig_row(db, search, motion))
    records.append({"name": "mar index load + trees", "unit": "s", "ours": load_s,
                    "baseline": float("nan"), "baseline_name": "-", "higher_is_better": False,
                    "ratio": float("nan")})
    records.append({"name": "mar index memory (RSS growth)", "unit": "MB", "ours": rss,
                    "baseline": arrays, "baseline_name": "bytes of the main arrays",
                    "higher_is_better": False, "ratio": arrays / rss if rss else float("nan")})
    return records


def main() -> None:
    """Run the benchmark from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--baseline-frames", type=int, default=20)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "bench_mar.json")
    args = parser.parse_args()
    records = run(args.frames, args.baseline_frames)
    for r in records:
        print(f"{r['name']:60} {r['unit']:4} {r['ours']:10.3f} {r['baseline']:10.3f} "
              f"{r['ratio']:7.2f}  {r['baseline_name']}")
    write_record(args.out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                            "machine": machine_info(), "results": records})


if __name__ == "__main__":
    main()
