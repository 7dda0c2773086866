"""How many navigating agents ``emotive serve --scene`` steps at 30 fps, and what a frame costs.

A large open scene (``--size`` metres square, four obstacles, ``--agents`` wanderers of mixed
emotions) is loaded as the server loads it (:func:`~emotive.serve.crowd_engine.load_crowd_engine`)
and stepped directly for ``--frames`` frames after ``--warmup`` (the first spawns every agent:
one warm-up of the gait network and a route each), each frame also encoded as a version-2
frame, as the server does for its clients. Printed per frame, in wall time and in the
processor time of the stepping thread (which other programs on a busy machine do not
inflate): the median and p99, the share within a 30 fps period (33.3 ms), and the median of
each part:

* ``steer``: each agent's goal moved on and its route's next corner from JuPedSim's
  ``RoutingEngine`` (:meth:`Crowd._steer`), one call per agent, less ``sidestep``: who
  gives way or overtakes (:meth:`Crowd._sidestep`, a neighbour query per agent);
* ``nav_readd``: the tie-back, every navigation agent removed and added again where its
  body stands (:meth:`Navigation._resync`), less its removal iteration;
* ``jps_iterate``: JuPedSim's iterations of the frame, and ``jps_remove`` the one iteration
  that applies the removals;
* ``body_path``: each body's straight path towards its plan (:meth:`Crowd._body_path`);
* ``set_path``: :meth:`GaitGenerator.set_paths`, the bodies whose path changed (their count
  in ``paths_set_per_frame``);
* ``gait_step``: :meth:`GaitGenerator.step` (the network, all agents batched);
* ``encode``: the version-2 frame (:func:`~emotive.serve.frames.encode_frame`);
* ``other``: the rest of the crowd's step (parameters from emotions, bookkeeping).

Then a 1 m obstacle is added where no body stands and the rebuild timed (``add_obstacle``).

``--server SECONDS`` then runs the real server on the same scene for that many wall seconds
with one client reading every frame, and prints its own counters (``/api/stats``: frames,
late frames, tick p50/p99). The machine's load average is printed before and after.

Run: ``python -m bench.bench_serve_crowd [--agents 2000 500 100] [--frames 30] [--server 60]``.
"""

from __future__ import annotations

import argparse
import asyncio
import inspect
import json
import os
import statistics
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import jupedsim
import numpy as np
import websockets

from emotive.crowd.crowd import Crowd
from emotive.crowd.navigation import SUBSTEPS, Navigation
from emotive.errors import EmotiveError
from emotive.models.gait.generate import GaitGenerator
from emotive.serve.crowd_engine import load_crowd_engine
from emotive.serve.frames import Frame, encode_frame
from emotive.serve.testing import running_server

#: The frame period at 30 fps, seconds.
PERIOD = 1.0 / 30.0
#: The parts of a frame, in the order printed.
PARTS = ("steer", "sidestep", "nav_readd", "jps_remove", "jps_iterate", "body_path",
         "set_path", "gait_step", "encode", "other")
#: Parts timed inside another, taken out of it: ``{inner: outer}``.
NESTED = {"sidestep": "steer", "jps_remove": "nav_readd"}


def scene_text(size: float, agents: int) -> str:
    """A ``size`` m square with four 6 m x 6 m obstacles and ``agents`` wanderers.

    The wanderers spawn in the middle band (35-65 % of the side, clear of the obstacles) and
    spread over the whole area as they walk to random points.
    """
    s = float(size)
    blocks = [(0.25 * s, 0.25 * s), (0.75 * s, 0.25 * s), (0.25 * s, 0.75 * s),
              (0.75 * s, 0.75 * s)]
    obstacles = "".join(
        f"\n[[area.obstacles]]\npolygon = [[{x - 3}, {y - 3}], [{x + 3}, {y - 3}], "
        f"[{x + 3}, {y + 3}], [{x - 3}, {y + 3}]]\n" for x, y in blocks)
    return (f"[area]\npolygon = [[0, 0], [{s}, 0], [{s}, {s}], [0, {s}]]\n{obstacles}\n"
            f"[[groups]]\nname = \"wanderers\"\nspawn = [[1, {0.35 * s}], [{s - 1}, {0.35 * s}], "
            f"[{s - 1}, {0.65 * s}], [1, {0.65 * s}]]\ncount = {agents}\ngoal = \"wander\"\n"
            "emotion = { choices = [\"happy\", \"neutral\", \"angry\", \"sad\"] }\n")


