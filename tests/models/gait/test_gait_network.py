"""Tests of GaitNetwork: shapes, unit quaternions, streaming equals windows, batch
independence, emotion vectors, ablation switches and feature statistics."""

from __future__ import annotations

import dataclasses

import pytest
import torch
from gait_helpers import NUM_JOINTS, random_inputs

from emotive.data.emotion import ALL_LABELS
from emotive.models.gait import GaitConfig, GaitInputs, GaitNetwork


def make_net(config: GaitConfig, seed: int = 0) -> GaitNetwork:
    torch.manual_seed(seed)
    return GaitNetwork(config).double()


def test_default_network_builds_with_the_paper_layers():
    net = GaitNetwork()
    linear = [m for m in net.fc_enc1 if isinstance(m, torch.nn.Linear)]
    assert len(linear) == 3
    assert len([m for m in net.fc_enc2 if isinstance(m, torch.nn.Linear)]) == 3
    assert len([m for m in net.fc_versors if isinstance(m, torch.nn.Linear)]) == 2
    assert net.gru.input_size == 4 * 22 + 32 + 32
    assert 0 < net.num_parameters < 500_000


def test_step_shapes_and_unit_quaternions(small_config):
    net = make_net(small_config)
    state = net.initial_state(3)
    assert state.shape == (2, 3, 24) and state.dtype == torch.float64
    out, new_state = net.step(random_inputs(small_config, 3, None), state)
    assert out.rotations.shape == out.raw_rotations.shape == (3, NUM_JOINTS, 4)
    assert out.root.shape == (3, 3) and new_state.shape == state.shape
    torch.testing.assert_close(out.rotations.norm(dim=-1), torch.ones(3, NUM_JOINTS,
                                                                      dtype=torch.float64))
    assert not torch.allclose(out.raw_rotations.norm(dim=-1), out.rotations.norm(dim=-1))


def test_forward_shapes(small_config):
    net = make_net(small_config)
    out, state = net(random_inputs(small_config, 2, 7))
    assert out.rotations.shape == (2, 7, NUM_JOINTS, 4) and out.root.shape == (2, 7, 3)
    assert state.shape == (2, 2, 24)
    assert torch.allclose(out.rotations.norm(dim=-1), torch.ones((), dtype=torch.float64))


def test_forward_equals_successive_steps(small_config):
    net = make_net(small_config)
    frames = 9
    inputs = random_inputs(small_config, 3, frames, seed=1)
    window, window_state = net(inputs)
    state = net.initial_state(3)
    for t in range(frames):
        frame = GaitInputs(*(x[:, t] for x in inputs))
        out, state = net.step(frame, state)
        for a, b in zip(out, window, strict=True):
            torch.testing.assert_close(a, b[:, t], rtol=0, atol=1e-12)
    torch.testing.assert_close(state, window_state, rtol=0, atol=1e-12)


def test_forward_continues_from_a_state(small_config):
    net = make_net(small_config)
    inputs = random_inputs(small_config, 2, 8, seed=2)
    whole, _ = net(inputs)
    first = GaitInputs(*(x[:, :5] for x in inputs))
    rest = GaitInputs(*(x[:, 5:] for x in inputs))
    _, state = net(first)
    tail, _ = net(rest, state)
    torch.testing.assert_close(tail.rotations, whole.rotations[:, 5:], rtol=0, atol=1e-12)
    # The state matters: the same frames from a fresh state predict otherwise.
    fresh, _ = net(rest)
    assert not torch.allclose(fresh.rotations, whole.rotations[:, 5:])


def test_agents_are_independent(small_config):
    net = make_net(small_config)
    inputs = random_inputs(small_config, 3, 6, seed=3)
    other = random_inputs(small_config, 3, 6, seed=4)
    # Agent 2 gets entirely different inputs; agents 0 and 1 must not notice.
    changed = GaitInputs(*(torch.cat((x[:2], y[2:])) for x, y in zip(inputs, other,
                                                                         strict=True)))
    a, _ = net(inputs)
    b, _ = net(changed)
    for x, y in zip(a, b, strict=True):
        torch.testing.assert_close(x[:2], y[:2], rtol=0, atol=0)
        assert not torch.allclose(x[2], y[2])


def test_emotion_blends_and_per_frame_emotions(small_config):
    net = make_net(small_config)
    inputs = random_inputs(small_config, 2, 5, seed=5)
    happy = torch.tensor([1.0, 0, 0, 0], dtype=torch.float64).expand(2, 4)
    blend = torch.tensor([0.5, 0.2, 0.3, 0.0], dtype=torch.float64).expand(2, 4)
    out_happy, _ = net(inputs._replace(emotion=happy))
    out_blend, _ = net(inputs._replace(emotion=blend))
    assert not torch.allclose(out_happy.rotations, out_blend.rotations)
    # A constant (B, C) emotion equals the same emotion repeated over the frames.
    repeated, _ = net(inputs._replace(emotion=blend[:, None].expand(2, 5, 4)))
    torch.testing.assert_close(repeated.root, out_blend.root, rtol=0, atol=0)
    # Switching emotion mid-window changes only the frames from the switch on.
    schedule = torch.cat((happy[:, None].expand(2, 3, 4), blend[:, None].expand(2, 2, 4)), 1)
    switched, _ = net(inputs._replace(emotion=schedule))
    torch.testing.assert_close(switched.root[:, :3], out_happy.root[:, :3], rtol=0, atol=0)
    assert not torch.allclose(switched.root[:, 3:], out_happy.root[:, 3:])


