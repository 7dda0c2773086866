"""The gait network on ONNX Runtime against torch: one network step, and a whole generator step.

Ours: the exported one-frame step (:mod:`emotive.models.gait.onnx_export`) run by
:class:`~emotive.models.gait.onnx_runtime.OnnxGaitNetwork` on onnxruntime's CPU provider with
one intra-op thread. Baseline: the same weights in torch's
:class:`~emotive.models.gait.network.GaitNetwork` on one torch thread (the generator's
default). Rows give milliseconds per step (median), for the network call alone on the inputs
of a running crowd and for :meth:`GaitGenerator.step
<emotive.models.gait.generate.GaitGenerator.step>` (network, controls, path following, foot
lock) of the same crowd; ratio > 1: ONNX Runtime is faster.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import torch

from bench.common import comparison, median_seconds, pinned_threads, print_rows
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import GaitInputs
from emotive.models.gait.onnx_export import export_onnx
from emotive.models.gait.onnx_runtime import OnnxGaitNetwork
from emotive.models.registry import get_model
from emotive.paths import figure8

EMOTIONS = ("happy", "sad", "angry", "neutral")
BASELINE = "torch (1 thread)"


def _crowd(model: GaitModel, agents: int, network: OnnxGaitNetwork | None) -> GaitGenerator:
    """``agents`` agents on a figure-8, stepped a few frames so that they walk."""
    gen = GaitGenerator(model, network=network)
    gen.add_agents([figure8()] * agents, [EMOTIONS[k % len(EMOTIONS)] for k in range(agents)],
                   starts=[0.37 * k for k in range(agents)])
    for _ in range(3):
        gen.step()
    return gen


def _inputs(gen: GaitGenerator) -> tuple[GaitInputs, torch.Tensor]:
    """The network inputs and state of a running crowd (movement as zeros: timing only)."""
    b = gen._batch
    n = len(gen)
    f = gen.graph.layout.unpack(b.rows)
    inputs = GaitInputs(f["rotations"], f["affective"],
                        torch.as_tensor(b.emotion, dtype=gen.dtype),
                        torch.zeros(n, 5, dtype=gen.dtype), f["root"])
    return inputs, b.state


def _ms_per_step(fn, steps: int, repeats: int) -> float:
    """Median milliseconds of one call of ``fn`` over ``repeats`` runs of ``steps`` calls."""
    return 1e3 * median_seconds(lambda: [fn() for _ in range(steps)], repeats=repeats) / steps


@torch.no_grad()
def _rows(model: GaitModel, runtime: OnnxGaitNetwork, agents: tuple[int, ...], steps: int,
          repeats: int) -> list[dict]:
    rows = []
    for n in agents:
        count = steps if n <= 100 else max(3, steps // 4)
        torch_gen, onnx_gen = _crowd(model, n, None), _crowd(model, n, runtime)
        inputs, state = _inputs(torch_gen)
        net = torch_gen.network
        torch_net = _ms_per_step(lambda i=inputs, s=state, f=net: f.step(i, s), count, repeats)
        onnx_net = _ms_per_step(lambda i=inputs, s=state: runtime.step(i, s), count, repeats)
        rows.append(comparison(f"gait_onnx_network_step[{n} agents, 1 thread]", "ms/step",
                               onnx_net, torch_net, BASELINE, higher_is_better=False))
        torch_step = _ms_per_step(torch_gen.step, count, repeats)
        onnx_step = _ms_per_step(onnx_gen.step, count, repeats)
        rows.append(comparison(f"gait_onnx_generator_step[{n} agents, 1 thread]", "ms/step",
                               onnx_step, torch_step, BASELINE, higher_is_better=False))
    return rows


def run(model: GaitModel | None = None, agents: tuple[int, ...] = (1, 100, 1000),
        steps: int = 20, repeats: int = 5, onnx_file: str | Path | None = None) -> list[dict]:
    """Milliseconds per step on ONNX Runtime against torch, per agent count.

    Args:
        model: the gait model (default: the committed one).
        agents: crowd sizes.
        steps: steps per timed run (a quarter of it above 100 agents, at least 3).
        repeats: timed runs per row; the median is kept.
        onnx_file: an export of ``model`` (default: exported now into a temporary folder).

    Returns:
        Two rows per crowd size: the network step alone and the whole generator step.
    """
    model = model or get_model("gait").load("generator").model
    with pinned_threads(1), tempfile.TemporaryDirectory(prefix="emotive-bench-onnx-") as tmp:
        path = onnx_file or export_onnx(model, Path(tmp) / "gait.onnx")
        runtime = OnnxGaitNetwork(path, threads=1)
        return _rows(model, runtime, agents, steps, repeats)


def main() -> None:
    """Print the benchmark rows and the total time."""
    print_rows(run)


if __name__ == "__main__":
    main()
