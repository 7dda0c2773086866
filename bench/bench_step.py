"""The whole per-frame step of gait agents: torch against the exported graph on ONNX Runtime.

Ours: :class:`emotive.models.gait.generate.GaitGenerator` stepping agents each on its own
circle with its own step (:class:`~emotive.models.gait.step_graph.AgentStep`, eager torch, one
thread), and the same generator driving the exported whole-step graph on onnxruntime's CPU
provider (one intra-op thread). Rows: agent-frames per second of 1,000 agents against the
70,000 target and torch against ONNX Runtime; milliseconds of one agent's step against the
1.5 ms target; the share of the step the network takes; and the parity of the two over 600
frames (largest joint gap, metres). Run ``python -m bench.bench_step``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import torch

from bench.common import comparison, median_seconds, pinned_threads, print_rows
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs
from emotive.models.gait.step_export import export_agent_step
from emotive.models.gait.step_runtime import OnnxAgentStep
from emotive.models.registry import get_model
from emotive.paths import circle

EMOTIONS = ("happy", "sad", "angry", "neutral")
#: Target of the whole step with 1,000 agents on one thread (agent-frames per second).
TARGET_RATE = 70_000.0
#: Target of one agent's step (milliseconds).
TARGET_ONE_MS = 1.5


def crowd(model: GaitModel, agents: int, step=None) -> GaitGenerator:
    """``agents`` agents each on its own circle of 1.5-2.5 m, walking for three frames."""
    gen = GaitGenerator(model, step=step)
    gen.add_agents([circle(1.5 + 0.001 * (k % 1000)) for k in range(agents)],
                   [EMOTIONS[k % len(EMOTIONS)] for k in range(agents)],
                   starts=[0.37 * k for k in range(agents)])
    for _ in range(3):
        gen.step()
    return gen


def _ms(gen: GaitGenerator, steps: int, repeats: int) -> float:
    """Median milliseconds of one step over ``repeats`` runs of ``steps`` steps."""
    return 1e3 * median_seconds(lambda: [gen.step() for _ in range(steps)],
                                repeats=repeats) / steps


@torch.no_grad()
def _network_ms(gen: GaitGenerator, steps: int, repeats: int) -> float:
    """Median milliseconds of the network alone on the crowd's inputs."""
    f = gen.graph.layout.unpack(gen._batch.rows)
    n = len(gen)
    inputs = GaitInputs(f["rotations"], f["affective"],
                        torch.as_tensor(gen._batch.emotion, dtype=gen.dtype),
                        torch.zeros(n, 5, dtype=gen.dtype), f["root"])
    state = gen._batch.state
    return 1e3 * median_seconds(lambda: [gen.network.step(inputs, state) for _ in range(steps)],
                                repeats=repeats) / steps


def parity(model: GaitModel, runtime: OnnxAgentStep, frames: int = 600) -> float:
    """Largest joint gap (metres) of 10 agents over ``frames`` frames, torch against ONNX."""
    worlds = []
    for step in (None, runtime):
        gen = crowd(model, 10, step)
        gen.set_emotion(gen.agents[0], "sad")
        worlds.append(np.stack([gen.step().world for _ in range(frames)]))
    return float(np.linalg.norm(worlds[0] - worlds[1], axis=-1).max())


def run(model: GaitModel | None = None, agents: int = 1000, repeats: int = 5) -> list[dict]:
    """The rows of the module docstring."""
    model = model or get_model("gait").load("generator").model
    with pinned_threads(1), tempfile.TemporaryDirectory() as tmp:
        runtime = OnnxAgentStep(export_agent_step(model, Path(tmp) / "agent.onnx"))
        torch_big, onnx_big = crowd(model, agents), crowd(model, agents, runtime)
        steps = 10
        big = {"torch": _ms(torch_big, steps, repeats), "onnx": _ms(onnx_big, steps, repeats)}
        network = _network_ms(torch_big, steps, repeats)
        one = {"torch": _ms(crowd(model, 1), 100, repeats),
               "onnx": _ms(crowd(model, 1, runtime), 100, repeats)}
        gap = parity(model, runtime)
    rate = {k: agents * 1e3 / v for k, v in big.items()}
    label = f"{agents} agents, own paths, 1 thread"
    rows = [
        comparison(f"step_torch[{label}]", "agent-frames/s", rate["torch"], TARGET_RATE,
                   "target: 70,000 agent-frames/s"),
        comparison(f"step_onnx[{label}]", "agent-frames/s", rate["onnx"], TARGET_RATE,
                   "target: 70,000 agent-frames/s"),
        comparison(f"step_onnx[{label}]", "agent-frames/s", rate["onnx"], rate["torch"],
                   "the torch step"),
        comparison(f"step_network_share[{label}]", "%", 100 * network / big["torch"], 100.0,
                   "the whole torch step", higher_is_better=False),
        comparison("step_torch[1 agent, 1 thread]", "ms", one["torch"], TARGET_ONE_MS,
                   "target: 1.5 ms", higher_is_better=False),
        comparison("step_onnx[1 agent, 1 thread]", "ms", one["onnx"], TARGET_ONE_MS,
                   "target: 1.5 ms", higher_is_better=False),
        comparison("step_parity[10 agents, 600 frames, onnx vs torch]", "m", gap, 1e-3,
                   "bound: 1e-3 m", higher_is_better=False),
    ]
    return rows


if __name__ == "__main__":
    print_rows(run)
