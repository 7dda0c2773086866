"""Data-parallel training (emotive.models.distributed): two gloo processes train the gait network
as one process does on the same global batch (checkpoint keys, log columns, resume, loss within
1 %), a failing process brings the job down in one line, and the checks of --nproc."""

from __future__ import annotations

import csv
from dataclasses import replace

import numpy as np
import pytest
import torch
import torch.distributed as dist

from cli_helpers import run_main
from emotive.data.emotion import ALL_LABELS
from emotive.errors import ConfigError
from emotive.models.distributed import (
    TrainingProcessError,
    World,
    available_cpus,
    check_nproc,
    current_world,
    launch,
    one_process_only,
    run_parallel,
)
from emotive.models.gait import GaitConfig
from emotive.models.gait.data import load_gait_data
from emotive.models.gait.training import CSV_COLUMNS, GaitTrainSettings, train_gait

#: Seconds a process waits for the others before giving up: the tests never wait that long
#: unless the launcher fails to stop a process, and then they fail instead of hanging.
TIMEOUT = 60.0

CONFIG = GaitConfig(
    labels=ALL_LABELS, enc1_hidden=16, enc1_out=8, enc2_hidden=16, enc2_out=8, gru_hidden=24,
    root_hidden=8, versor_hidden=24,
)
SETTINGS = GaitTrainSettings(
    epochs=1, batch_size=8, window=12, stride=24, learning_rate=3e-3,
    teacher_forcing_decay=0.5, datasets=("bandai-namco-1",), max_clips=2,
)

needs_two_cpus = pytest.mark.skipif(available_cpus() < 2, reason="needs 2 CPUs")


@pytest.fixture(scope="module")
def data(bandai1_dir):
    return load_gait_data(CONFIG, SETTINGS.datasets, SETTINGS.window, SETTINGS.stride,
                          max_clips=SETTINGS.max_clips)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return rows


def two_processes(data, out_dir, settings, **kwargs):
    return launch(train_gait, (CONFIG, settings),
                  dict(progress=False, out_dir=out_dir, data=data, seed=3, **kwargs), 2, TIMEOUT)


def assert_close(a, b, name):
    assert abs(float(a) - float(b)) <= 0.01 * abs(float(b)), (name, a, b)


@needs_two_cpus
@pytest.mark.data
def test_two_processes_train_as_one_on_the_same_global_batch(data, tmp_path):
    # The last batch is short: its rows are shared out unevenly.
    assert len(data["train"]) % SETTINGS.batch_size
    one = train_gait(CONFIG, SETTINGS, progress=False, out_dir=tmp_path / "one", data=data,
                     seed=3)
    two = two_processes(data, tmp_path / "two", SETTINGS)
    assert sorted(p.name for p in (tmp_path / "two").iterdir()) == ["best.pt", "last.pt",
                                                                    "log.csv"]
    rows_one, rows_two = read_csv(tmp_path / "one" / "log.csv"), read_csv(tmp_path / "two"
                                                                          / "log.csv")
    assert tuple(rows_two[0]) == tuple(rows_one[0]) == CSV_COLUMNS and len(rows_two) == 1
    for column in ("train_total", "val_total", "train_motion", "val_pose"):
        assert_close(rows_two[0][column], rows_one[0][column], column)
    assert rows_two[0]["lr"] == rows_one[0]["lr"]
    for name in ("last.pt", "best.pt"):
        a = torch.load(tmp_path / "one" / name, weights_only=True)
        b = torch.load(tmp_path / "two" / name, weights_only=True)
        assert set(a) == set(b) and set(a["state"]) == set(b["state"])
        assert (a["epoch"], a["seed"], a["train"]) == (b["epoch"], b["seed"], b["train"])
    # The random state after the epoch is the same: every process drew what one process draws.
    a = torch.load(tmp_path / "one" / "last.pt", weights_only=True)
    b = torch.load(tmp_path / "two" / "last.pt", weights_only=True)
    assert a["rng"]["numpy"] == b["rng"]["numpy"]
    for k, v in one.network.state_dict().items():
        torch.testing.assert_close(two.network.state_dict()[k], v, rtol=1e-3, atol=1e-4)

    # Resume on two processes (process 0 reads last.pt and sends it) as on one.
    longer = replace(SETTINGS, epochs=2)
    one = train_gait(CONFIG, longer, progress=False, out_dir=tmp_path / "one", data=data,
                     seed=3, resume=True)
    two = two_processes(data, tmp_path / "two", longer, resume=True)
    rows_one, rows_two = read_csv(tmp_path / "one" / "log.csv"), read_csv(tmp_path / "two"
                                                                          / "log.csv")
    assert [r["epoch"] for r in rows_two] == ["1", "2"]
    assert len(two.history) == 2 and two.history[0]["train_total"] == float(
        rows_two[0]["train_total"])
    for column in ("train_total", "val_total"):
        assert_close(rows_two[1][column], rows_one[1][column], column)
    assert torch.load(tmp_path / "two" / "last.pt", weights_only=True)["epoch"] == 2


