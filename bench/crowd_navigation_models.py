"""Which JuPedSim operational model suits the crowd: collision-free speed V2 or anticipation.

Runs one small two-way corridor (7 m x 3 m, ``--count`` agents each way, mixed emotions) with
each model under the same tie-back (every navigation agent re-added where its body stands,
each frame) and prints, per model: the smallest hip-to-hip distance (m), how many agents
reached their exit, the frame the last one left, and the p99 distance between body and
navigation agent (m). Run: ``python -m bench.crowd_navigation_models [--count 4]``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.distance import pdist

from emotive.crowd.crowd import Crowd
from emotive.crowd.scene import load_scene
from emotive.models.gait.model import load_gait_model

SCENE = """
[area]
polygon = [[0, 0], [7, 0], [7, 3], [0, 3]]

[[groups]]
name = "east"
spawn = [[0, 0], [1.6, 0], [1.6, 3], [0, 3]]
count = {count}
goal = [[6, 0], [7, 0], [7, 3], [6, 3]]
emotion = {{ choices = ["happy", "angry", "neutral", "sad"] }}

[[groups]]
name = "west"
spawn = [[5.4, 0], [7, 0], [7, 3], [5.4, 3]]
count = {count}
goal = [[0, 0], [1, 0], [1, 3], [0, 3]]
emotion = {{ choices = ["happy", "angry", "neutral", "sad"] }}
"""


def run(model_name: str, count: int, frames: int, seed: int) -> dict:
    """One run of the corridor with JuPedSim's ``model_name`` (``cfs`` or ``avm``)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "corridor.toml"
        path.write_text(SCENE.format(count=count), encoding="utf-8")
        scene = load_scene(path)
    crowd = Crowd(scene, model=MODEL, seed=seed, navigation=model_name)
    mover = crowd.gait.graph.mover
    closest, tie, last = np.inf, [], None
    for f in range(frames):
        frame = crowd.step()
        if len(frame.agents) > 1:
            closest = min(closest, float(pdist(frame.positions[:, mover][:, [0, 2]]).min()))
        tie.extend(np.hypot(*(frame.root - frame.navigation).T).tolist())
        if not crowd.agents:
            last = f
            break
    reached = crowd.goal_reached()
    return {"model": model_name, "min_hip_distance": round(closest, 3),
            "reached": f"{sum(reached.values())}/{len(reached)}", "all_left_at_frame": last,
            "tie_p99": round(float(np.percentile(tie, 99)), 3)}


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=4)
    parser.add_argument("--frames", type=int, default=900)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    args = parser.parse_args()
    MODEL = load_gait_model()
    for seed in args.seeds:
        for name in ("cfs", "avm"):
            print(json.dumps({"seed": seed, **run(name, args.count, args.frames, seed)}),
                  flush=True)
