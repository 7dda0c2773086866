"""The shared epoch loop: log rows, best/last checkpoints, Ctrl-C."""

from __future__ import annotations

import csv

import pytest
import torch

from emotive.models.epochs import EpochOutcome, TrainingLog, resumed_log, run_epochs

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


def test_ctrl_c_saves_the_weights_with_the_interrupted_epochs_start(tmp_path):
    log = TrainingLog()
    with pytest.raises(KeyboardInterrupt):
        loop(tmp_path, log, [3.0, 1.0, 2.0], interrupt_at=(1, 2))
    last = saved(tmp_path / "last.pt")
    # Epoch 2 of 3 was interrupted after two updates: 5 in all, random state of its start (3).
    assert (last["epoch"], last["updates"], last["rng"]) == (1, 5, 3)
    assert [r["epoch"] for r in last["history"]] == [1]
    resumed = resumed_log(last)
    assert (resumed.start_epoch, resumed.best_val, len(resumed.history)) == (1, 3.0, 1)
    loop(tmp_path, resumed, [3.0, 1.0, 2.0])
    assert [r["epoch"] for r in resumed.history] == [1, 2, 3]


def test_ctrl_c_before_any_update_leaves_last_as_it_was(tmp_path):
    log = TrainingLog()
    loop(tmp_path, log, [3.0], epochs=1)
    before = saved(tmp_path / "last.pt")
    with pytest.raises(KeyboardInterrupt):
        loop(tmp_path, resumed_log(before), [3.0, 1.0], interrupt_at=(1, 0))
    assert saved(tmp_path / "last.pt") == before
