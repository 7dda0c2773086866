"""The gait step exported to ONNX and run on ONNX Runtime: parity with torch, errors, cache."""

from __future__ import annotations

import copy
import json
import math
import sys
import tempfile

import numpy as np
import onnx
import pytest
import torch

from emotive.core.roles import resolve_roles
from emotive.errors import ConfigError, EmotiveError
from emotive.models.gait import GaitConfig, GaitGenerator, GaitInputs, GaitNetwork
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.model import GaitModel, load_gait_model
from emotive.models.gait.network import same_hemisphere
from emotive.models.gait.onnx_export import (
    INPUT_NAMES,
    META_KEYS,
    OPSET,
    OUTPUT_NAMES,
    OnnxUnavailableError,
    export_onnx,
)
from emotive.models.gait.onnx_runtime import (
    GaitInputError,
    OnnxGaitNetwork,
    cached_onnx_path,
    load_onnx_network,
)
from emotive.paths import circle, figure8
from emotive.transforms.kinematics import PoseFK

#: Closed-loop steps of the parity tests.
STEPS = 300


@pytest.fixture(scope="module")
def model() -> GaitModel:
    return load_gait_model()


@pytest.fixture(scope="module")
def onnx_file(model, tmp_path_factory):
    return export_onnx(model, tmp_path_factory.mktemp("onnx") / "gait.onnx")


@pytest.fixture(scope="module")
def runtime(onnx_file) -> OnnxGaitNetwork:
    return OnnxGaitNetwork(onnx_file)


def _dims(value_info) -> list:
    return [d.dim_param or d.dim_value for d in value_info.type.tensor_type.shape.dim]


def test_the_file_holds_a_checked_step_graph_with_a_dynamic_batch_and_metadata(model, onnx_file):
    proto = onnx.load(str(onnx_file))
    onnx.checker.check_model(proto, full_check=True)
    cfg = model.network.config
    assert [i.name for i in proto.graph.input] == list(INPUT_NAMES)
    assert [o.name for o in proto.graph.output] == list(OUTPUT_NAMES)
    shapes = {v.name: _dims(v) for v in (*proto.graph.input, *proto.graph.output)}
    assert shapes["rotations"] == shapes["next_rotations"] == ["B", cfg.num_joints, 4]
    assert shapes["emotion"] == ["B", cfg.num_labels]
    assert shapes["state"] == shapes["next_state"] == [cfg.gru_layers, "B", cfg.gru_hidden]
    assert proto.opset_import[0].version == OPSET
    meta = {p.key: p.value for p in proto.metadata_props}
    assert set(META_KEYS) <= set(meta)
    assert meta["joint_names"].count('"') == 2 * cfg.num_joints
    assert float(meta["fps"]) == cfg.fps
    controls = GaitControls.from_dict(json.loads(meta["controls"]))
    assert controls.skeleton.names == model.controls.skeleton.names
    assert np.array_equal(controls.standing_rotations, model.controls.standing_rotations)
    assert "GRU" in {n.op_type for n in proto.graph.node}
    assert not list(onnx_file.parent.glob(".*tmp*")), "no temporary file left beside it"


def _closed_loop(step, model: GaitModel, agents: int) -> tuple[np.ndarray, np.ndarray]:
    """``STEPS`` steps of ``agents`` agents, each fed its own predictions and their features.

    Returns the ``(STEPS, B, J, 4)`` rotations and ``(STEPS, B, 3)`` root features.
    """
    c = model.controls
    sk = c.skeleton
    fk = PoseFK(sk.parents, c.standing_positions, sk.end_site_parents, sk.end_site_offsets,
                torch.float32)
    roles = resolve_roles(sk)
    rot = torch.as_tensor(c.standing_rotations, dtype=torch.float32).expand(agents, -1, -1)
    root = torch.tensor([c.standing_height, 0.0, 0.0]).expand(agents, -1)
    weights = torch.rand(agents, len(model.labels), generator=torch.Generator().manual_seed(3))
    emotion = weights / weights.sum(1, keepdim=True)
    omega = torch.as_tensor(c.step_frequency, dtype=torch.float32) @ emotion.T
    speed = torch.as_tensor(c.speed, dtype=torch.float32) @ emotion.T
    state, rots, roots = None, [], []
    for t in range(STEPS):
        theta = omega * t
        movement = torch.stack((theta.sin(), theta.cos(), omega, speed, 0.01 * speed**2), 1)
        affective = gait_affective(fk(rot), roles)
        out, state = step(GaitInputs(rot, affective, emotion, movement, root), state)
        rot, root = same_hemisphere(out.rotations, rot), out.root
        rots.append(rot.numpy())
        roots.append(root.numpy())
    return np.stack(rots), np.stack(roots)


