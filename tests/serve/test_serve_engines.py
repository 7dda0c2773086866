"""The engines behind ``--model`` and ``--backend``: FCRBM agents, the ONNX step, refusals."""

from __future__ import annotations

import asyncio

import httpx
import numpy as np
import pytest

from emotive.serve.engines import _optional_module, load_engine
from emotive.serve.errors import ServeError
from emotive.serve.messages import to_command
from emotive.serve.quantize import SIGNED_ERROR
from emotive.serve.settings import MAX_STEP_BUDGET, ServeSettings
from emotive.serve.simulation import JOIN_PER_TICK, Simulation
from emotive.serve.testing import running_server
from serve_client import WsClient


async def _two_agents(url: str):
    async with WsClient(url) as client:
        ids = await client.add_agents(2, emotion={"valence": 0.6, "arousal": 0.4})
        # FCRBM agents warm up over the first ticks before they are in the frames.
        await client.wait_for(lambda: client.frames and len(client.frames[-1][1].ids) == 2)
        frames = await client.frames_after(15)
        return ids, frames


def test_the_onnx_backend_runs_the_whole_exported_step_and_torch_is_traced_ahead():
    step_runtime = pytest.importorskip("emotive.models.gait.step_runtime")
    onnx = load_engine("gait", "onnx")
    assert isinstance(onnx.generator._step_fn, step_runtime.OnnxAgentStep)
    torch_engine = load_engine("gait", "torch")
    assert set(torch_engine.generator._traces) == {False, True}


def test_empty_scene_steps_without_the_model():
    engine = load_engine()
    frame = engine.step()
    assert frame.rotations.shape == (0, engine.skeleton.num_joints, 4)
    assert engine.rest.num_frames == 1


@pytest.mark.parametrize(("settings", "model", "backend"), [
    ({"model": "fcrbm"}, "fcrbm", "torch"),
    ({"backend": "onnx"}, "gait", "onnx"),
])
def test_optional_engines_stream(settings, model, backend):
    pytest.importorskip(
        "emotive.models.fcrbm.stream" if model == "fcrbm" else "emotive.models.gait.step_runtime")
    # The admission rule is pinned wide open: it fits the measured step time, and on a busy
    # machine one FCRBM agent's step can take more than the default budget, which would
    # (rightly) refuse the second agent; admission has its own tests.
    with running_server(**settings, step_budget=MAX_STEP_BUDGET) as url:
        health = httpx.get(f"{url}/api/health").json()
        sk = httpx.get(f"{url}/api/skeleton").json()
        ids, frames = asyncio.run(_two_agents(url))
    assert (health["model"], health["backend"]) == (model, backend)
    last = frames[-1]
    assert sorted(last.ids.tolist()) == sorted(ids)
    assert last.rotations.shape[1] == len(sk["joints"])
    assert last.emotion.shape[1] == len(sk["labels"])
    # Compact frames carry valence and arousal in 16 bits (then read as float32).
    np.testing.assert_allclose(last.valence_arousal, [[0.6, 0.4]] * 2, atol=SIGNED_ERROR + 1e-7)
    assert np.isfinite(last.world).all()
    assert np.abs(frames[0].world - last.world).max() > 0.01


def test_a_missing_optional_module_is_a_typed_error():
    with pytest.raises(ServeError, match=r"--backend onnx needs the module emotive\.nothing_here"):
        _optional_module("emotive.nothing_here", "--backend onnx")


class _Discard:
    def encodings(self) -> frozenset[int]:
        return frozenset()

    def frame(self, data: dict[int, bytes]) -> None:
        pass

    def notice(self, client: int, message: dict) -> None:
        pass


def test_fcrbm_agents_join_a_tick_without_warm_up_work(monkeypatch):
    stream_module = pytest.importorskip("emotive.models.fcrbm.stream")
    sampled: list[int] = []
    gibbs = stream_module.gibbs_frame
    monkeypatch.setattr(stream_module, "gibbs_frame",
                        lambda net, w, window, *a: sampled.append(len(window)) or gibbs(
                            net, w, window, *a))
    engine = load_engine("fcrbm")
    sim = Simulation(engine, ServeSettings(model="fcrbm"), _Discard())
    command = to_command({"type": "add_agent", "path": "figure8", "emotion": "sad=0.5,old=0.5"},
                         engine.labels, engine.points_over)
    futures = [sim.submit(command) for _ in range(50)]
    sim._apply_pending()  # a tick's commands, on this thread: joining is bookkeeping only
    assert sampled == [] and len(engine) == JOIN_PER_TICK
    assert all(f.done() for f in futures[:JOIN_PER_TICK])
    sim._tick()  # the step samples each agent once (plus the bounded warm-up)
    assert sum(sampled) <= len(engine) + stream_module.WARMUP_BUDGET
