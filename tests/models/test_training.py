"""The shared training machinery (emotive.models.training): the epoch loop, log rows,
best/last checkpoints, Ctrl-C."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest
import torch

from emotive.errors import ConfigError, OutputError
from emotive.models.training import (
    EpochOutcome,
    TrainingLog,
    check_resumable,
    read_checkpoint,
    restore_rng_state,
    resumed_log,
    rng_state,
    run_epochs,
    save_checkpoint,
    seed_everything,
)

COLUMNS = ("epoch", "loss", "seconds")


def loop(tmp_path, log, scores, interrupt_at=None, epochs=None):
    """Run the loop over a fake trainer whose epoch ``e`` scores ``scores[e]``; a state counter
    stands for the weights and the random state."""
    state = {"updates": 0}

    def run_epoch(epoch, batch_done):
        for batch in range(3):
            if (epoch, batch) == interrupt_at:
                raise KeyboardInterrupt
            state["updates"] += 1
            batch_done(f"batch {batch}")
        return EpochOutcome({"loss": scores[epoch]}, scores[epoch], f"loss {scores[epoch]}")

    def checkpoint(done, rng):
        return {"epoch": done, "rng": rng, "best_val": log.best_val,
                "history": list(log.history), "updates": state["updates"]}

    run_epochs(log, epochs or len(scores), 3, tmp_path, COLUMNS, run_epoch, checkpoint,
               lambda: state["updates"], progress=False)


def saved(path):
    return torch.load(path, weights_only=True)


def test_the_loop_logs_every_epoch_and_keeps_the_best(tmp_path):
    log = TrainingLog()
    loop(tmp_path, log, [3.0, 1.0, 2.0])
    assert [r["epoch"] for r in log.history] == [1, 2, 3]
    assert [r["loss"] for r in log.history] == [3.0, 1.0, 2.0]
    assert log.best_val == 1.0
    assert saved(tmp_path / "best.pt")["epoch"] == 2
    assert saved(tmp_path / "last.pt")["epoch"] == 3
    with open(tmp_path / "log.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == COLUMNS and [r["loss"] for r in rows] == ["3.0", "1.0", "2.0"]


def test_ctrl_c_keeps_last_at_the_last_finished_epoch(tmp_path, capsys):
    log = TrainingLog()
    with pytest.raises(KeyboardInterrupt):
        loop(tmp_path, log, [3.0, 1.0, 2.0], interrupt_at=(1, 2))
    last = saved(tmp_path / "last.pt")
    # Epoch 2 of 3 was interrupted after two updates: last.pt stays at the end of epoch 1
    # (3 updates, random state 3), and the log and its file say the same.
    assert (last["epoch"], last["updates"], last["rng"]) == (1, 3, 3)
    assert [r["epoch"] for r in last["history"]] == [1]
    assert [r["epoch"] for r in log.history] == [1] and log.best_val == 3.0
    with open(tmp_path / "log.csv", newline="") as f:
        assert [r["epoch"] for r in csv.DictReader(f)] == ["1"]
    assert "interrupted in epoch 2" in capsys.readouterr().err
    resumed = resumed_log(last)
    assert (resumed.start_epoch, resumed.best_val, len(resumed.history)) == (1, 3.0, 1)
    loop(tmp_path, resumed, [3.0, 1.0, 2.0])
    assert [r["epoch"] for r in resumed.history] == [1, 2, 3]


def test_ctrl_c_in_the_first_epoch_saves_nothing(tmp_path, capsys):
    log = TrainingLog()
    with pytest.raises(KeyboardInterrupt):
        loop(tmp_path, log, [3.0, 1.0], interrupt_at=(0, 1))
    assert list(tmp_path.iterdir()) == [] and log.history == []
    assert "nothing saved; run again" in capsys.readouterr().err


def test_ctrl_c_before_any_update_leaves_last_as_it_was(tmp_path):
    log = TrainingLog()
    loop(tmp_path, log, [3.0], epochs=1)
    before = saved(tmp_path / "last.pt")
    with pytest.raises(KeyboardInterrupt):
        loop(tmp_path, resumed_log(before), [3.0, 1.0], interrupt_at=(1, 0))
    assert saved(tmp_path / "last.pt") == before


def test_read_checkpoint_turns_every_failure_into_a_config_error(tmp_path):
    def build(ckpt):
        return ckpt["value"] * 2

    good = tmp_path / "good.pt"
    torch.save({"value": 21}, good)
    assert read_checkpoint(good, "a test checkpoint", build, "fix it") == (42, {"value": 21})
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a checkpoint")
    foreign = tmp_path / "foreign.pt"
    torch.save({"other": 1}, foreign)
    for path, words in ((tmp_path / "missing.pt", "checkpoint not found; fix it"),
                        (tmp_path, "is a folder"),
                        (garbage, "not a test checkpoint"),
                        (foreign, "not a test checkpoint ('value'); fix it")):
        with pytest.raises(ConfigError, match=re.escape(words)) as info:
            read_checkpoint(path, "a test checkpoint", build, "fix it")
        assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_check_resumable_allows_only_more_epochs(tmp_path):
    saved = {"config": {"size": 3}, "train": {"epochs": 2, "lr": 0.1}}
    check_resumable(tmp_path, saved, {"size": 3}, {"epochs": 5, "lr": 0.1}, 0)
    with pytest.raises(ConfigError, match=r"another \[model\] config"):
        check_resumable(tmp_path, saved, {"size": 4}, {"epochs": 2, "lr": 0.1}, 0)
    with pytest.raises(ConfigError, match=r"other \[train\] settings"):
        check_resumable(tmp_path, saved, {"size": 3}, {"epochs": 2, "lr": 0.2}, 0)


def test_random_state_round_trips_numpy_and_torch():
    for generator in (None, torch.Generator().manual_seed(5)):
        rng = seed_everything(7)
        state = rng_state(rng, generator)
        first = rng.random(3), torch.rand(3, generator=generator)
        restore_rng_state(rng, state, generator)
        again = rng.random(3), torch.rand(3, generator=generator)
        assert (first[0] == again[0]).all() and torch.equal(first[1], again[1])


@pytest.mark.parametrize("failure", [
    OSError(28, "No space left on device"),
    RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos 64 vs 0\nmore"),
])
def test_a_failed_save_is_an_output_error_keeping_the_previous_file(tmp_path, monkeypatch,
                                                                    failure):
    path = tmp_path / "last.pt"
    save_checkpoint(path, {"epoch": 1})

    def full_disk(obj, f):
        Path(f).write_bytes(b"half")
        raise failure

    monkeypatch.setattr(torch, "save", full_disk)
    with pytest.raises(OutputError) as info:
        save_checkpoint(path, {"epoch": 2})
    message = str(info.value)
    assert "\n" not in message and "enforce" not in message
    assert "cannot write" in message and str(path) in message
    assert "free" in message
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["last.pt"]
    assert saved(path) == {"epoch": 1}


def test_a_failed_save_in_training_says_which_epoch_last_keeps(tmp_path, monkeypatch):
    loop(tmp_path, TrainingLog(), [3.0], epochs=1)
    real_save = torch.save

    def fail_on_epoch_2(obj, f):
        if obj["epoch"] == 2:
            raise RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos")
        real_save(obj, f)

    monkeypatch.setattr(torch, "save", fail_on_epoch_2)
    resumed = resumed_log(saved(tmp_path / "last.pt"))
    with pytest.raises(OutputError, match=r"stopped after epoch 2, .*last\.pt keeps epoch 1$"):
        loop(tmp_path, resumed, [3.0, 2.0, 1.0])
    monkeypatch.undo()
    assert saved(tmp_path / "last.pt")["epoch"] == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["best.pt", "last.pt", "log.csv"]
