"""Tests of the QuaterNet baseline: config, network (shapes, streaming, unit quaternions),
settings files, checkpoints, and a short training run on real windows."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from emotive.data.emotion import ALL_LABELS
from emotive.errors import ConfigError
from emotive.models.gait import GaitConfig, GaitRig
from emotive.models.gait.data import load_gait_data
from emotive.models.gait.quaternet import QuaterNetConfig, QuaterNetwork
from emotive.models.gait.quaternet.training import (
    CSV_COLUMNS,
    load_quaternet_checkpoint,
    load_quaternet_settings,
    quaternet_loss,
    rollout,
    train_quaternet,
)
from emotive.models.gait.training import GaitTrainSettings, load_gait_settings

REPO = Path(__file__).resolve().parents[4]
SMALL = QuaterNetConfig(control_hidden=8, gru_hidden=24)
SETTINGS = GaitTrainSettings(
    epochs=2, batch_size=8, window=12, stride=24, learning_rate=3e-3,
    teacher_forcing_decay=0.5, datasets=("bandai-namco-1",), max_clips=2,
)


def inputs(config: QuaterNetConfig, batch: int, frames: int | None, seed: int = 0):
    """Random float64 unit rotations and movement inputs, ``(B, T, ...)`` or ``(B, ...)``."""
    g = torch.Generator().manual_seed(seed)
    lead = (batch,) if frames is None else (batch, frames)
    q = torch.randn(*lead, config.num_joints, 4, generator=g, dtype=torch.float64)
    return q / q.norm(dim=-1, keepdim=True), torch.randn(*lead, 5, generator=g,
                                                         dtype=torch.float64)


def network(config: QuaterNetConfig = SMALL, seed: int = 0) -> QuaterNetwork:
    torch.manual_seed(seed)
    return QuaterNetwork(config).double()


def test_config_round_trip_and_errors():
    config = QuaterNetConfig(labels=("sad", "happy"), gru_layers=1, residual=True)
    assert QuaterNetConfig.from_dict(config.to_dict()) == config
    assert QuaterNetConfig.from_json(config.to_json()) == config
    assert QuaterNetConfig().labels == ALL_LABELS and QuaterNetConfig().num_joints == 22
    with pytest.raises(ValueError, match="unknown QuaterNetConfig fields"):
        QuaterNetConfig.from_dict({**config.to_dict(), "enc1_hidden": 3})
    for bad, match in ((dict(gru_hidden=0), "gru_hidden"), (dict(fps=-1.0), "fps"),
                       (dict(versor_weight=-1), "versor_weight"),
                       (dict(use_movement=1), "use_movement")):
        with pytest.raises(ValueError, match=match):
            QuaterNetConfig(**bad)


@pytest.mark.parametrize("config", [SMALL, replace(SMALL, use_movement=False, gru_layers=1),
                                    replace(SMALL, residual=True)])
def test_forward_equals_steps_and_outputs_unit_quaternions(config):
    net = network(config)
    rotations, movement = inputs(config, 3, 7)
    with torch.no_grad():
        out, state = net(rotations, movement)
        assert out.rotations.shape == out.raw_rotations.shape == (3, 7, config.num_joints, 4)
        assert state.shape == (config.gru_layers, 3, config.gru_hidden)
        torch.testing.assert_close(out.rotations.norm(dim=-1),
                                   torch.ones(3, 7, config.num_joints, dtype=torch.float64))
        step_state = None
        for t in range(7):
            frame, step_state = net.step(rotations[:, t], movement[:, t], step_state)
            assert frame.rotations.shape == (3, config.num_joints, 4)
            torch.testing.assert_close(frame.rotations, out.rotations[:, t])
            torch.testing.assert_close(frame.raw_rotations, out.raw_rotations[:, t])
        torch.testing.assert_close(step_state, state)
        # Carrying the state across windows is the same as one long window.
        first, mid = net(rotations[:, :3], movement[:, :3])
        second, _ = net(rotations[:, 3:], movement[:, 3:], mid)
        torch.testing.assert_close(torch.cat((first.rotations, second.rotations), 1),
                                   out.rotations)


@pytest.mark.parametrize("residual", [False, True])
def test_residual_applies_the_prediction_to_the_input_rotation(residual):
    net = network(replace(SMALL, residual=residual))
    with torch.no_grad():
        net.fc_out.weight.zero_()
        net.fc_out.bias.copy_(torch.tensor([1.0, 0, 0, 0]).repeat(SMALL.num_joints))
        rotations, movement = inputs(SMALL, 2, 4)
        out, _ = net(rotations, movement)
    expected = rotations if residual else torch.tensor([1.0, 0, 0, 0]).expand_as(rotations)
    torch.testing.assert_close(out.rotations, expected.to(torch.float64))


def test_movement_statistics_standardise_the_inputs():
    net = network()
    rotations, movement = inputs(SMALL, 2, 5)
    mean, std = torch.arange(5.0), torch.linspace(0.5, 2.0, 5)
    with torch.no_grad():
        plain, _ = net(rotations, (movement - mean.double()) / std.double())
        net.set_feature_statistics((mean, std))
        standardised, _ = net(rotations, movement)
    torch.testing.assert_close(standardised.rotations, plain.rotations)
    with pytest.raises(ValueError, match="shape"):
        net.set_feature_statistics((torch.zeros(4), torch.ones(4)))
    with pytest.raises(ValueError, match="positive"):
        net.set_feature_statistics((torch.zeros(5), torch.zeros(5)))


def test_bad_shapes_name_the_input():
    net = network()
    rotations, movement = inputs(SMALL, 2, 5)
    with pytest.raises(ValueError, match=r"rotations must have shape \(B, T, J=22, 4\)"):
        net(rotations[..., :3], movement)
    with pytest.raises(ValueError, match=r"movement must have shape \(B, T, 5\)"):
        net(rotations, movement[:, :4])
    with pytest.raises(ValueError, match=r"movement must have shape \(B, 5\)"):
        net.step(rotations[:, 0], None)
    with pytest.raises(ValueError, match=r"state must have shape \(L=2, B=2, H=24\)"):
        net(rotations, movement, torch.zeros(1, 2, 24, dtype=torch.float64))


def test_repository_config_trains_like_the_gait_network(tmp_path):
    config, settings = load_quaternet_settings(REPO / "configs" / "quaternet.toml")
    assert config == QuaterNetConfig()
    assert settings == load_gait_settings(REPO / "configs" / "gait.toml")[1]
    assert config.labels == load_gait_settings(REPO / "configs" / "gait.toml")[0].labels
    with pytest.raises(ConfigError, match="not found"):
        load_quaternet_settings(tmp_path / "missing.toml")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[train\nepochs = 3", "not valid TOML"),
        ("[model]\nenc1_hidden = 3", r"unknown key \[model\] enc1_hidden"),
        ("[model]\ngru_hidden = -1", r"\[model\] gru_hidden"),
        ("[train]\nepochs = 0", r"\[train\] epochs"),
        ("[optim]\nlr = 1", r"unknown section \[optim\]"),
    ],
)
def test_bad_config_files_give_one_line_typed_errors(tmp_path, text, match):
    path = tmp_path / "quaternet.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        load_quaternet_settings(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_missing_corrupt_and_foreign_checkpoints_are_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_quaternet_checkpoint(tmp_path / "missing.pt")
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    truncated = tmp_path / "truncated.pt"
    torch.save({"config": SMALL.to_dict(), "state": network().state_dict()}, truncated)
    truncated.write_bytes(truncated.read_bytes()[:200])
    gait = tmp_path / "gait.pt"
    torch.save({"config": GaitConfig().to_dict(), "state": {}}, gait)
    for path in (garbage, truncated, gait):
        with pytest.raises(ConfigError, match="not a QuaterNet checkpoint") as info:
            load_quaternet_checkpoint(path)
        assert str(path) in str(info.value)
    with pytest.raises(ConfigError, match="is a folder"):
        load_quaternet_checkpoint(tmp_path)


def test_command_reports_config_errors_and_resume_without_checkpoint(tmp_path):
    import typer

    from emotive.commands.train import train_quaternet_command

    app = typer.Typer()
    app.command()(train_quaternet_command)
    bad = tmp_path / "bad.toml"
    bad.write_text("[train]\nbatch_size = 'x'")
    result = CliRunner().invoke(app, ["--config", str(bad), "--out", str(tmp_path / "o")])
    assert isinstance(result.exception, ConfigError)
    assert "[train] batch_size" in str(result.exception)
    with pytest.raises(ConfigError, match="no checkpoint to resume"):
        train_quaternet(SMALL, SETTINGS, progress=False, out_dir=tmp_path, resume=True,
                        data={"train": None})


@pytest.fixture(scope="module")
def data(bandai1_dir):
    gait = GaitConfig(labels=SMALL.labels, num_joints=SMALL.num_joints, fps=SMALL.fps)
    return load_gait_data(gait, SETTINGS.datasets, SETTINGS.window, SETTINGS.stride,
                          max_clips=SETTINGS.max_clips)


def run(data, out_dir, settings=SETTINGS, **kwargs):
    return train_quaternet(SMALL, settings, progress=False, out_dir=out_dir, data=data, **kwargs)


def losses(history):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in history]


@pytest.mark.data
def test_training_lowers_the_loss_and_writes_loadable_checkpoints(data, tmp_path):
    # Teacher-forced throughout, so the epochs' losses are comparable.
    result = run(data, tmp_path, replace(SETTINGS, epochs=3, teacher_forcing_decay=1.0))
    with open(tmp_path / "log.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 3 and tuple(rows[0]) == CSV_COLUMNS
    assert float(rows[-1]["train_total"]) < float(rows[0]["train_total"])
    assert float(rows[-1]["train_pose"]) < float(rows[0]["train_pose"])
    assert all(float(r["val_total"]) > 0 for r in rows)
    for name in ("last.pt", "best.pt"):
        net, ckpt = load_quaternet_checkpoint(tmp_path / name)
        assert isinstance(net, QuaterNetwork) and ckpt["config"] == SMALL.to_dict()
        assert ckpt["model"] == "quaternet" and ckpt["train"]["epochs"] == 3
        assert ckpt["controls"]["labels"] == list(SMALL.labels)
    assert load_quaternet_checkpoint(tmp_path / "last.pt")[1]["epoch"] == 3
    best_epoch = int(np.argmin([float(r["val_total"]) for r in rows])) + 1
    assert load_quaternet_checkpoint(tmp_path / "best.pt")[1]["epoch"] == best_epoch
    np.testing.assert_allclose(result.network.movement_std.numpy(),
                               data["train"].statistics()["movement"][1])
    last = load_quaternet_checkpoint(tmp_path / "last.pt")[0]
    for k, v in result.network.state_dict().items():
        torch.testing.assert_close(last.state_dict()[k], v, rtol=0, atol=0)


@pytest.mark.data
def test_same_seed_same_run_and_resume_equals_an_uninterrupted_run(data, tmp_path):
    first = run(data, tmp_path / "a", seed=3)
    assert losses(run(data, tmp_path / "b", seed=3).history) == losses(first.history)
    assert [r["teacher_forcing"] for r in first.history] == [1.0, 0.5]
    run(data, tmp_path / "c", replace(SETTINGS, epochs=1), seed=3)
    resumed = run(data, tmp_path / "c", resume=True, seed=3)
    assert losses(resumed.history) == losses(first.history)
    for k, v in first.network.state_dict().items():
        torch.testing.assert_close(resumed.network.state_dict()[k], v, rtol=0, atol=0)
    with pytest.raises(ConfigError, match="another \\[model\\] config"):
        train_quaternet(replace(SMALL, gru_hidden=16), SETTINGS, progress=False,
                        out_dir=tmp_path / "c", resume=True, data=data)


@pytest.mark.data
def test_rollout_feeds_back_predictions_and_the_loss_has_both_terms(data):
    net = network().float()
    rig = GaitRig.from_skeleton(data["train"].skeleton)
    batch = data["train"].batch(np.arange(3))
    with torch.no_grad():
        forced = rollout(net, batch, np.ones(SETTINGS.window, dtype=bool))
        direct, _ = net(batch.rotations[:, :-1], batch.movement[:, :-1])
        mask = np.ones(SETTINGS.window, dtype=bool)
        mask[4] = False
        mixed = rollout(net, batch, mask)
        total, terms = quaternet_loss(forced, batch, rig, SMALL)
    torch.testing.assert_close(forced.rotations, direct.rotations)
    torch.testing.assert_close(mixed.rotations[:, :4], forced.rotations[:, :4])
    assert not torch.allclose(mixed.rotations[:, 4], forced.rotations[:, 4])
    assert terms["pose"] > 0 and terms["versor"] > 0
    assert float(total) == pytest.approx(terms["pose"] + 0.01 * terms["versor"], rel=1e-5)
