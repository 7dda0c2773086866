"""Tests of the gait training loop on a few real windows: loss goes down, checkpoints and CSV,
determinism, exact resume (also after Ctrl-C inside an epoch), scheduled sampling and config
errors."""

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
from emotive.models.gait import GaitConfig, GaitNetwork, GaitRig
from emotive.models.gait.data import load_gait_data
from emotive.models.gait.model import load_gait_checkpoint
from emotive.models.gait.training import (
    CSV_COLUMNS,
    GaitTrainSettings,
    load_gait_settings,
    rollout,
    teacher_forcing_mask,
    train_gait,
)

REPO = Path(__file__).resolve().parents[3]
CONFIG = GaitConfig(
    labels=ALL_LABELS, enc1_hidden=16, enc1_out=8, enc2_hidden=16, enc2_out=8, gru_hidden=24,
    root_hidden=8, versor_hidden=24,
)
SETTINGS = GaitTrainSettings(
    epochs=2, batch_size=8, window=12, stride=24, learning_rate=3e-3,
    teacher_forcing_decay=0.5, datasets=("bandai-namco-1",), max_clips=2,
)


@pytest.fixture(scope="module")
def data(bandai1_dir):
    return load_gait_data(CONFIG, SETTINGS.datasets, SETTINGS.window, SETTINGS.stride,
                          max_clips=SETTINGS.max_clips)


def run(data, out_dir, settings=SETTINGS, **kwargs):
    return train_gait(CONFIG, settings, progress=False, out_dir=out_dir, data=data, **kwargs)


def losses(history):
    return [{k: v for k, v in row.items() if k != "seconds"} for row in history]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.mark.data
def test_training_lowers_the_loss_and_writes_checkpoints_and_log(data, tmp_path):
    # Teacher-forced throughout, so the epochs' losses are comparable.
    settings = replace(SETTINGS, epochs=3, teacher_forcing_decay=1.0)
    result = run(data, tmp_path, settings)
    rows = read_csv(tmp_path / "log.csv")
    assert len(rows) == 3 and tuple(rows[0]) == CSV_COLUMNS
    assert [int(r["epoch"]) for r in rows] == [1, 2, 3]
    assert float(rows[-1]["train_total"]) < float(rows[0]["train_total"])
    assert all(float(r["val_total"]) > 0 and float(r["seconds"]) > 0 for r in rows)
    assert float(rows[1]["lr"]) == pytest.approx(3e-3 * 0.999)
    for name in ("last.pt", "best.pt"):
        net, ckpt = load_gait_checkpoint(tmp_path / name)
        assert isinstance(net, GaitNetwork) and ckpt["config"] == CONFIG.to_dict()
        assert ckpt["train"]["epochs"] == 3 and set(ckpt) >= {"optimizer", "rng", "state"}
    _, last = load_gait_checkpoint(tmp_path / "last.pt")
    assert last["epoch"] == 3
    best_epoch = int(np.argmin([float(r["val_total"]) for r in rows])) + 1
    assert load_gait_checkpoint(tmp_path / "best.pt")[1]["epoch"] == best_epoch
    # The training statistics travel in the weights.
    np.testing.assert_allclose(result.network.root_std.numpy(),
                               data["train"].statistics()["root"][1])


@pytest.mark.data
def test_same_seed_same_run_and_resume_equals_an_uninterrupted_run(data, tmp_path):
    first = run(data, tmp_path / "a", seed=3)
    second = run(data, tmp_path / "b", seed=3)
    assert losses(first.history) == losses(second.history)
    assert [r["teacher_forcing"] for r in first.history] == [1.0, 0.5]
    other = run(data, tmp_path / "c", replace(SETTINGS, epochs=1), seed=4)
    assert losses(other.history)[0] != losses(first.history)[0]

    run(data, tmp_path / "d", replace(SETTINGS, epochs=1), seed=3)
    resumed = run(data, tmp_path / "d", resume=True, seed=3)
    assert losses(resumed.history) == losses(first.history)
    assert len(read_csv(tmp_path / "d" / "log.csv")) == 2
    for k, v in first.network.state_dict().items():
        torch.testing.assert_close(resumed.network.state_dict()[k], v, rtol=0, atol=0)


