"""Feet on the floor: how low the feet go and how much they skate, generate and transfer.

Usage: ``python -m bench.feet_floor [--seconds 10] [--out bench/results/feet_floor.json]``.
Needs Bandai Namco dataset 1 (the transfer rows; the style-transfer index is built on first
use) and about a minute of one CPU core.

Rows:

* ``emotive generate`` (the registry's gait generator, what the command runs): 10 s walks
  along the default figure-8, seed 0, happy, sad, angry and neutral.
* ``emotive transfer`` (:func:`emotive.models.mar.transfer.transfer_motion`, what the command
  runs): dataset 1's ``walk_normal_001`` and ``walk_happy_001`` into
  ``proud=0.6,angry=0.4`` and ``sad``, and each input itself.

Columns (heel = ankle joint, toe = the toe role, both feet):

* ``below floor``: the deepest heel or toe under its floor height, cm. A rig's foot points
  stand above ``y = 0`` when the foot is on the floor (Bandai's ankle 11.8 cm, toe 4.5 cm),
  so each point's floor height is where it is when standing on the floor: the gait
  checkpoint's standing pose for generated walks, the input's own 5th-percentile height
  (:func:`emotive.ik.floor.clip_floor`) for transfers and inputs.
* ``below y=0``: the evaluation suite's ground penetration
  (:func:`emotive.eval.feet.ground_penetration`, the same points against ``y = 0``), cm.
* ``skate``: the evaluation suite's foot skate (:func:`emotive.eval.feet.foot_skating`,
  contacts detected on each clip: mean horizontal speed of planted feet), m/s.
* ``skate 2cm``: the measure ``emotive retarget`` prints (:func:`emotive.retarget.foot_skate`:
  every heel and toe within 2 cm of its floor, whatever it does), m/s.

The floor heights are computed here, not taken from the code under test, so that the same
script measures the code before and after a change.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import machine_info, write_record
from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.data import dataset_dir
from emotive.data.emotion import coerce_emotion
from emotive.eval.feet import foot_skating, ground_penetration
from emotive.features.contacts import FOOT_ROLES
from emotive.io.bvh import read_bvh
from emotive.models.api import GenerationRequest
from emotive.models.mar.default_index import load_default_index
from emotive.models.mar.transfer import transfer_motion
from emotive.models.registry import get_model
from emotive.retarget import foot_skate

HERE = Path(__file__).resolve().parent
EMOTIONS = ("happy", "sad", "angry", "neutral")
CLIPS = ("dataset-1_walk_normal_001", "dataset-1_walk_happy_001")
STYLES = ("proud=0.6,angry=0.4", "sad")


def feet(motion: Motion, floor: np.ndarray) -> dict:
    """The four measures of one clip (see the module docstring)."""
    points = motion.positions_with_end_sites()
    roles = resolve_roles(motion.skeleton)
    heights = points[:, roles.indices(FOOT_ROLES), 1]
    return {
        "frames": motion.num_frames,
        "below_floor_cm": 100 * float(np.maximum(floor - heights, 0.0).max()),
        "below_y0_cm": 100 * float(ground_penetration(points, roles).max),
        "lowest_cm": 100 * float(heights.min()),
        "skate": float(foot_skating(points, roles, motion.fps).mean_speed),
        "skate_2cm": float(foot_skate(motion)),
    }


def standing_floor(generator) -> np.ndarray:
    """``(4,)`` heel and toe heights of the gait checkpoint's standing pose."""
    c = generator.model.controls
    stand = Motion(c.skeleton, c.standing_rotations[None], c.standing_positions[None], c.fps)
    roles = resolve_roles(c.skeleton)
    return stand.positions_with_end_sites()[0, roles.indices(FOOT_ROLES), 1]


def generate_rows(seconds: float) -> list[dict]:
    """The gait generator's walks, one per emotion."""
    generator = get_model("gait").load("generator")
    floor = standing_floor(generator)
    rows = []
    for emotion in EMOTIONS:
        request = GenerationRequest(emotion, schedule=coerce_emotion(emotion, generator.labels),
                                    seconds=seconds, seed=0)
        motion = generator.generate(request).motion
        rows.append({"item": f"generate {emotion} {seconds:g} s", **feet(motion, floor)})
    return rows


def transfer_rows() -> list[dict]:
    """Each input clip, then its transfers."""
    db = load_default_index(progress=False)
    folder = dataset_dir("bandai-namco-1") / "data"
    rows = []
    for name in CLIPS:
        clip = read_bvh(folder / f"{name}.bvh")
        points = clip.positions_with_end_sites()
        floor = np.percentile(points[:, resolve_roles(clip.skeleton).indices(FOOT_ROLES), 1],
                              5.0, axis=0)
        short = name.removeprefix("dataset-1_")
        rows.append({"item": f"input {short}", **feet(clip, floor)})
        for style in STYLES:
            result = transfer_motion(clip, db, style)
            rows.append({"item": f"transfer {short} -> {style}", **feet(result.motion, floor)})
    return rows


def table(rows: list[dict]) -> str:
    """The rows as a Markdown table."""
    out = ["| item | frames | below floor (cm) | below y=0 (cm) | skate (m/s) | "
           "skate 2cm (m/s) |", "|---|---:|---:|---:|---:|---:|"]
    out += [f"| {r['item']} | {r['frames']} | {r['below_floor_cm']:.2f} | "
            f"{r['below_y0_cm']:.2f} | {r['skate']:.3f} | {r['skate_2cm']:.3f} |" for r in rows]
    return "\n".join(out)


def main() -> None:
    """Measure, print the table and write the JSON record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "feet_floor.json")
    args = parser.parse_args()
    torch.set_num_threads(1)
    start = time.perf_counter()
    rows = generate_rows(args.seconds) + transfer_rows()
    print(table(rows))
    print(f"{time.perf_counter() - start:.1f} s")
    write_record(args.out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                            "machine": machine_info(), "rows": rows})


if __name__ == "__main__":
    main()
