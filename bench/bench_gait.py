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

import time
from collections import deque

import numpy as np
import torch

from bench.common import comparison, median_seconds
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs
from emotive.models.registry import get_model
from emotive.paths import figure8

#: Input frames the window re-running baseline feeds the network for every new frame (2 s).
WINDOW = 60
EMOTIONS = ("happy", "sad", "angry", "neutral")


def _generator(model: GaitModel, agents: int) -> GaitGenerator:
    gen = GaitGenerator(model)
    path = figure8()
    for k in range(agents):
        gen.add_agent(path, EMOTIONS[k % len(EMOTIONS)], start=0.37 * k)
    for _ in range(3):
        gen.step()
    return gen


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

    def _inputs(self, k: int) -> tuple[torch.Tensor, ...]:
        g = self.gen
        movement = torch.tensor([np.sin(g._theta[k]), np.cos(g._theta[k]), 0.2, g._slp[k],
                                 g._kappa[k]], dtype=g.dtype)
        return (g._rot[k], g._affective[k], torch.as_tensor(g._emotion[k], dtype=g.dtype),
                movement, g._root[k])

    @torch.no_grad()
    def step(self) -> None:
        """Advance every agent one frame, each by its own windowed forward."""
        g = self.gen
        for k, history in enumerate(self.history):
            window = GaitInputs(*(torch.stack(x)[None] for x in zip(*history, strict=True)))
            out, _ = self.net(window)
            rot = out.rotations[:, -1]
            _, affective = g._affective_of(rot)
            g._rot[k], g._root[k], g._affective[k] = rot[0], out.root[0, -1], affective[0]
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


def main() -> None:
    """Print the benchmark rows and the total time."""
    start = time.perf_counter()
    for row in run():
        print(row)
    print(f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