@torch.no_grad()
def test_300_closed_loop_steps_match_torch_within_1e_4(model, runtime):
    torch_rot, torch_root = _closed_loop(model.network.float().step, model, agents=4)
    onnx_rot, onnx_root = _closed_loop(runtime.step, model, agents=4)
    assert np.isfinite(torch_rot).all() and np.abs(np.diff(torch_rot, axis=0)).max() > 1e-3
    assert np.abs(torch_rot - onnx_rot).max() <= 1e-4
    assert np.abs(torch_root - onnx_root).max() <= 1e-4


@torch.no_grad()
@pytest.mark.parametrize("batch", [1, 7])
def test_one_step_and_windows_match_torch_for_any_batch(model, runtime, batch):
    net = model.network.float()
    g = torch.Generator().manual_seed(batch)
    cfg = net.config
    inputs = GaitInputs(
        torch.nn.functional.normalize(torch.randn(batch, 5, cfg.num_joints, 4, generator=g),
                                      dim=-1),
        torch.randn(batch, 5, 18, generator=g), torch.rand(batch, cfg.num_labels, generator=g),
        torch.randn(batch, 5, 5, generator=g), torch.randn(batch, 5, 3, generator=g))
    state = torch.randn(cfg.gru_layers, batch, cfg.gru_hidden, generator=g)
    want, want_state = net(inputs, state)
    got, got_state = runtime(inputs, state)
    assert got.rotations.shape == want.rotations.shape == (batch, 5, cfg.num_joints, 4)
    for a, b in ((got.rotations, want.rotations), (got.root, want.root), (got_state, want_state)):
        assert (a - b).abs().max() <= 1e-5
    frame = GaitInputs(*(x[:, 0] if x.ndim > 2 else x for x in inputs))
    out64, state64 = runtime.step(GaitInputs(*(x.double() for x in frame)), state.double())
    assert out64.rotations.dtype == state64.dtype == torch.float64
    assert (out64.root.float() - want.root[:, 0]).abs().max() <= 1e-5


def test_no_agents_is_an_empty_step(runtime):
    cfg = runtime.config
    state = runtime.initial_state(0)
    assert state.shape == (cfg.gru_layers, 0, cfg.gru_hidden)
    out, new = runtime.step(GaitInputs(torch.zeros(0, cfg.num_joints, 4), torch.zeros(0, 18),
                                       torch.zeros(0, cfg.num_labels), torch.zeros(0, 5),
                                       torch.zeros(0, 3)), state)
    assert out.rotations.shape == (0, cfg.num_joints, 4) and new.shape == state.shape


def test_the_generator_on_onnx_streams_the_torch_generator_world_positions(model, runtime):
    worlds = []
    for network in (None, runtime):
        gen = GaitGenerator(model, network=network)
        gen.add_agents([figure8(), circle(2.0), figure8()], ["happy", "sad", "angry=0.5,tired=0.5"],
                       starts=[0.0, 1.0, 2.0])
        worlds.append(np.stack([gen.step().world for _ in range(STEPS)]))
    torch_world, onnx_world = worlds
    track = np.linalg.norm(np.diff(torch_world[:, :, 1][..., [0, 2]], axis=0), axis=-1)
    assert (track.sum(0) > 3.0).all(), "the agents walk"
    assert np.abs(torch_world - onnx_world).max() <= 1e-3


def test_a_network_without_affective_inputs_exports_and_matches(model, tmp_path):
    cfg = GaitConfig(labels=model.labels, num_joints=model.network.config.num_joints,
                     enc1_hidden=8, enc1_out=4, enc2_hidden=8, enc2_out=4, gru_hidden=16,
                     gru_layers=2, root_hidden=4, versor_hidden=16, use_affective=False)
    small = GaitModel(GaitNetwork(cfg).eval(), model.controls, model.source)
    runtime = load_onnx_network(small, export_onnx(small, tmp_path / "small.onnx"))
    g = torch.Generator().manual_seed(0)
    inputs = GaitInputs(torch.randn(3, cfg.num_joints, 4, generator=g), None,
                        torch.rand(3, cfg.num_labels, generator=g), torch.randn(3, 5, generator=g),
                        torch.randn(3, 3, generator=g))
    with torch.no_grad():
        want, want_state = small.network.step(inputs)
    got, got_state = runtime.step(inputs)
    assert (got.rotations - want.rotations).abs().max() <= 1e-5
    assert (got_state - want_state).abs().max() <= 1e-5


