"""Measure a written crowd run from its files: the BVH hips, not the navigation's positions.

Reads the folder ``emotive crowd`` wrote (``agent-NNNN.bvh``, ``agents.csv``,
``navigation.csv``, ``scene.json``), takes every body's hip joint (the rig's ``root`` role)
from the BVH files by forward kinematics, places each file at its first frame
(``agents.csv``), and reports:

* ``min_hip_distance``: the smallest distance between two hips on the ground at one frame (m);
* ``close_pairs`` / ``close_pair_frames``: agent pairs (and pair-frames) with hips closer than
  :data:`CLOSE`;
* ``hips_in_obstacles``: hip samples more than :data:`INSIDE_TOLERANCE` inside an obstacle or
  outside the area;
* ``goal_share``: the share of agents that met their goal (exits: the last hip inside the exit
  polygon; waypoints and wanderers: as the run recorded);
* ``tie_p99``: the 99th percentile of the distance between a body's hips and its navigation
  agent at the same frame (m);
* ``per_emotion``: per dominant emotion, the agents, their mean walking speed (m/s, frames
  where the hips move), their mean distance to the nearest other hip (m) and their foot
  skate (m/s, :func:`emotive.eval.feet.foot_skating`, the evaluation suite's measure, over
  every agent's whole BVH);
* ``stood_free``: agents that stood (hips under :data:`WALKING` over one second) for more
  than :data:`STAND_LIMIT` seconds in a row while no other hip was within :data:`FREE_WAY`
  of theirs, before they met their goal (their way was free, yet they stood), and
  ``longest_free_stand``, the longest such stand (s).

Run as ``python -m emotive.crowd.measure OUT_DIR [OUT_DIR_NO_AVOIDANCE]``: prints JSON; with a
second folder (the same scene and seed run with ``--no-avoidance``) it adds the close pairs
avoidance saves and, per emotion, the foot skate of the crowd over that of the same agents
walking without avoidance (each on its own line, as if alone: ``skate_ratio``).
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import Polygon

from emotive.core.roles import resolve_roles
from emotive.crowd.goals import ARRIVAL_RADIUS
from emotive.eval.feet import foot_skating
from emotive.io.bvh import read_bvh
from emotive.transforms.kinematics import forward_kinematics_np

__all__ = ["CLOSE", "INSIDE_TOLERANCE", "hip_tracks", "measure_run"]

#: Hips closer than this (m) make a close pair.
CLOSE = 0.3
#: Depth (m) inside an obstacle that counts as walking into it.
INSIDE_TOLERANCE = 0.05
#: Hip speed (m/s) above which a frame counts as walking.
WALKING = 0.1
#: Longest stand (s) allowed while the way is free.
STAND_LIMIT = 5.0
#: No other hip within this distance (m): the way is free.
FREE_WAY = 1.0


def hip_tracks(folder: Path, skate: dict[int, float] | None = None,
               ) -> tuple[dict[int, tuple[int, np.ndarray]], float, list[dict]]:
    """Every agent's first frame and hip ground track ``(T, 2)`` from the BVH files.

    Args:
        folder: the run folder.
        skate: filled with each agent's foot skate (m/s) when given.

    Returns:
        ``{id: (first frame, (T, 2) hips x, y)}``, the frame rate and the ``agents.csv`` rows.
    """
    with open(folder / "agents.csv", encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    tracks, fps, hip, roles = {}, 0.0, None, None
    for row in rows:
        motion = read_bvh(folder / row["file"])
        if roles is None:
            roles = resolve_roles(motion.skeleton)
            hip = int(roles.indices(("root",))[0])
        _, world = forward_kinematics_np(motion.rotations, motion.positions,
                                         motion.skeleton.parents)
        tracks[int(row["id"])] = (int(row["first_frame"]), world[:, hip][:, [0, 2]])
        fps = motion.fps
        if skate is not None and motion.num_frames > 1:
            skate[int(row["id"])] = float(foot_skating(motion.positions_with_end_sites(), roles,
                                                       fps).mean_speed)
    return tracks, fps, rows


def _free_stands(tracks: dict[int, tuple[int, np.ndarray]], fps: float,
                 free: dict[int, np.ndarray], ends: dict[int, int]) -> dict[int, float]:
    """Per agent, its longest stand (s) while its way was free, before frame ``ends[a]``.

    Args:
        tracks: as :func:`hip_tracks`.
        fps: frame rate.
        free: ``(T,)`` per agent, whether no other hip was within :data:`FREE_WAY`.
        ends: per agent, the frame (of its own track) from which it has met its goal.
    """
    window = max(round(fps), 1)
    out = {}
    for a, (_, xy) in tracks.items():
        n = min(len(xy), ends.get(a, len(xy)))
        if n <= window:
            continue
        moved = np.hypot(*(xy[window:n] - xy[:n - window]).T) * fps / window
        stand = (moved < WALKING) & free[a][:n - window]
        run = longest = 0
        for s in stand:
            run = run + 1 if s else 0
            longest = max(longest, run)
        out[a] = (longest + window) / fps if longest else 0.0
    return out


def _per_frame(tracks: dict[int, tuple[int, np.ndarray]]) -> dict[int, tuple[list, np.ndarray]]:
    frames: dict[int, tuple[list, list]] = {}
    for a, (first, xy) in tracks.items():
        for k, p in enumerate(xy):
            ids, pts = frames.setdefault(first + k, ([], []))
            ids.append(a)
            pts.append(p)
    return {f: (ids, np.asarray(pts)) for f, (ids, pts) in frames.items()}


def _navigation(folder: Path) -> dict[tuple[int, int], np.ndarray]:
    out = {}
    with open(folder / "navigation.csv", encoding="utf-8") as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            a, fr, x, y = line.split()
            out[(int(a), int(fr))] = np.array([float(x), float(y)])
    return out


def measure_run(folder: str | Path) -> dict[str, Any]:
    """The measures of one written run (see the module docstring)."""
    folder = Path(folder)
    skate: dict[int, float] = {}
    tracks, fps, rows = hip_tracks(folder, skate)
    scene = json.loads((folder / "scene.json").read_text(encoding="utf-8"))
    area = Polygon(scene["area"]["polygon"])
    obstacles = [Polygon(o["polygon"]) for o in scene["area"]["obstacles"]]
    groups = {g["name"]: g for g in scene["groups"]}
    min_d, pairs, pair_frames = np.inf, set(), 0
    nearest: dict[int, list[float]] = {a: [] for a in tracks}
    free = {a: np.ones(len(xy), dtype=bool) for a, (_, xy) in tracks.items()}
    for frame, (ids, pts) in _per_frame(tracks).items():
        if len(pts) < 2:
            continue
        tree = cKDTree(pts)
        d, _ = tree.query(pts, k=2)
        min_d = min(min_d, float(d[:, 1].min()))
        for a, dd in zip(ids, d[:, 1], strict=True):
            nearest[a].append(float(dd))
            free[a][frame - tracks[a][0]] = dd > FREE_WAY
        for i, k in tree.query_pairs(CLOSE):
            pairs.add((min(ids[i], ids[k]), max(ids[i], ids[k])))
            pair_frames += 1
    inside = 0
    walls = area.boundary
    for _, xy in tracks.values():
        pts = shapely.points(xy)
        out_area = ~shapely.contains(area, pts) & (shapely.distance(walls, pts)
                                                   > INSIDE_TOLERANCE)
        inside += int(out_area.sum())
        for o in obstacles:
            deep = shapely.contains(o, pts) & (shapely.distance(o.boundary, pts)
                                               > INSIDE_TOLERANCE)
            inside += int(deep.sum())
    reached, per, ends = 0, {}, {}
    for row in rows:
        a = int(row["id"])
        _, xy = tracks[a]
        goal = groups.get(row["group"], {}).get("goal")
        if isinstance(goal, list):
            ok = bool(shapely.contains_xy(Polygon(goal), *xy[-1]))
        else:
            ok = row["reached"] == "1"
        reached += ok
        if ok and isinstance(goal, dict) and goal.get("waypoints"):
            last = np.asarray(goal["waypoints"][-1], dtype=np.float64)
            at = np.flatnonzero(np.hypot(*(xy - last).T) <= ARRIVAL_RADIUS)
            ends[a] = int(at[0]) if len(at) else len(xy)
        speed = np.hypot(*np.diff(xy, axis=0).T) * fps
        walking = speed[speed > WALKING]
        e = per.setdefault(row["label"], {"agents": 0, "speed": [], "nearest": [], "skate": []})
        e["agents"] += 1
        e["speed"].extend(walking.tolist())
        e["nearest"].extend(nearest[a])
        if a in skate:
            e["skate"].append(skate[a])
    stands = _free_stands(tracks, fps, free, ends)
    nav = _navigation(folder)
    gaps = [float(np.hypot(*(xy[k] - nav[(a, first + k)])))
            for a, (first, xy) in tracks.items() for k in range(len(xy))
            if (a, first + k) in nav]
    return {
        "agents": len(tracks), "frames": max((f + len(x) for f, x in tracks.values()),
                                             default=0), "fps": fps,
        "min_hip_distance": float(min_d), "close_pairs": len(pairs),
        "close_pair_frames": pair_frames, "hips_in_obstacles": inside,
        "goal_share": reached / max(len(rows), 1),
        "tie_p99": float(np.percentile(gaps, 99)) if gaps else 0.0,
        "tie_max": float(max(gaps)) if gaps else 0.0,
        "stood_free": sum(1 for t in stands.values() if t > STAND_LIMIT),
        "longest_free_stand": max(stands.values(), default=0.0),
        "per_emotion": {k: {"agents": v["agents"],
                            "mean_speed": float(np.mean(v["speed"])) if v["speed"] else 0.0,
                            "mean_nearest": float(np.mean(v["nearest"])) if v["nearest"]
                            else 0.0,
                            "foot_skate": float(np.mean(v["skate"])) if v["skate"] else 0.0}
                        for k, v in sorted(per.items())},
    }


def main(argv: list[str] | None = None) -> None:
    """Print the measures of a run folder (and the close pairs saved against a second)."""
    args = sys.argv[1:] if argv is None else argv
    if not args or len(args) > 2:
        print("usage: python -m emotive.crowd.measure OUT_DIR [OUT_DIR_NO_AVOIDANCE]",
              file=sys.stderr)
        raise SystemExit(2)
    result = measure_run(args[0])
    if len(args) == 2:
        base = measure_run(args[1])
        result["without_avoidance"] = {k: base[k] for k in (
            "min_hip_distance", "close_pairs", "close_pair_frames", "goal_share")}
        result["close_pairs_saved"] = base["close_pairs"] - result["close_pairs"]
        for label, row in result["per_emotion"].items():
            alone = base["per_emotion"].get(label, {}).get("foot_skate", 0.0)
            row["skate_alone"] = alone
            row["skate_ratio"] = row["foot_skate"] / alone if alone > 0 else float("nan")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