def load_average() -> list[float]:
    """The machine's load average over 1, 5 and 15 minutes."""
    return [round(v, 2) for v in os.getloadavg()]


class Split:
    """Wall and processor seconds spent in wrapped methods, per frame."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = defaultdict(float)
        self.cpu: dict[str, float] = defaultdict(float)
        self.count: dict[str, int] = defaultdict(int)

    def clear(self) -> None:
        """Start a new frame."""
        self.wall.clear()
        self.cpu.clear()
        self.count.clear()

    def wrap(self, owner: Any, name: str, part: Callable[[tuple], str],
             count: Callable[[tuple], int] = lambda args: 1) -> None:
        """Time ``owner.name`` (a class attribute) into the part ``part(args)`` names."""
        static = isinstance(inspect.getattr_static(owner, name), staticmethod)
        original = getattr(owner, name)

        def timed(*args: Any, **kwargs: Any) -> Any:
            wall, cpu = time.perf_counter(), time.thread_time()
            try:
                return original(*args, **kwargs)
            finally:
                at = part(args)
                self.wall[at] += time.perf_counter() - wall
                self.cpu[at] += time.thread_time() - cpu
                self.count[at] += count(args)

        setattr(owner, name, staticmethod(timed) if static else timed)


SPLIT = Split()
SPLIT.wrap(Crowd, "_steer", lambda a: "steer")
SPLIT.wrap(Crowd, "_sidestep", lambda a: "sidestep")
SPLIT.wrap(Crowd, "_body_path", lambda a: "body_path")
SPLIT.wrap(Navigation, "_resync", lambda a: "nav_readd")
SPLIT.wrap(jupedsim.Simulation, "iterate",
           lambda a: "jps_iterate" if (a[1] if len(a) > 1 else 1) == SUBSTEPS else "jps_remove")
SPLIT.wrap(GaitGenerator, "set_paths", lambda a: "set_path", lambda a: len(a[1]))
SPLIT.wrap(GaitGenerator, "step", lambda a: "gait_step")


def _parts(seconds: dict[str, float], total: float) -> dict[str, float]:
    row = dict(seconds)
    for inner, outer in NESTED.items():
        row[outer] = row.get(outer, 0.0) - row.get(inner, 0.0)
    row["other"] = total - sum(v for n, v in row.items() if n != "other")
    return row


def _ms(rows: list[dict[str, float]]) -> dict[str, float]:
    return {p: round(1000 * statistics.median(r.get(p, 0.0) for r in rows), 1) for p in PARTS}


def engine_run(path: Path, frames: int, warmup: int) -> dict[str, Any]:
    """Step the server's crowd engine directly; the frame times and their split."""
    engine = load_crowd_engine(path, seed=0)
    walls, cpus, wall_parts, cpu_parts, agents, paths = [], [], [], [], [], []
    for k in range(warmup + frames):
        SPLIT.clear()
        wall, cpu = time.perf_counter(), time.thread_time()
        frame = engine.step(full=False)
        data = Frame(k, k * PERIOD, np.asarray(frame.agents, dtype=np.int32),
                     np.zeros((len(frame.agents), 2)), frame.emotion,
                     frame.positions[:, engine.mover], frame.rotations)
        t, c = time.perf_counter(), time.thread_time()
        encode_frame(data, 2)
        SPLIT.wall["encode"] += time.perf_counter() - t
        SPLIT.cpu["encode"] += time.thread_time() - c
        wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
        if k < warmup:
            continue
        walls.append(wall)
        cpus.append(cpu)
        wall_parts.append(_parts(SPLIT.wall, wall))
        cpu_parts.append(_parts(SPLIT.cpu, cpu))
        agents.append(len(frame.agents))
        paths.append(SPLIT.count["set_path"])
    rebuild = obstacle_seconds(engine)
    cpu_median = statistics.median(cpus)
    return {
        "agents": int(np.median(agents)), "frames": len(walls),
        "frame_ms": {"p50": round(1000 * statistics.median(walls), 1),
                     "p99": round(1000 * float(np.percentile(walls, 99)), 1)},
        "frame_cpu_ms": {"p50": round(1000 * cpu_median, 1),
                         "p99": round(1000 * float(np.percentile(cpus, 99)), 1)},
        "within_period": round(float(np.mean(np.array(walls) <= PERIOD)), 3),
        "cpu_within_period": round(float(np.mean(np.array(cpus) <= PERIOD)), 3),
        "paths_set_per_frame": int(np.median(paths)),
        "split_ms": _ms(wall_parts),
        "split_cpu_ms": _ms(cpu_parts),
        "obstacle_rebuild_ms": None if rebuild is None else round(1000 * rebuild, 1),
    }


