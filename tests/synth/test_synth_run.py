"""Runs on Ray: the small recipe gives 8 walks; 1 and 2 workers, a rerun, a full disk then a
rerun, a run killed with SIGKILL then restarted, and a two-node cluster all give the same bytes;
3 s walks (trajectories drawn again until novel) from the command line with 2 workers give the
bytes of 1 worker; a run stopped with SIGINT or SIGTERM leaves no Ray process behind.

The in-process runs share one local Ray of 2 CPUs (module fixture), so its workers load the
model once; the killed runs, the short-walk run and the cluster run are ``emotive synth``
processes, as users start them. Everything listens on 127.0.0.1 and is stopped at the end.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch
from ray_procs import descendants, wait_gone

from disk_faults import fill_disk
from emotive.errors import OutputError
from emotive.synth import SyntheticGaits, store, synthesize
from emotive.synth.recipe import Recipe, named_recipe

ray = pytest.importorskip("ray")

#: The small recipe: 2 paths x 3 emotions + 2 x 1 transitions, 4 s each, here a walk a shard.
SMALL = named_recipe("small", shard_size=1)
CLI_SMALL = ["--recipe", "small", "--shard-size", "1"]
EMOTIVE = str(Path(sys.executable).parent / "emotive")
#: Hang guard of the command-line runs (nothing is asserted about time).
RUN_TIMEOUT_S = 300
#: How long a stopped run's Ray processes may take to end; a run that does not stop Ray
#: leaves two of its agents for about a minute.
RAY_GONE_S = 30


def files(folder: Path) -> dict[str, str]:
    """sha256 of every file of a data set folder but its lock, by relative path."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name != store.LOCK}


def shas(folder: Path) -> set[str]:
    return set(pd.read_parquet(folder / "manifest.parquet")["sha256"])