def test_labels_set_the_emotion_length():
    cfg = GaitConfig(labels=ALL_LABELS, num_joints=3, gru_hidden=8, versor_hidden=8)
    net = make_net(cfg)
    out, _ = net.step(random_inputs(cfg, 2, None))
    assert out.rotations.shape == (2, 3, 4)


@pytest.mark.parametrize("size", [3, 5])
def test_wrong_emotion_length_is_rejected(small_config, size):
    net = make_net(small_config)
    frame = random_inputs(small_config, 2, None)
    with pytest.raises(ValueError, match="emotion vectors must have 4 entries"):
        net.step(frame._replace(emotion=torch.ones(2, size, dtype=torch.float64) / size))
    window = random_inputs(small_config, 2, 4)
    with pytest.raises(ValueError, match="emotion vectors must have 4 entries"):
        net(window._replace(emotion=torch.ones(2, 4, size, dtype=torch.float64) / size))


@pytest.mark.parametrize(("field", "shape"), [
    ("rotations", (2, NUM_JOINTS - 1, 4)), ("rotations", (2, NUM_JOINTS, 3)),
    ("affective", (2, 17)), ("movement", (2, 6)), ("root", (3, 3)), ("emotion", (1, 4)),
])
def test_wrong_shapes_are_rejected(small_config, field, shape):
    net = make_net(small_config)
    frame = random_inputs(small_config, 2, None)
    bad = frame._replace(**{field: torch.zeros(shape, dtype=torch.float64)})
    with pytest.raises(ValueError, match=field):
        net.step(bad)


def test_window_passed_to_step_and_bad_state_are_rejected(small_config):
    net = make_net(small_config)
    with pytest.raises(ValueError, match="rotations"):
        net.step(random_inputs(small_config, 2, 4))
    with pytest.raises(ValueError, match="rotations"):
        net(random_inputs(small_config, 2, None))
    with pytest.raises(ValueError, match="state"):
        net.step(random_inputs(small_config, 2, None), net.initial_state(3))


def _affective_sensitivity(config: GaitConfig) -> float:
    net = make_net(config)
    inputs = random_inputs(config, 2, 4, seed=6)
    a, _ = net(inputs)
    b, _ = net(inputs._replace(affective=inputs.affective + 1.0))
    return max(float((x - y).abs().max().detach()) for x, y in zip(a, b, strict=True))


def test_affective_switch_changes_what_the_network_reads(small_config):
    assert _affective_sensitivity(small_config) > 1e-6
    ablated = dataclasses.replace(small_config, use_affective=False)
    assert _affective_sensitivity(ablated) == 0.0
    net = make_net(ablated)
    assert net.fc_enc1[0].in_features == ablated.num_labels
    out, _ = net.step(random_inputs(ablated, 2, None)._replace(affective=None))
    assert torch.isfinite(out.rotations).all()
    with pytest.raises(ValueError, match="affective"):
        make_net(small_config).step(random_inputs(small_config, 2, None)._replace(
            affective=None))


def test_root_loss_switch_keeps_the_network(small_config):
    ablated = dataclasses.replace(small_config, use_root_loss=False)
    torch.testing.assert_close(
        make_net(small_config)(random_inputs(small_config, 1, 3))[0].root,
        make_net(ablated)(random_inputs(ablated, 1, 3))[0].root,
    )


def test_feature_statistics_standardise_inputs_and_restore_root_units(small_config):
    net = make_net(small_config)
    plain = make_net(small_config)
    g = torch.Generator().manual_seed(7)
    stats = {name: (torch.randn(n, generator=g, dtype=torch.float64),
                    torch.rand(n, generator=g, dtype=torch.float64) + 0.5)
             for name, n in (("affective", 18), ("movement", 5), ("root", 3))}
    net.set_feature_statistics(**stats)
    inputs = random_inputs(small_config, 2, 3, seed=8)
    standard = inputs._replace(**{
        name: (getattr(inputs, name) - mean) / std for name, (mean, std) in stats.items()
    })
    a, _ = net(inputs)
    b, _ = plain(standard)
    torch.testing.assert_close(a.rotations, b.rotations)
    mean, std = stats["root"]
    torch.testing.assert_close(a.root, b.root * std + mean)
    # The statistics are buffers: they travel with the state dict.
    restored = make_net(small_config, seed=1)
    restored.load_state_dict(net.state_dict())
    torch.testing.assert_close(restored(inputs)[0].root, a.root)
    with pytest.raises(ValueError, match="std"):
        net.set_feature_statistics(root=(torch.zeros(3), torch.zeros(3)))
    with pytest.raises(ValueError, match="shape"):
        net.set_feature_statistics(movement=(torch.zeros(4), torch.ones(4)))


def test_gradients_reach_every_parameter(small_config):
    net = make_net(small_config)
    out, _ = net(random_inputs(small_config, 2, 4))
    (out.raw_rotations.square().sum() + out.root.square().sum()).backward()
    for name, p in net.named_parameters():
        assert p.grad is not None and torch.isfinite(p.grad).all(), name
        assert p.grad.abs().sum() > 0, name