def obstacle_seconds(engine: Any) -> float | None:
    """Seconds to add a 1 m obstacle (the navigation rebuilt) where no body stands."""
    b = engine.crowd.walkable.bounds
    rng = np.random.default_rng(0)
    for _ in range(50):
        x, z = rng.uniform(b[0] + 2, b[2] - 2), rng.uniform(b[1] + 2, b[3] - 2)
        corners = np.array([[x, z], [x + 1, z], [x + 1, z + 1], [x, z + 1]])
        start = time.perf_counter()
        try:
            engine.add_obstacle(corners)
        except EmotiveError:
            continue
        return time.perf_counter() - start
    return None


def server_run(path: Path, seconds: float) -> dict[str, Any]:
    """The real server on the scene for ``seconds`` wall seconds, one client reading."""
    with running_server(scene=str(path), max_agents=10) as base:
        first = httpx.get(f"{base}/api/stats", timeout=120).json()

        async def read() -> int:
            frames = 0
            deadline = time.monotonic() + seconds
            async with websockets.connect(base.replace("http", "ws", 1) + "/ws",
                                          max_size=None) as ws:
                while (left := deadline - time.monotonic()) > 0:
                    try:
                        message = await asyncio.wait_for(ws.recv(), left)
                    except TimeoutError:
                        break
                    frames += isinstance(message, bytes)
            return frames

        received = asyncio.run(read())
        stats = httpx.get(f"{base}/api/stats", timeout=120).json()
    frames = stats["frames"] - first["frames"]
    late = stats["late_frames"] - first["late_frames"]
    return {"seconds": seconds, "agents": stats["agents"], "frames": frames,
            "frames_per_second": round(frames / seconds, 2), "late_frames": late,
            "on_time": round(1 - late / max(frames, 1), 3), "client_frames": received,
            "tick_ms": stats["step_ms"], "tick_parts_ms": stats["tick_ms"]}


def main() -> None:
    """Run the measurement (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, nargs="+", default=[2000],
                        help="agent counts to step (the server runs the first)")
    parser.add_argument("--size", type=float, default=100.0, help="side of the area, m")
    parser.add_argument("--frames", type=int, default=30, help="frames timed")
    parser.add_argument("--warmup", type=int, default=3, help="frames stepped first, untimed")
    parser.add_argument("--server", type=float, default=0.0,
                        help="also run the server this many wall seconds (0: not)")
    parser.add_argument("--out", type=Path, help="write the results as JSON here")
    args = parser.parse_args()
    out: dict[str, Any] = {"load_average_before": load_average(), "cpus": os.cpu_count()}
    out["engine"] = []
    with tempfile.TemporaryDirectory() as tmp:
        for count in args.agents:
            path = Path(tmp) / f"open-{count}.toml"
            path.write_text(scene_text(args.size, count), encoding="utf-8")
            out["engine"].append(engine_run(path, args.frames, args.warmup))
            print(json.dumps(out["engine"][-1]), flush=True)
        if args.server > 0:
            path = Path(tmp) / f"open-{args.agents[0]}.toml"
            out["server"] = server_run(path, args.server)
            print(json.dumps(out["server"]), flush=True)
    out["load_average_after"] = load_average()
    print("load average before/after:", out["load_average_before"], out["load_average_after"])
    if args.out:
        args.out.write_text(json.dumps(out, indent=1), encoding="utf-8")


if __name__ == "__main__":
    main()
