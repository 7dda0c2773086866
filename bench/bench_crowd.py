"""Crowds with navigation: the time of one :meth:`Crowd.step` at 500, 1,000 and 2,000 agents.

Scene: the plaza of ``examples/scenes/plaza.toml`` (an open square, four obstacles, three
groups wandering between random points with mixed emotions and paces) scaled so that every
agent count has the plaza's 4 m² per agent (:func:`plaza`), built in code.

Per agent count, in one run on one torch thread: the crowd with navigation (JuPedSim, the
collision-free speed model, avoidance on); the same scene and seed without it
(``avoidance=False``: each navigation agent walks straight at its target, no JuPedSim
iteration, no re-adding); and the crowd's own :class:`GaitGenerator` stepped bare (the same
agents, no navigation and no new paths). After ``warmup`` frames (the first spawns every
agent and warms the network) the three take turns frame by frame for ``frames`` frames, so a
change of the machine's load falls on all alike; the median of each is kept, in wall time
and in this process's CPU time. Rows: agent-frames per second (wall) with navigation against
each of the two, each row with every side's milliseconds per frame and the load average
around it (the development machine is shared: read the ratios more than the numbers).

``--profile N`` instead prints where the time of a frame with navigation goes at ``N``
agents (cProfile): JuPedSim's iterations, re-adding the navigation agents, the gait step,
:meth:`GaitGenerator.set_paths`, steering (goals and routes), making the bodies' paths, the
rest, and how much of all that Python's garbage collector took.

Run ``python -m bench.bench_crowd [--agents 500 1000 2000] [--frames 60] [--quick]
[--profile 2000] [--out bench/results/crowd.json]``; ``make bench`` runs it as ``crowd_nav``.
"""

from __future__ import annotations

import argparse
import cProfile
import gc
import math
import os
import pstats
import statistics
import time
from pathlib import Path

from bench.common import comparison, machine_info, pinned_threads, write_record
from emotive.crowd.crowd import Crowd
from emotive.crowd.scene import Scene, parse_scene
from emotive.models.gait.model import GaitModel
from emotive.models.registry import get_model

#: Agent counts of the rows.
AGENTS = (500, 1000, 2000)
#: Timed frames per side and row (2 s of scene time), and untimed frames before them.
FRAMES, WARMUP = 60, 5
#: Agents the plaza of ``examples/scenes/plaza.toml`` holds at its size (40 m x 30 m).
PLAZA_AGENTS = 300
#: The plaza at its own size: area, obstacles, and each group's spawn, emotions and pace.
_AREA = [[0, 0], [40, 0], [40, 30], [0, 30]]
_OBSTACLES = (
    [[18, 13], [19.2, 12.5], [20.8, 12.5], [22, 13], [22.5, 15], [22, 17], [20.8, 17.5],
     [19.2, 17.5], [18, 17], [17.5, 15]],                    # fountain
    [[6, 6], [9, 6], [9, 9], [6, 9]],                        # kiosk west
    [[31, 21], [34, 21], [34, 24], [31, 24]],                # kiosk east
    [[8, 22], [16, 22], [16, 22.8], [8, 22.8]],              # bench row
)
_GROUPS = (
    ("strollers", [[1, 1], [39, 1], [39, 5], [1, 5]],
     {"choices": ["happy", "neutral", "happy=0.5,neutral=0.5"]}, [0.8, 1.1]),
    ("hurried", [[1, 25], [39, 25], [39, 29], [1, 29]],
     {"choices": ["angry", "neutral", "angry=0.5,neutral=0.5"], "weights": [2, 1, 1]},
     [1.0, 1.0]),
    ("downcast", [[1, 11.5], [16, 11.5], [16, 18.5], [1, 18.5]],
     {"choices": ["sad", "neutral", "sad=0.6,happy=0.4"]}, [1.0, 1.0]),
)