@pytest.mark.parametrize(("field", "shape", "words"), [
    ("rotations", (2, 21, 4), ["rotations", "(2, 21, 4)", "J=22"]),
    ("emotion", (2, 4), ["emotion", "(2, 4)", "happy"]),
    ("movement", (3, 5), ["movement", "(3, 5)", "B=2"]),
])
def test_a_wrong_shaped_input_is_a_typed_error_naming_it(runtime, field, shape, words):
    cfg = runtime.config
    inputs = GaitInputs(torch.zeros(2, cfg.num_joints, 4), torch.zeros(2, 18),
                        torch.zeros(2, cfg.num_labels), torch.zeros(2, 5), torch.zeros(2, 3))
    with pytest.raises(GaitInputError) as exc:
        runtime.step(inputs._replace(**{field: torch.zeros(shape)}))
    assert isinstance(exc.value, EmotiveError) and isinstance(exc.value, ValueError)
    assert all(w in str(exc.value) for w in words), str(exc.value)
    with pytest.raises(GaitInputError, match="state must have shape"):
        runtime.step(inputs, torch.zeros(cfg.gru_layers, 3, cfg.gru_hidden))


def test_a_file_for_another_rig_or_other_weights_is_a_typed_error(model, onnx_file, tmp_path):
    proto = onnx.load(str(onnx_file))
    for prop in proto.metadata_props:
        if prop.key == "joint_names":
            prop.value = prop.value.replace('"Hips"', '"pelvis"')
    other = tmp_path / "other-rig.onnx"
    onnx.save(proto, str(other))
    with pytest.raises(ConfigError, match=r"other-rig\.onnx.*the rig \(joint names\).*emotive "
                                          r"export onnx --out .*other-rig\.onnx"):
        load_onnx_network(model, other)
    network = copy.deepcopy(model.network)
    with torch.no_grad():
        next(network.parameters()).add_(0.01)
    retrained = GaitModel(network, model.controls, model.source)
    with pytest.raises(ConfigError, match=r"gait\.onnx.*the weights.*--weights"):
        load_onnx_network(retrained, onnx_file)


def test_missing_corrupt_and_foreign_files_are_typed_errors(model, tmp_path):
    with pytest.raises(ConfigError, match=r"none\.onnx: no such ONNX file.*emotive export onnx"):
        load_onnx_network(model, tmp_path / "none.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"\x08\x07garbage" * 10)
    with pytest.raises(ConfigError, match=r"bad\.onnx: not .*emotive export onnx --out"):
        load_onnx_network(model, bad)
    foreign = tmp_path / "foreign.onnx"
    x = onnx.helper.make_tensor_value_info("x", onnx.TensorProto.FLOAT, [1])
    y = onnx.helper.make_tensor_value_info("y", onnx.TensorProto.FLOAT, [1])
    graph = onnx.helper.make_graph([onnx.helper.make_node("Relu", ["x"], ["y"])], "g", [x], [y])
    onnx.save(onnx.helper.make_model(graph), str(foreign))
    with pytest.raises(ConfigError, match="not an emotive gait step file"):
        OnnxGaitNetwork(foreign)
    with pytest.raises(ValueError, match="threads"):
        OnnxGaitNetwork(foreign, threads=0)


def test_without_a_file_the_model_is_exported_once_into_the_cache(model, tmp_path, monkeypatch):
    monkeypatch.setenv("EMOTIVE_HOME", str(tmp_path))
    first = load_onnx_network(model, threads=2)
    assert first.path == cached_onnx_path(model) and first.path.parent == tmp_path / "onnx"
    assert first.threads == 2
    stamp = first.path.stat().st_mtime_ns
    assert load_onnx_network(model).path.stat().st_mtime_ns == stamp
    first.path.write_bytes(b"truncated")
    again = load_onnx_network(model)
    assert again.path == first.path and again.path.stat().st_size > 100_000
    out, _ = again.step(GaitInputs(torch.zeros(1, again.config.num_joints, 4), torch.zeros(1, 18),
                                   torch.full((1, again.config.num_labels), 1.0),
                                   torch.zeros(1, 5), torch.zeros(1, 3)))
    norms = out.rotations.norm(dim=-1)
    assert math.isclose(float(norms.min()), 1.0, abs_tol=1e-5)


def test_an_unwritable_cache_falls_back_to_a_temporary_folder(model, tmp_path, monkeypatch):
    home = tmp_path / "home"
    home.write_text("a file, not a folder")
    monkeypatch.setenv("EMOTIVE_HOME", str(home))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    network = load_onnx_network(model)
    assert network.path.is_file() and network.path.parent.parent == tmp_path
    assert network.path.name == cached_onnx_path(model).name


def test_without_onnxruntime_the_error_says_what_to_install(onnx_file, monkeypatch):
    monkeypatch.setitem(sys.modules, "onnxruntime", None)
    with pytest.raises(OnnxUnavailableError, match=r"onnxruntime.*pip install 'emotive\[onnx\]'"):
        OnnxGaitNetwork(onnx_file)
