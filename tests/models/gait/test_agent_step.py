"""The whole per-frame step as one ONNX graph: parity with GaitGenerator, the documented engine
loop, dynamic batch, metadata and bad input."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
import torch

from emotive.errors import ConfigError
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import load_gait_model
from emotive.models.gait.step_export import STEP_INPUTS, STEP_META_KEYS, export_agent_step
from emotive.models.gait.step_runtime import (
    OnnxAgentStep,
    StepInputError,
    load_agent_step,
    read_step_metadata,
)
from emotive.paths import GroundPath, circle, figure8, line, waypoints

ort = pytest.importorskip("onnxruntime")
DOCS = Path(__file__).resolve().parents[3] / "docs" / "runtime.md"


@pytest.fixture(scope="module")
def model():
    torch.set_num_threads(1)
    return load_gait_model()


@pytest.fixture(scope="module")
def agent_file(model, tmp_path_factory) -> Path:
    return export_agent_step(model, tmp_path_factory.mktemp("step") / "agent.onnx")


@pytest.fixture(scope="module")
def runtime(agent_file) -> OnnxAgentStep:
    return OnnxAgentStep(agent_file)


def _walk(model, step, frames: int = 600):
    """10 agents on their own paths, three emotion changes; joints and contacts per frame."""
    gen = GaitGenerator(model, step=step)
    rng = np.random.default_rng(0)
    paths = [figure8(), circle(1.5), circle(2.5), line(30.0)] + [
        waypoints(rng.uniform(-4.0, 4.0, (4, 2))) for _ in range(6)]
    emotions = ["happy", "sad", "angry", "neutral", "happy=0.5,sad=0.5"] * 2
    ids = gen.add_agents(paths, emotions, seeds=list(range(10)))
    world, contacts = [], []
    for t in range(frames):
        if t == 200:
            gen.set_emotion(ids[0], "sad")
            gen.set_emotion(ids[3], "angry=0.7,happy=0.3")
        if t == 400:
            gen.set_emotion(ids[1], "happy")
        frame = gen.step()
        world.append(frame.world)
        contacts.append(gen.agent_field("lock_planted"))
    return np.stack(world), np.stack(contacts)


def test_the_exported_step_walks_exactly_like_the_generator(model, runtime):
    ours, our_contacts = _walk(model, None)
    theirs, their_contacts = _walk(model, runtime)
    gap = np.linalg.norm(ours - theirs, axis=-1)
    assert gap.max() < 1e-3, f"max joint gap {gap.max():.2e} m"
    np.testing.assert_array_equal(our_contacts, their_contacts)
    # The agents walked: every one moved metres, and feet were planted along the way.
    assert (np.linalg.norm(ours[-1, :, 0, [0, 2]] - ours[0, :, 0, [0, 2]], axis=-1) > 0.2).all()
    assert our_contacts.mean() > 0.2


def test_the_documented_engine_loop_runs_as_written_and_matches_the_generator(
        model, agent_file, monkeypatch):
    text = DOCS.read_text(encoding="utf-8")
    code = text.split("<!-- runtime-example -->\n```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(agent_file.parent)
    namespace: dict = {}
    exec(compile(code, str(DOCS), "exec"), namespace)  # the page's example, verbatim
    gen = GaitGenerator(model)
    paths = []
    for r in (1.5, 2.0, 2.5):
        a = np.linspace(0.0, 2.0 * math.pi, int(2.0 * math.pi * r / 0.005) + 1)
        paths.append(GroundPath.from_polyline(np.stack((r * (1 - np.cos(a)), r * np.sin(a)),
                                                       -1), closed=True))
    gen.add_agents(paths, ["happy", "sad", "angry"], seeds=[0, 1, 2])
    for _ in range(90):
        frame = gen.step()
    assert np.abs(frame.world - namespace["world"]).max() < 1e-3


def test_the_file_has_a_dynamic_batch_and_the_metadata_an_engine_needs(model, agent_file,
                                                                      runtime):
    meta = read_step_metadata(agent_file)
    assert set(STEP_META_KEYS) <= set(meta)
    layout = json.loads(meta["agent_layout"])
    shapes = json.loads(meta["inputs"])
    size = layout[-1]["offset"] + math.prod(layout[-1]["shape"])
    assert shapes["agent"] == ["B", size]
    assert json.loads(meta["labels"]) == list(model.labels)
    sampling = json.loads(meta["path_sampling"])
    assert shapes["path"] == ["B", sampling["count"], 2]
    for batch in (1, 5):
        gen = GaitGenerator(model, step=runtime)
        gen.add_agents([circle(2.0)] * batch, ["happy"] * batch)
        frame = gen.step()
        assert frame.world.shape == (batch, 27, 3) and np.isfinite(frame.world).all()


def _feeds(runtime: OnnxAgentStep, batch: int = 2) -> dict[str, np.ndarray]:
    shapes = runtime.shapes
    sampling = json.loads(runtime.metadata["path_sampling"])
    ahead = sampling["first"] + sampling["spacing"] * np.arange(sampling["count"])
    path = np.stack((np.zeros_like(ahead), ahead), -1)
    return {
        "recurrent": np.zeros((shapes["recurrent"][0], batch, shapes["recurrent"][2]),
                              np.float32),
        "agent": np.zeros((batch, shapes["agent"][1]), np.float32),
        "emotion": np.full((batch, shapes["emotion"][1]), 1.0 / shapes["emotion"][1],
                           np.float32),
        "pace": np.ones(batch, np.float32),
        "path": np.repeat(path[None], batch, 0).astype(np.float32),
        "path_left": np.full(batch, 1e6, np.float32), "start": np.ones(batch, np.float32),
        "phase": np.zeros(batch, np.float32),
    }


def _call(runtime: OnnxAgentStep, feeds: dict[str, np.ndarray]):
    return runtime(*(torch.from_numpy(feeds[name]) for name in STEP_INPUTS))


def test_bad_shapes_and_non_finite_controls_are_named_before_the_call(runtime):
    feeds = _feeds(runtime)
    feeds["emotion"] = feeds["emotion"][:, :4]
    with pytest.raises(StepInputError, match=r"input 'emotion' must have shape \(B, 19\)"):
        _call(runtime, feeds)
    feeds = _feeds(runtime)
    feeds["path"] = feeds["path"][:, :3]
    with pytest.raises(StepInputError, match=r"input 'path' must have shape \(B, 15, 2\)"):
        _call(runtime, feeds)
    feeds = _feeds(runtime, 3)
    feeds["pace"][2] = np.nan
    with pytest.raises(StepInputError, match=r"control 'pace' is not finite .* \[2\]"):
        _call(runtime, feeds)


def _session(agent_file: Path):
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    return ort.InferenceSession(str(agent_file), options, providers=["CPUExecutionProvider"])


def _run(session, feeds: dict[str, np.ndarray], steps: int, follow: bool = True) -> dict:
    """``steps`` calls, the first 9 start steps; ``follow``: the samples stay put in the world."""
    names = [o.name for o in session.get_outputs()]
    world = feeds["path"].copy()
    for k in range(steps):
        feeds["start"] = np.full_like(feeds["start"], 1.0 if k < 9 else 0.0)
        out = dict(zip(names, session.run(None, feeds), strict=True))
        feeds["recurrent"], feeds["agent"] = out["next_recurrent"], out["next_agent"]
        if not follow:
            continue
        x, z, psi = (out["ground"][:, i, None] for i in range(3))
        dx, dz = world[..., 0] - x, world[..., 1] - z
        c, s = np.cos(psi), np.sin(psi)
        feeds["path"] = np.stack((c * dx - s * dz, s * dx + c * dz), -1).astype(np.float32)
    return out


def test_the_graph_reads_non_finite_controls_as_safe_values(runtime, agent_file):
    session = _session(agent_file)
    feeds = _feeds(runtime)
    for name in ("emotion", "pace", "path_left", "phase"):
        feeds[name] = np.full_like(feeds[name], np.nan)
    feeds["path"][1] = np.inf
    out = _run(session, feeds, 30, follow=False)
    for name, value in out.items():
        assert np.isfinite(value).all(), name


def test_a_path_of_one_point_walks_the_agent_to_it_and_stops(runtime, agent_file):
    session = _session(agent_file)
    feeds = _feeds(runtime, 1)
    feeds["path"] = np.zeros_like(feeds["path"])  # every sample at the origin
    feeds["path"][..., 1] = 0.3  # the one point: 30 cm ahead
    feeds["path_left"][:] = 0.0
    out = _run(session, feeds, 90)
    assert all(np.isfinite(v).all() for v in out.values())
    assert abs(out["ground"][0, 0]) < 0.05 and out["ground"][0, 1] < 0.35
    assert out["advance"][0] == 0.0


def test_files_that_are_missing_foreign_or_for_other_weights_fail_in_one_line(
        model, tmp_path, agent_file):
    with pytest.raises(ConfigError, match=r"none\.onnx: no such ONNX file.*--step agent"):
        OnnxAgentStep(tmp_path / "none.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not onnx")
    with pytest.raises(ConfigError, match=r"bad\.onnx: not a readable ONNX model"):
        OnnxAgentStep(bad)
    other = load_gait_model()
    with torch.no_grad():
        next(other.network.parameters()).add_(0.01)
    with pytest.raises(ConfigError, match=r"exported for another model"):
        load_agent_step(other, agent_file)


def test_the_cached_export_is_made_once_and_reused(model, tmp_path, monkeypatch):
    monkeypatch.setenv("EMOTIVE_HOME", str(tmp_path))
    first = load_agent_step(model)
    stamp = os.stat(first.path).st_mtime_ns
    again = load_agent_step(model)
    assert again.path == first.path and os.stat(again.path).st_mtime_ns == stamp


def test_the_traced_steps_walk_like_the_eager_step(model):
    """The start and walking traces (made ahead by ``prepare``) give the eager step's poses."""
    traced = GaitGenerator(model)
    traced.prepare()
    assert set(traced._traces) == {False, True}
    assert all(trace is not None for trace in traced._traces.values())
    worlds = []
    for gen in (traced, GaitGenerator(model, traced=False)):
        a = gen.add_agents([figure8(), circle(2.0)], ["happy", "sad=0.6,angry=0.4"],
                           seeds=[0, 1])
        walk = [gen.step().world for _ in range(60)]
        gen.set_emotion(a[0], "angry")
        gen.add_agent(line(10.0), "neutral")  # a start call among walking agents
        walk += [gen.step().world[:2] for _ in range(60)]
        worlds.append(np.stack(walk))
    gap = np.linalg.norm(worlds[0] - worlds[1], axis=-1)
    assert gap.max() < 1e-4, f"max joint gap {gap.max():.2e} m"