@needs_two_cpus
@pytest.mark.data
def test_two_processes_train_the_classifier_as_one(bandai1_dir):
    from emotive.eval.classifier import ClassifierConfig
    from emotive.eval.classifier_training import load_tracks, split_features, train_classifier

    tracks = [t for t in load_tracks(("bandai-namco-1",))
              if t.style in ("happy", "sad", "angry", "normal") and t.content == "walk"]
    config = replace(ClassifierConfig(datasets=("bandai-namco-1",)), augment_copies=0, epochs=2,
                     steps_per_epoch=3, batch_size=16)
    data = split_features(tracks, config)
    one = train_classifier(config, data=data)
    two = launch(train_classifier, (config,), {"data": data}, 2, TIMEOUT)
    # Dropout included: every process draws the global batch's masks and keeps its rows.
    for k, v in one.net.state_dict().items():
        torch.testing.assert_close(two.net.state_dict()[k], v, rtol=1e-4, atol=1e-5)
    assert two.metrics["val"]["confusion"] == one.metrics["val"]["confusion"]


def test_batch_dropout_draws_one_process_masks():
    net = torch.nn.Sequential(torch.nn.Identity(), torch.nn.Dropout(0.5))
    x = torch.randn(7, 3)
    torch.manual_seed(1)
    whole = net(x)
    parts = []
    for world in (World(0, 2), World(1, 2)):
        torch.manual_seed(1)
        with world.batch_dropout(net, 7):
            parts.append(net(x[world.rows(7)]))
        assert isinstance(net[1], torch.nn.Dropout)
    assert torch.equal(torch.cat(parts), whole)


def fail_on_process_1(kind: str) -> None:
    """Process 1 fails at once; process 0 waits for it in a collective, as in a training."""
    if current_world().rank == 1:
        if kind == "config":
            raise ConfigError("bad.toml: [train] epochs: epochs must be an integer >= 1")
        raise RuntimeError("a bug\nwith a second line")
    dist.all_reduce(torch.zeros(3))


@needs_two_cpus
def test_a_failing_process_stops_the_job_with_one_error_line():
    with pytest.raises(TrainingProcessError) as info:
        launch(fail_on_process_1, ("bug",), {}, 2, TIMEOUT)
    message = str(info.value)
    assert message == ("training process 1 of 2 failed: RuntimeError: a bug; every process "
                       "was stopped")
    # A user's error in a process is raised as itself, as one process would raise it.
    with pytest.raises(ConfigError, match=r"^bad.toml: \[train\] epochs: epochs must be"):
        launch(fail_on_process_1, ("config",), {}, 2, TIMEOUT)


def test_rows_and_parts_share_out_a_global_batch():
    for n, size in ((8, 2), (7, 2), (5, 3), (3, 3)):
        worlds = [World(rank, size) for rank in range(size)]
        rows = [np.arange(n)[w.rows(n)] for w in worlds]
        assert np.concatenate(rows).tolist() == list(range(n))
        assert max(map(len, rows)) - min(map(len, rows)) <= 1
        weights = np.arange(n) % 3 * 1.0
        parts = np.array([w.split(n, weights, np.zeros(n))[1] for w in worlds])
        np.testing.assert_allclose(parts[:, :2].sum(0), 1.0)
        assert (parts[:, 2] == 0).all()
    assert World().split(4, np.zeros(4)) == (slice(0, 4), [1.0, 1.0])
    with pytest.raises(ConfigError, match="fewer rows than the 3 training processes"):
        World(0, 3).split(2)
    with pytest.raises(ConfigError, match=r"\[train\] batch_size 2: fewer rows than the 3"):
        World(0, 3).check_batch(2, "[train] batch_size")


def test_one_process_helpers_change_nothing():
    world = current_world()
    assert world == World() and world.is_main
    rows = [{"total": 1.5}, {"total": 2.5}]
    assert world.merge_rows(rows, ("total",)) is rows
    assert world.sum_terms({"total": 3.0}, 4, ("total",)) == ({"total": 3.0}, 4)
    assert world.from_main(lambda: 5) == 5
    assert run_parallel(lambda x, y=0: x + y, 2, y=3) == 5


def test_nproc_and_torchrun_checks(monkeypatch, capsys):
    for bad in (0, available_cpus() + 1):
        with pytest.raises(ConfigError, match=f"--nproc {bad}: give 1 to"):
            check_nproc(bad)
    code, _, err = run_main(monkeypatch, capsys, "train", "gait", "--nproc", "0")
    assert code == 2 and "--nproc" in err and len(err.strip().splitlines()) == 1
    # Started by torchrun: torchrun sets the processes, and a one-process trainer is refused.
    monkeypatch.setenv("WORLD_SIZE", "2")
    with pytest.raises(ConfigError, match="leave out --nproc"):
        run_parallel(print, nproc=2)
    with pytest.raises(ConfigError, match="runs in one process"):
        one_process_only()