@pytest.mark.data
def test_ctrl_c_inside_an_epoch_then_resume_equals_an_uninterrupted_run(data, tmp_path):
    settings = replace(SETTINGS, epochs=3)
    straight = run(data, tmp_path / "a", settings, seed=2)
    interrupted = []

    def interrupt(epoch, batch):
        if (epoch, batch) == (1, 1) and not interrupted:
            interrupted.append(True)
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run(data, tmp_path / "b", settings, seed=2, on_batch=interrupt)
    # last.pt stays at the end of epoch 1: the updates made inside epoch 2 are dropped.
    _, ckpt = load_gait_checkpoint(tmp_path / "b" / "last.pt")
    assert ckpt["epoch"] == 1 and len(ckpt["history"]) == 1
    assert len(read_csv(tmp_path / "b" / "log.csv")) == 1
    resumed = run(data, tmp_path / "b", settings, seed=2, resume=True, on_batch=interrupt)
    assert losses(resumed.history) == losses(straight.history)
    assert (losses(read_csv(tmp_path / "b" / "log.csv"))
            == losses(read_csv(tmp_path / "a" / "log.csv")))
    for k, v in straight.network.state_dict().items():
        torch.testing.assert_close(resumed.network.state_dict()[k], v, rtol=0, atol=0)
    for name in ("last.pt", "best.pt"):
        a = torch.load(tmp_path / "a" / name, weights_only=True)
        b = torch.load(tmp_path / "b" / name, weights_only=True)
        assert a["epoch"] == b["epoch"]
        for k, v in a["state"].items():
            assert torch.equal(b["state"][k], v), (name, k)


@pytest.mark.data
def test_rollout_feeds_back_its_predictions_where_not_teacher_forced(data):
    torch.manual_seed(0)
    net = GaitNetwork(CONFIG)
    rig = GaitRig.from_skeleton(data["train"].skeleton)
    batch = data["train"].batch(np.arange(3))
    with torch.no_grad():
        forced = rollout(net, batch, np.ones(SETTINGS.window, dtype=bool), rig)
        direct, _ = net(batch.inputs())
        mask = np.ones(SETTINGS.window, dtype=bool)
        mask[4] = False
        mixed = rollout(net, batch, mask, rig)
    torch.testing.assert_close(forced.rotations, direct.rotations)
    torch.testing.assert_close(mixed.rotations[:, :4], forced.rotations[:, :4])
    assert not torch.allclose(mixed.rotations[:, 4], forced.rotations[:, 4])