@pytest.fixture(scope="module")
def local_ray():
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False,
             logging_level="ERROR", _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def reference(local_ray, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("synth") / "one-worker"
    report = synthesize(out, SMALL, workers=1, progress=False)
    assert (report.walks, report.shards, report.made, report.kept) == (8, 8, 8, 0)
    return out


def test_small_run_gives_eight_rows_a_card_and_a_dataset(reference):
    manifest = pd.read_parquet(reference / "manifest.parquet")
    assert len(manifest) == 8 and manifest["sha256"].is_unique
    assert list(manifest["kind"]) == ["constant"] * 6 + ["transition"] * 2
    assert list(manifest["path_id"]) == [0, 0, 0, 1, 1, 1, 0, 1]
    assert manifest["perceived"].isin(["happy", "sad", "angry", "neutral"]).all()
    assert manifest["unsure"].dtype == bool
    assert (manifest["frames"] == 121).all() and (manifest["path_deviation"] < 0.05).all()
    assert np.isfinite(manifest["foot_skate"]).all()
    moved = manifest[manifest["kind"] == "transition"]
    assert (moved["transition_from"] >= 0).all() and moved["transition_time"].between(1.6,
                                                                                      2.4).all()
    assert all(not np.allclose(a, b) for a, b in zip(moved["emotion"], moved["emotion_end"],
                                                     strict=True))
    card = (reference / "README.md").read_text()
    for words in ("CC BY-NC 4.0", "non-commercial use only", "**8 walks**", "SyntheticGaits",
                  "Novel trajectories", "What the classifier perceives"):
        assert words in card, words
    novelty = json.loads((reference / "novelty.json").read_text())
    assert ("None coincides" in card) if novelty["checked"] else ("was skipped" in card)

    walks = SyntheticGaits(reference, fields=("rotations", "world", "emotion", "path"))
    assert len(walks) == 8 and walks.labels == ("happy", "sad", "angry", "neutral")
    item = walks[7]
    assert item["rotations"].shape == (121, 22, 4) and item["world"].shape == (121, 27, 3)
    assert item["emotion"].shape == (121, 4) and item["path"].shape[1] == 2
    assert int(item["sample_id"]) == 7
    batch = next(iter(torch.utils.data.DataLoader(SyntheticGaits(reference), batch_size=4)))
    assert batch["rotations"].shape == (4, 121, 22, 4) and batch["root"].shape == (4, 121, 3)
    motion = walks.motion(3)
    assert np.allclose(motion.positions_with_end_sites(), walks[3]["world"].numpy(), atol=1e-4)
    assert all(walks.verify(k) for k in range(8))
    assert walks.row(6)["kind"] == "transition"


def test_two_workers_give_the_same_bytes_and_a_rerun_does_nothing(reference, tmp_path):
    out = tmp_path / "two-workers"
    synthesize(out, SMALL, workers=2, progress=False)
    assert files(out) == files(reference)
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    again = synthesize(out, SMALL, workers=2, progress=False)
    assert (again.made, again.kept) == (0, 8)
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == stamps


def test_a_full_disk_stops_cleanly_and_a_rerun_finishes(reference, tmp_path, monkeypatch):
    out = tmp_path / "full"
    write = store.Folder.write_files
    calls = []

    def filling(folder, written):
        calls.append(1)
        if len(calls) == 3:             # recipe, a shard, then the disk is full
            fill_disk(monkeypatch)
        return write(folder, written)

    monkeypatch.setattr(store.Folder, "write_files", filling)
    with pytest.raises(OutputError, match="the disk is full"):
        synthesize(out, SMALL, workers=1, progress=False)
    monkeypatch.undo()                  # space again
    left = sorted(p.name for p in (out / "shards").iterdir())
    assert left == ["shard-00000.npz"]           # whole, and nothing half-written beside it
    assert not (out / "manifest.parquet").exists()
    report = synthesize(out, SMALL, workers=1, progress=False)
    assert (report.made, report.kept) == (7, 1)
    assert files(out) == files(reference)


def test_a_killed_run_continues_where_it_stopped(reference, tmp_path):
    out = tmp_path / "killed"
    proc = subprocess.Popen([EMOTIVE, "synth", "--out", str(out), *CLI_SMALL, "--workers", "1"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    try:
        # Each finished shard prints a line after its file is written: kill after the first.
        for line in proc.stderr:
            if line.startswith("synth: 1/8"):
                break
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=RUN_TIMEOUT_S)
    finally:
        _stop_group(proc)
    assert proc.returncode == -signal.SIGKILL
    assert not (out / "manifest.parquet").exists()
    done = sorted((out / "shards").iterdir())
    assert 1 <= len(done) < 8
    assert all(np.load(p)["rows"].size == 1 for p in done)
    report = synthesize(out, SMALL, workers=1, progress=False)
    assert report.kept == len(done) and report.made == 8 - len(done)
    assert files(out) == files(reference)


def _stop_group(proc: subprocess.Popen) -> None:
    """Kill what the run started (its local Ray: same process group) and close its pipe."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.stderr.close()
    proc.wait(timeout=RUN_TIMEOUT_S)


def test_short_walks_from_the_command_line_match_one_worker(local_ray, tmp_path):
    """3 s walks, seed 0: with the data its trajectory 1 is a later draw (the first two follow
    clips of the data); 2 workers in a command give the bytes of 1 worker here."""
    short = replace(SMALL, seconds=3.0)
    one = tmp_path / "one"
    synthesize(one, short, workers=1, progress=False)
    two = tmp_path / "two"
    result = subprocess.run([EMOTIVE, "synth", "--out", str(two), *CLI_SMALL, "--seconds", "3",
                             "--workers", "2", "--no-progress"], capture_output=True, text=True,
                            timeout=RUN_TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    assert files(two) == files(one)
    checked = json.loads((one / "novelty.json").read_text())
    if checked["checked"]:
        assert not any(p["coincides"] for p in checked["paths"])
        assert [p["draw"] for p in checked["paths"]] == [0, 2]


@pytest.mark.parametrize(("stop", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_stopped_run_leaves_no_ray_process(tmp_path, stop, code):
    out = tmp_path / "stopped"
    proc = subprocess.Popen([EMOTIVE, "synth", "--out", str(out), *CLI_SMALL, "--workers", "2"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            start_new_session=True)
    try:
        for line in proc.stderr:         # a line per shard written: Ray and its workers run
            if line.startswith("synth: 1/8"):
                break
        started = descendants(proc.pid)
        proc.send_signal(stop)
        proc.wait(timeout=RUN_TIMEOUT_S)
        left = wait_gone(started, RAY_GONE_S)
    finally:
        _stop_group(proc)
    assert proc.returncode == code
    assert len(started) >= 4             # GCS server, raylet, its agents, workers
    assert not left, f"{len(left)} of the run's {len(started)} processes still run"
    assert 1 <= len(list((out / "shards").iterdir())) < 8
    assert not (out / "manifest.parquet").exists()


def test_a_two_node_cluster_gives_the_same_data_set(reference, tmp_path):
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, head_node_args={
        "num_cpus": 1, "node_ip_address": "127.0.0.1", "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=1, node_ip_address="127.0.0.1")
        cluster.wait_for_nodes()
        out = tmp_path / "cluster"
        # Ray turns 127.0.0.1 into the machine's address unless told the cluster is this
        # machine alone; the nodes above listen on 127.0.0.1.
        env = {**os.environ, "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}
        result = subprocess.run([EMOTIVE, "synth", "--out", str(out), *CLI_SMALL, "--address",
                                 cluster.address, "--no-progress"], env=env,
                                capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
        assert result.returncode == 0, result.stderr
        assert f"Ray cluster at {cluster.address}, 2 workers" in result.stderr
    finally:
        cluster.shutdown()
    assert shas(out) == shas(reference)
    assert files(out) == files(reference)


def test_a_check_skipped_without_the_data_runs_again_later(local_ray, tmp_path, monkeypatch):
    from emotive.synth import novelty

    out = tmp_path / "later"
    one = Recipe(paths=1, emotions=1, transitions=0, seconds=4.0)
    monkeypatch.setattr(novelty, "data_root_paths", lambda: "the data set x is not available")
    synthesize(out, one, workers=1, progress=False)
    assert "was skipped" in (out / "README.md").read_text()
    monkeypatch.undo()
    shard = (out / "shards" / "shard-00000.npz").stat().st_mtime_ns
    report = synthesize(out, one, workers=1, progress=False)
    assert report.made == 0 and (out / "shards" / "shard-00000.npz").stat().st_mtime_ns == shard
    checked = json.loads((out / "novelty.json").read_text())["checked"]
    assert checked == isinstance(novelty.data_root_paths(), tuple)
    assert ("None coincides" if checked else "was skipped") in (out / "README.md").read_text()