def plaza(agents: int) -> Scene:
    """The plaza scaled to hold ``agents`` wandering agents at its own density."""
    scale = math.sqrt(agents / PLAZA_AGENTS)

    def scaled(ring: list) -> list:
        return [[scale * x, scale * y] for x, y in ring]

    counts = [agents // 3, agents // 3, agents - 2 * (agents // 3)]
    return parse_scene({
        "name": f"plaza-{agents}",
        "area": {"polygon": scaled(_AREA),
                 "obstacles": [{"polygon": scaled(o)} for o in _OBSTACLES]},
        "groups": [{"name": name, "spawn": scaled(spawn), "count": count, "goal": "wander",
                    "emotion": emotion, "pace": pace}
                   for (name, spawn, emotion, pace), count in zip(_GROUPS, counts, strict=True)],
    })


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def _crowd(model: GaitModel, agents: int, avoidance: bool, warmup: int) -> Crowd:
    crowd = Crowd(plaza(agents), model=model, seed=0, avoidance=avoidance)
    for _ in range(warmup):
        crowd.step()
    if len(crowd.agents) != agents:
        raise RuntimeError(f"the plaza spawned {len(crowd.agents)} agents, not {agents}")
    return crowd


def measure(model: GaitModel, agents: int, frames: int = FRAMES, warmup: int = WARMUP
            ) -> dict[str, float]:
    """Median ms per frame of the three sides at ``agents`` agents (see the module docstring).

    The sides take turns frame by frame (with navigation, without, the bare gait), so a
    change of the machine's load falls on all three alike. Wall time (``*_ms``) and this
    process's CPU time (``*_cpu_ms``, less sensitive to other jobs) are both kept.
    """
    load = _load()
    sides = {"navigation": _crowd(model, agents, True, warmup).step,
             "no_avoidance": _crowd(model, agents, False, warmup).step,
             "gait": _crowd(model, agents, False, warmup).gait.step}
    wall: dict[str, list[float]] = {k: [] for k in sides}
    cpu: dict[str, list[float]] = {k: [] for k in sides}
    for _ in range(frames):
        for name, step in sides.items():
            w, c = time.perf_counter(), time.process_time()
            step()
            wall[name].append(time.perf_counter() - w)
            cpu[name].append(time.process_time() - c)
    out = {f"{k}_ms": 1e3 * statistics.median(v) for k, v in wall.items()}
    out |= {f"{k}_cpu_ms": 1e3 * statistics.median(v) for k, v in cpu.items()}
    return {**out, "load_before": load, "load_after": _load()}


def run(model: GaitModel | None = None, agents: tuple[int, ...] = AGENTS,
        frames: int = FRAMES, warmup: int = WARMUP) -> list[dict]:
    """The rows of the module docstring, two per agent count."""
    model = model or get_model("gait").load("generator").model
    rows = []
    with pinned_threads(1):
        for n in agents:
            m = measure(model, n, frames, warmup)
            rate = {k: n * 1e3 / m[k] for k in ("navigation_ms", "no_avoidance_ms", "gait_ms")}
            extra = {**m, "agents": n, "frames": frames, "agent_frames_per_s": rate}
            label = f"{n} agents, plaza, 1 thread"
            rows.append({**comparison(
                f"crowd_nav[{label}]", "agent-frames/s", rate["navigation_ms"],
                rate["no_avoidance_ms"], "the same crowd without navigation (avoidance=False)"),
                **extra})
            rows.append({**comparison(
                f"crowd_nav[{label}]", "agent-frames/s", rate["navigation_ms"],
                rate["gait_ms"], "the same agents' GaitGenerator stepped bare"), **extra})
            print(f"  {n} agents, ms/frame wall (CPU): with navigation "
                  f"{m['navigation_ms']:.0f} ({m['navigation_cpu_ms']:.0f}), without "
                  f"{m['no_avoidance_ms']:.0f} ({m['no_avoidance_cpu_ms']:.0f}), bare gait "
                  f"{m['gait_ms']:.0f} ({m['gait_cpu_ms']:.0f}); load {m['load_before']} -> "
                  f"{m['load_after']}", flush=True)
    return rows


def _cumulative(stats: pstats.Stats, name: str, file_part: str, caller: str = "") -> float:
    """Cumulative seconds of function ``name`` of a file whose path holds ``file_part``.

    With ``caller``: only the time of its calls from functions of that name.
    """
    total = 0.0
    for (path, _, func), (_, _, _, ct, callers) in stats.stats.items():
        if func != name or file_part not in path:
            continue
        if not caller:
            total += ct
            continue
        total += sum(v[3] for (_, _, f), v in callers.items() if f == caller)
    return total


class _Collections:
    """A :data:`gc.callbacks` entry adding up the time of the collector's runs."""

    def __init__(self) -> None:
        self.seconds, self.full, self._start = 0.0, 0, 0.0

    def __call__(self, phase: str, info: dict) -> None:
        if phase == "start":
            self._start = time.perf_counter()
            return
        self.seconds += time.perf_counter() - self._start
        self.full += info["generation"] == 2


def profile(agents: int, frames: int = 10, warmup: int = WARMUP) -> dict[str, float]:
    """Milliseconds per frame with navigation at ``agents`` agents, split (cProfile)."""
    model = get_model("gait").load("generator").model
    with pinned_threads(1):
        crowd = _crowd(model, agents, True, warmup)
        prof = cProfile.Profile()
        collections = _Collections()
        gc.callbacks.append(collections)
        start = time.perf_counter()
        prof.enable()
        try:
            for _ in range(frames):
                crowd.step()
        finally:
            prof.disable()
            gc.callbacks.remove(collections)
        wall = time.perf_counter() - start
    stats = pstats.Stats(prof)
    iterate = _cumulative(stats, "iterate", "jupedsim")
    parts = {
        "JuPedSim iterate": iterate,
        "Navigation._resync re-adding (its iterate excluded)":
            _cumulative(stats, "_resync", "navigation")
            - _cumulative(stats, "iterate", "jupedsim", caller="_resync"),
        "GaitGenerator.step": _cumulative(stats, "step", "generate.py"),
        "GaitGenerator.set_paths": _cumulative(stats, "set_paths", "generate.py"),
        "Crowd._steer (goals, routes, targets)": _cumulative(stats, "_steer", "crowd.py"),
        "Crowd._body_path (the new paths, GroundPath made)":
            _cumulative(stats, "_body_path", "crowd.py"),
    }
    total = _cumulative(stats, "step", "crowd.py")
    parts["the rest of Crowd.step"] = total - sum(parts.values())
    print(f"{agents} agents, {frames} frames with navigation, 1 thread, load {_load()}: "
          f"{1e3 * total / frames:.0f} ms/frame under cProfile "
          f"({1e3 * wall / frames:.0f} ms wall)")
    for name, seconds in parts.items():
        print(f"  {name:55} {1e3 * seconds / frames:8.1f} ms  {100 * seconds / total:5.1f} %")
    print(f"  {'of all these, Python garbage collection':55} "
          f"{1e3 * collections.seconds / frames:8.1f} ms  "
          f"{100 * collections.seconds / total:5.1f} % ({collections.full} full collections)")
    stats.sort_stats("cumulative").print_stats(25)
    return {name: 1e3 * s / frames for name, s in parts.items()}


def main() -> None:
    """Run the rows (or ``--profile``) from the command line and write their record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, nargs="+", default=list(AGENTS))
    parser.add_argument("--frames", type=int, default=FRAMES)
    parser.add_argument("--quick", action="store_true", help="500 agents, 10 frames")
    parser.add_argument("--profile", type=int, default=0, metavar="N",
                        help="print the split of a frame at N agents instead")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    if args.profile:
        profile(args.profile, frames=min(args.frames, 10))
        return
    agents, frames = ((500,), 10) if args.quick else (tuple(args.agents), args.frames)
    rows = run(agents=agents, frames=frames)
    out = args.out or Path(__file__).resolve().parent / "results" / \
        f"crowd-{time.strftime('%Y%m%d-%H%M%S')}.json"
    write_record(out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": machine_info(),
                       "results": rows})


if __name__ == "__main__":
    main()