def test_teacher_forcing_mask():
    rng = np.random.default_rng(0)
    assert teacher_forcing_mask(5, 1.0, rng).all()
    assert teacher_forcing_mask(5, 0.0, rng).tolist() == [True, False, False, False, False]
    assert rng.random() == np.random.default_rng(0).random()
    half = teacher_forcing_mask(10_000, 0.5, rng)
    assert half[0] and 0.45 < half.mean() < 0.55


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[train\nepochs = 3", "not valid TOML"),
        ("[train]\nepochz = 3", r"unknown key \[train\] epochz"),
        ("[train]\nepochs = 0", r"\[train\] epochs: epochs must be an integer >= 1"),
        ("[model]\ngru_hidden = -1", r"\[model\] gru_hidden"),
        ("[model]\nlabels = ['happy', 'bored']", r"\[model\]"),
        ("[optim]\nlr = 1", r"unknown section \[optim\]"),
    ],
)
def test_bad_config_files_give_one_line_typed_errors(tmp_path, text, match):
    path = tmp_path / "gait.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match) as info:
        load_gait_settings(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_repository_config_and_missing_file(tmp_path):
    config, settings = load_gait_settings(REPO / "configs" / "gait.toml")
    assert config.labels == ALL_LABELS
    # The committed recipe: the paper's rates, a shorter schedule (see configs/gait.toml).
    assert settings == GaitTrainSettings(epochs=70, stride=30, lr_decay=0.98,
                                         teacher_forcing_decay=0.95)
    with pytest.raises(ConfigError, match="not found"):
        load_gait_settings(tmp_path / "missing.toml")


def test_command_reports_config_errors_and_resume_without_checkpoint(tmp_path):
    import typer

    from emotive.commands.train import train_gait_command

    app = typer.Typer()
    app.command()(train_gait_command)
    bad = tmp_path / "bad.toml"
    bad.write_text("[train]\nbatch_size = 'x'")
    result = CliRunner().invoke(app, ["--config", str(bad), "--out", str(tmp_path / "o")])
    assert isinstance(result.exception, ConfigError)
    assert "[train] batch_size" in str(result.exception)
    with pytest.raises(ConfigError, match="no checkpoint to resume"):
        train_gait(CONFIG, SETTINGS, progress=False, out_dir=tmp_path, resume=True,
                   data={"train": None})


@pytest.mark.data
def test_fine_tuning_starts_from_a_checkpoint_with_other_loss_weights(data, tmp_path):
    base = run(data, tmp_path / "base", replace(SETTINGS, epochs=1))
    settings = replace(SETTINGS, epochs=1, init_from=str(tmp_path / "base" / "best.pt"),
                       initial_teacher_forcing=0.0, learning_rate=1e-12)
    tuned = train_gait(replace(CONFIG, amplitude_weight=2.0), settings, progress=False,
                       out_dir=tmp_path / "tuned", data=data)
    # A vanishing learning rate: the tuned weights are the starting checkpoint's.
    for k, v in base.network.state_dict().items():
        torch.testing.assert_close(tuned.network.state_dict()[k], v, rtol=0, atol=1e-9)
    row = tuned.history[0]
    assert row["teacher_forcing"] == 0.0 and row["train_amplitude"] > 0
    with pytest.raises(ConfigError, match=r"differs in \['gru_hidden'\]"):
        train_gait(replace(CONFIG, gru_hidden=12), settings, progress=False,
                   out_dir=tmp_path / "other", data=data)
    with pytest.raises(ConfigError, match="not found"):
        train_gait(CONFIG, replace(settings, init_from=str(tmp_path / "none.pt")),
                   progress=False, out_dir=tmp_path / "none", data=data)


def test_the_committed_model_is_the_fine_tuning_of_the_committed_first_stage():
    from emotive.models.gait.model import default_checkpoint_path

    config, settings = load_gait_settings(REPO / "configs" / "gait-finetune.toml")
    assert config.amplitude_weight > 0 and settings.label_balance > 0
    stage1 = REPO / settings.init_from
    _, first_ckpt = load_gait_checkpoint(stage1)
    base_config, base_settings = load_gait_settings(REPO / "configs" / "gait.toml")
    # Written before the fine-tuning fields existed: those keep their defaults.
    assert base_config.to_dict() == {**base_config.to_dict(), **first_ckpt["config"]}
    assert base_settings.to_dict() == {**base_settings.to_dict(), **first_ckpt["train"]}
    _, ckpt = load_gait_checkpoint(default_checkpoint_path())
    assert ckpt["config"] == config.to_dict()
    # The checkpoint was trained from the repo root, when init_from was read from the working
    # folder; the recipe now names the same file from its own folder.
    trained = dict(ckpt["train"])
    assert (REPO / trained.pop("init_from")).resolve() == Path(settings.init_from).resolve()
    assert trained == {k: v for k, v in settings.to_dict().items() if k != "init_from"}
