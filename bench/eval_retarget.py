"""Another rig at the source's quality and speed: foot skate after retargeting, MAR's cost.

Usage: ``python -m bench.eval_retarget [--rounds 3] [--out bench/results/eval_retarget.json]``.
Needs Bandai Namco datasets 1 and 2.

The rig is the suite's Mixamo-named rig in centimetres, standing in a T-pose, with end sites
of 15 cm at the head and 10 cm at the hands (``tests/retarget/retarget_helpers.py``, imported
from there so that the bench measures the rig the tests check).

* **Foot skate** (:func:`emotive.retarget.foot_skate`, the measure ``emotive retarget``
  prints: heels and toes within 2 cm of their floor) and the suite's measure over the source's
  planted intervals (:func:`emotive.eval.feet.foot_skating`), as target over source, for a
  generated 20 s and 10 s walk (the gait network, seed 0), dataset 1's ``walk_normal_001``
  and dataset 2's ``walk_active_001``; and how many of the source's grounded heel and toe
  frames the target keeps on the ground.
* **Style transfer** (:func:`emotive.models.mar.transfer.transfer_motion`, the whole clip as
  ``emotive transfer`` runs it, index loaded) on dataset 1's ``walk_normal_001``: CPU
  milliseconds per input frame on the Bandai rig and on the clip retargeted onto the rig,
  interleaved over ``--rounds`` rounds on one thread; medians.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from bench.common import machine_info, write_record
from emotive.commands.generate import generate
from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.eval.feet import foot_skating
from emotive.features.contacts import FOOT_ROLES, foot_contacts, ground_heights
from emotive.io.bvh import read_bvh
from emotive.models.mar.database import MARDatabase
from emotive.models.mar.default_index import default_index_path, load_default_index
from emotive.models.mar.search import PointCloudSearch
from emotive.models.mar.transfer import transfer_motion
from emotive.retarget import foot_skate, retarget
from emotive.retarget.feet import SKATE_HEIGHT

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests" / "retarget"))
from retarget_helpers import mixamo_cm_rig  # noqa: E402 (the tests' rig, see the docstring)

STYLE = "proud=0.6,angry=0.4"


def _generated(seconds: int, folder: Path):
    out = folder / f"walk{seconds}.bvh"
    generate(model="gait", emotion="neutral", seconds=float(seconds), out=out)
    return read_bvh(out)


def _real(dataset: str, name: str):
    return next(c.motion for c in load_clips(dataset, contents=["walk"]) if c.name == name)


def _grounded(motion) -> np.ndarray:
    feet = motion.positions_with_end_sites()[:, resolve_roles(motion.skeleton).indices(FOOT_ROLES)]
    return (ground_heights(feet) < SKATE_HEIGHT).sum(0)


def skate_rows(clips: dict) -> list[dict]:
    """One record per clip: both skate ratios and the grounded share."""
    rows = []
    rig = mixamo_cm_rig()
    for name, source in clips.items():
        moved = retarget(source, rig)
        contacts = foot_contacts(source.positions_with_end_sites(),
                                 resolve_roles(source.skeleton), source.fps)

        def suite(m, c=contacts):
            return float(foot_skating(m.positions_with_end_sites(), resolve_roles(m.skeleton),
                                      m.fps, c).mean_speed)

        rows.append({"clip": name, "printed_source": foot_skate(source),
                     "printed_target": foot_skate(moved),
                     "printed_ratio": foot_skate(moved) / foot_skate(source),
                     "suite_ratio": suite(moved) / suite(source),
                     "grounded_share": float(np.min(_grounded(moved) / _grounded(source)))})
    return rows


def speed_row(rounds: int) -> dict:
    """CPU ms per input frame of the whole-clip transfer, Bandai rig against the other rig."""
    torch.set_num_threads(1)
    load_default_index(progress=True)
    db = MARDatabase.load(default_index_path())
    search = PointCloudSearch(db)
    motion = _real("bandai-namco-1", "dataset-1_walk_normal_001")
    other = retarget(motion, mixamo_cm_rig())

    def cpu_ms(m) -> float:
        start = time.process_time()
        transfer_motion(m, db, STYLE, search=search)
        return 1000.0 * (time.process_time() - start) / m.num_frames

    bandai, mixamo = [], []
    with threadpool_limits(1):
        for _ in range(rounds):
            bandai.append(cpu_ms(motion))
            mixamo.append(cpu_ms(other))
    return {"clip": "dataset-1_walk_normal_001", "frames": motion.num_frames,
            "bandai_cpu_ms": bandai, "mixamo_cm_cpu_ms": mixamo,
            "ratio_of_medians": statistics.median(mixamo) / statistics.median(bandai)}


def main() -> None:
    """Run both studies, print them and write their record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "eval_retarget.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        clips = {"generated 20 s walk": _generated(20, Path(tmp)),
                 "generated 10 s walk": _generated(10, Path(tmp)),
                 "dataset 1 walk_normal_001": _real("bandai-namco-1",
                                                    "dataset-1_walk_normal_001"),
                 "dataset 2 walk_active_001": _real("bandai-namco-2-locomotion",
                                                    "dataset-2_walk_active_001")}
        skate = skate_rows(clips)
    for r in skate:
        print(f"{r['clip']:28} printed skate {r['printed_source']:.3f} -> "
              f"{r['printed_target']:.3f} m/s ({r['printed_ratio']:.2f}x); suite measure "
              f"{r['suite_ratio']:.2f}x; grounded frames kept >= {r['grounded_share']:.0%}")
    speed = speed_row(args.rounds)
    print(f"MAR whole clip, CPU ms/frame: Bandai {[round(x, 1) for x in speed['bandai_cpu_ms']]}"
          f", Mixamo cm rig {[round(x, 1) for x in speed['mixamo_cm_cpu_ms']]}; ratio of "
          f"medians {speed['ratio_of_medians']:.2f}")
    write_record(args.out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                            "machine": machine_info(), "skate": skate, "mar_speed": speed})


if __name__ == "__main__":
    main()
