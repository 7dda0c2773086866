"""Gait generation throughput: the streaming batched generator against a window re-running one.

Ours: :class:`emotive.models.gait.generate.GaitGenerator`, every agent stepped in one batched
network call per frame with the GRU state carried. Baseline: the same network and the same
per-frame work (affective features of the new pose, the path and phase controls), but the way
the original implementation animates: for every new frame and one agent at a time, the network
runs over that agent's last :data:`WINDOW` input frames from a fresh state and only its last
output is kept.

Both run on one torch thread: a frame of even 1000 agents is a few small matrix products, which
a second thread slows down with its synchronisation (on the 2-core development machine, 10
agents stepped at 1,059 agent-frames/s on two threads against 5,575 on one), and the other core
stays free for the application.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import torch

from bench.common import (
    DEFAULT_THREADS,
    comparison,
    median_seconds,
    print_rows,
    resident_mb,
    unpinned_threads,
)
from emotive.core.roles import JointRoles, resolve_roles
from emotive.eval.feet import foot_skating
from emotive.io.bvh import read_bvh
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs
from emotive.models.registry import get_model
from emotive.paths import circle, figure8

#: Input frames the window re-running baseline feeds the network for every new frame (2 s).
WINDOW = 60
EMOTIONS = ("happy", "sad", "angry", "neutral")


def _generator(model: GaitModel, agents: int, own_paths: bool = False,
               threads: int = 1) -> GaitGenerator:
    """``agents`` agents on one shared figure-8, or each on its own circle."""
    gen = GaitGenerator(model, threads=threads)
    shared = figure8()
    # Own paths: distinct circles of 1.5-2.5 m radius (a room-sized crowd), one object each.
    paths = [circle(1.5 + 0.001 * (k % 1000)) if own_paths else shared for k in range(agents)]
    gen.add_agents(paths, [EMOTIONS[k % len(EMOTIONS)] for k in range(agents)],
                   starts=[0.37 * k for k in range(agents)])
    for _ in range(3):
        gen.step()
    return gen


def _rate(gen: GaitGenerator, steps: int) -> float:
    """Median agent-frames per second of ``steps`` steps."""
    seconds = median_seconds(lambda: [gen.step() for _ in range(steps)], repeats=3)
    return len(gen) * steps / seconds


def crowd_rows(model: GaitModel, agents: int = 1000, default_threads: int | None = None
               ) -> list[dict]:
    """Own paths against one shared path, one thread against torch's default, 10,000 agents.

    Returns rows: ``agents`` agents each on its own circle against the same agents sharing
    one path (target ratio >= 0.8); the same on one thread against the 30,000 agent-frames/s
    target; 100 agents stepped as the generator does by default (one thread) against torch's
    default thread count; and the memory of 10,000 agents (resident growth, MB) against 2 GB.
    """
    shared = _rate(_generator(model, agents), 10)
    own = _rate(_generator(model, agents, own_paths=True), 10)
    # Torch's own default, read when the benchmarks started: inside a pinned block
    # torch.get_num_threads() is the pinned count.
    threads = default_threads or DEFAULT_THREADS
    with unpinned_threads():
        default = _rate(_generator(model, 100, threads=max(threads, 1)), 20)
    ours = _rate(_generator(model, 100), 20)
    before = resident_mb()
    big = _generator(model, 10_000, own_paths=True)
    big.step()
    grown = resident_mb() - before
    return [
        comparison(f"gait_own_paths[{agents} agents, 1 thread]", "agent-frames/s", own, shared,
                   f"{agents} agents on one shared path"),
        comparison(f"gait_own_paths[{agents} agents, 1 thread]", "agent-frames/s", own,
                   30_000.0, "target: 30,000 agent-frames/s"),
        comparison("gait_threads[100 agents, generator default]", "agent-frames/s", ours,
                   default, f"torch default ({threads} threads)"),
        comparison("gait_memory[10,000 agents, own paths]", "MB", grown, 2048.0,
                   "budget: 2 GB", higher_is_better=False),
    ]


class WindowRerun:
    """The baseline: per agent, the network over its last ``WINDOW`` inputs for each frame.

    Wraps a :class:`GaitGenerator` for the controls and the pose bookkeeping, and replaces its
    one batched ``step`` by one windowed ``forward`` per agent.
    """

    def __init__(self, gen: GaitGenerator) -> None:
        self.gen = gen
        net = gen.network
        self.history: list[deque] = []
        for k in range(len(gen)):
            frame = self._inputs(k)
            self.history.append(deque([frame] * WINDOW, maxlen=WINDOW))
        self.net = net

    def _fields(self) -> dict[str, torch.Tensor]:
        return self.gen.graph.layout.unpack(self.gen._batch.rows)

    def _inputs(self, k: int) -> tuple[torch.Tensor, ...]:
        f = self._fields()
        theta = float(f["theta"][k])
        movement = torch.tensor([np.sin(theta), np.cos(theta), 0.2, float(f["speed_lowpass"][k]),
                                 float(f["kappa"][k])], dtype=self.gen.dtype)
        return (f["rotations"][k], f["affective"][k],
                torch.as_tensor(self.gen._batch.emotion[k], dtype=self.gen.dtype), movement,
                f["root"][k])

    @torch.no_grad()
    def step(self) -> None:
        """Advance every agent one frame, each by its own windowed forward."""
        g = self.gen
        for k, history in enumerate(self.history):
            window = GaitInputs(*(torch.stack(x)[None] for x in zip(*history, strict=True)))
            out, _ = self.net(window)
            rot = out.rotations[:, -1]
            affective = gait_affective(g.graph.fk(rot), g.graph.roles)
            f = self._fields()
            f["rotations"][k], f["root"][k], f["affective"][k] = (rot[0], out.root[0, -1],
                                                                  affective[0])
            history.append(self._inputs(k))


def run(model: GaitModel | None = None, agents: tuple[int, ...] = (1, 10, 100, 1000),
        baseline_agents: tuple[int, ...] = (1, 10, 100), steps: int = 30) -> list[dict]:
    """Agent-frames per second of the streaming generator against the baseline.

    Agent-frames per second of the streaming generator for each agent count, and side by
    side with the window re-running baseline for ``baseline_agents``.
    """
    model = model or get_model("gait").load("generator").model
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _run(model, agents, baseline_agents, steps)
    finally:
        torch.set_num_threads(threads)


def _run(model: GaitModel, agents: tuple[int, ...], baseline_agents: tuple[int, ...],
         steps: int) -> list[dict]:
    out = []
    rates = {}
    for n in agents:
        gen = _generator(model, n)
        count = max(5, steps if n <= 100 else steps // 3)

        def run_ours(gen: GaitGenerator = gen, count: int = count) -> None:
            for _ in range(count):
                gen.step()

        seconds = median_seconds(run_ours, repeats=3)
        rates[n] = n * count / seconds
    for n in agents:
        if n in baseline_agents:
            base = WindowRerun(_generator(model, n))
            count = 5
            seconds = median_seconds(lambda b=base, c=count: [b.step() for _ in range(c)],
                                     repeats=3)
            out.append(comparison(f"gait_generate[{n} agents, 1 thread]", "agent-frames/s",
                                  rates[n], n * count / seconds,
                                  f"window re-run ({WINDOW} frames)"))
        else:
            out.append(comparison(f"gait_generate[{n} agents, 1 thread]", "agent-frames/s",
                                  rates[n], 3000.0, "target: 100 agents at 30 fps"))
    return out


def default_model() -> GaitModel:
    """The committed gait network."""
    return get_model("gait").load("generator").model


def low_foot_skate(points: np.ndarray, fps: float, roles: JointRoles) -> float:
    """Mean horizontal speed (m/s) of ankles and toes while within 2 cm of their floor.

    An independent measure beside the evaluation suite's: each point's floor is its 5th
    percentile height over the clip; frame pairs where the point stays below floor + 2 cm
    count.

    Args:
        points: ``(T, J + E, 3)`` world positions.
        fps: frames per second.
        roles: the rig's roles.
    """
    feet = points[:, [roles.index[r] for r in ("l_ankle", "l_toe", "r_ankle", "r_toe")]]
    height = feet[..., 1]
    low = height < np.percentile(height, 5, axis=0) + 0.02
    low = low[1:] & low[:-1]
    speed = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1) * fps
    return float(speed[low].mean())


def skate_rows(model: GaitModel, clips: list, agents: int = 4, seconds: float = 10.0
               ) -> list[dict]:
    """Streamed foot skate per emotion against real dataset-1 walks.

    Rows per emotion: the evaluation suite's measure
    (:func:`emotive.eval.feet.foot_skating`) and :func:`low_foot_skate`, of ``agents`` agents
    streamed on a figure-8 (the foot lock on, as every consumer gets them) against the mean
    over the real walks of that emotion in ``clips``; and the largest ankle difference from
    the unlocked stream while that foot is not planted (median and 95th percentile, cm).
    """
    roles = resolve_roles(model.controls.skeleton)
    rows = []
    for emotion in EMOTIONS:
        streams = {}
        for lock in (True, False):
            gen = GaitGenerator(model, foot_lock=lock)
            gen.add_agents([figure8()] * agents, [emotion] * agents, seeds=list(range(agents)))
            frames, planted = [], []
            for _ in range(round(seconds * model.fps)):
                frames.append(gen.step().world)
                planted.append(gen._batch.feet_planted.any(-1))
            streams[lock] = (np.stack(frames, 1), np.stack(planted, 1))
        world, planted = streams[True]
        real = [read_bvh(c) for c in clips if f"_walk_{emotion}_" in c.name
                or (emotion == "neutral" and "_walk_normal_" in c.name)]
        real_roles = [resolve_roles(r.skeleton) for r in real]
        suite = np.mean([float(foot_skating(w, roles, model.fps).mean_speed) for w in world])
        suite_real = np.mean([float(foot_skating(r.positions_with_end_sites(), rr, r.fps)
                                    .mean_speed) for r, rr in zip(real, real_roles, strict=True)])
        low = np.mean([low_foot_skate(w, model.fps, roles) for w in world])
        low_real = np.mean([low_foot_skate(r.positions_with_end_sites(), r.fps, rr)
                            for r, rr in zip(real, real_roles, strict=True)])
        ankles = [roles.index["l_ankle"], roles.index["r_ankle"]]
        gap = np.linalg.norm(world[:, :, ankles] - streams[False][0][:, :, ankles], axis=-1)
        swing = gap[~planted] * 100.0
        rows += [
            comparison(f"gait_stream_skate[{emotion}, suite measure]", "m/s", suite,
                       suite_real, f"real dataset-1 {emotion} walks", higher_is_better=False),
            comparison(f"gait_stream_skate[{emotion}, within 2 cm]", "m/s", low, low_real,
                       f"real dataset-1 {emotion} walks", higher_is_better=False),
            comparison(f"gait_lock_swing_change[{emotion}, ankle p50]", "cm",
                       float(np.median(swing)), float(np.percentile(swing, 95)),
                       "ankle p95 (unlocked stream, foot not planted)", higher_is_better=False),
        ]
    return rows


def main() -> None:
    """Print the benchmark rows and the total time."""
    print_rows(run)


if __name__ == "__main__":
    main()
