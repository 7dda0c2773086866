"""Verifying an unpacked data set against its manifest, repairing it, and removing what a
killed unpack left behind."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from emotive.data import registry, store
from emotive.data.manifest import manifest_path
from emotive.errors import DataError

#: A child process: register the data set it is given, then unpack it, pausing half-way
#: (after writing a ready file) until the go file appears.
CHILD = """
import json, sys, time
from pathlib import Path
from emotive.data import registry, store
from emotive.data.registry import DatasetInfo
spec, archive, ready, go, force = json.loads(sys.argv[1]), *map(Path, sys.argv[2:5]), sys.argv[5]
fields = {k: tuple(v) if isinstance(v, list) else v for k, v in spec.items()}
registry.REGISTRY[spec["name"]] = DatasetInfo(**fields)
unpack = store.unpack

def paused(tar, members, dest):
    half = len(members) // 2
    hashes = unpack(tar, members[:half], dest)
    ready.touch()
    deadline = time.monotonic() + 300
    while not go.exists() and time.monotonic() < deadline:
        time.sleep(0.01)
    return {**hashes, **unpack(tar, members[half:], dest)}

store.unpack = paused
store.extract_archive(spec["name"], archive, force=force == "force")
"""


def start_paused_unpack(fake, home: Path, tmp: Path, force: bool) -> tuple[subprocess.Popen, Path]:
    """Start a child unpacking ``fake`` into ``home``; return it, paused half-way, and its go
    file. Waits on the ready file (however busy the machine); the limit is a hang guard."""
    ready, go = tmp / "ready", tmp / "go"
    env = dict(os.environ, EMOTIVE_HOME=str(home))
    argv = [json.dumps(dataclasses.asdict(fake.info)), str(fake.archive), str(ready), str(go),
            "force" if force else "first"]
    proc = subprocess.Popen([sys.executable, "-c", CHILD, *argv], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not ready.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert ready.exists(), proc.communicate()[1]
    return proc, go


def hidden(home: Path) -> list[str]:
    """Hidden entries of the cache's data set and archive folders (temporary files, locks)."""
    return sorted(p.name for d in ("datasets", "archives") if (home / d).is_dir()
                  for p in (home / d).iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("force", [False, True], ids=["first-unpack", "force"])
def test_kill_during_unpack_then_rerun_leaves_nothing(force, fake, tmp_path, isolated_home,
                                                      monkeypatch):
    monkeypatch.setenv("EMOTIVE_DATA", str(fake.archive.parent))
    if force:
        store.extract_archive("fake-1", fake.archive)
    proc, _ = start_paused_unpack(fake, isolated_home, tmp_path, force)
    left = store.leftovers("fake-1")
    assert len(left) == 1 and left[0].name.startswith(f".{fake.info.folder}.")
    assert any(left[0].rglob("*.bvh"))
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=120)
    assert store.leftovers("fake-1") == left  # a killed process cannot clean up
    folder = store.dataset_dir("fake-1")  # the rerun
    assert store.leftovers("fake-1") == [] and hidden(isolated_home) == []
    assert store.verify("fake-1").clean
    assert len(list((folder / "data").glob("*.bvh"))) == 18


def test_concurrent_unpack_holding_the_lock_is_never_touched(fake, tmp_path, isolated_home):
    folder = store.extract_archive("fake-1", fake.archive)
    proc, go = start_paused_unpack(fake, isolated_home, tmp_path, force=True)
    try:
        live = store.leftovers("fake-1")
        assert len(live) == 1
        before = sorted(p.relative_to(live[0]) for p in live[0].rglob("*"))
        assert store.dataset_dir("fake-1") == folder  # finds the lock held: leaves it alone
        assert sorted(p.relative_to(live[0]) for p in live[0].rglob("*")) == before
        with pytest.raises(DataError, match="another process has been unpacking fake-1"):
            with store.file_lock(store._lock_path(fake.info), what="unpacking fake-1",
                                 timeout_s=0.1):
                pass
    finally:
        go.touch()
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert store.leftovers("fake-1") == [] and store.verify("fake-1").clean


def test_leftover_manifest_and_archive_copies_removed(fake, isolated_home):
    store.fetch("fake-1", fake.archive)
    datasets, archives = isolated_home / "datasets", isolated_home / "archives"
    junk = [datasets / f".{fake.info.folder}.manifest.json.abcd_123.tmp.json",
            archives / f".{fake.info.archive}.zz99xx00.tmp"]
    for path in junk:
        path.write_text("half")
    part = archives / f"{fake.info.archive}.part"
    part.write_text("a download to resume")
    keep = datasets / ".Other-Motiondataset.abcd1234"  # another data set's, not ours
    keep.mkdir()
    assert store.leftovers("fake-1") == sorted(junk)
    store.fetch_archive("fake-1", fake.archive)
    assert not junk[1].exists() and part.exists()
    store.verify("fake-1")
    assert store.leftovers("fake-1") == [] and keep.exists()


def damage(folder: Path) -> dict[str, bytes]:
    """Flip one byte of a file, delete one, truncate one and add one; return the originals."""
    data = folder / "data"
    names = ("dataset-1_walk_happy_001.bvh", "dataset-1_bow_normal_002.bvh",
             "dataset-1_walk-left_sad_001.json")
    originals = {n: (data / n).read_bytes() for n in names}
    raw = bytearray(originals[names[0]])
    raw[len(raw) // 3] ^= 0x20
    (data / names[0]).write_bytes(raw)
    (data / names[1]).unlink()
    os.truncate(data / names[2], 3)
    (data / "dataset-1_walk_happy_099.bvh").write_text("not from the archive")
    return originals


def test_verify_finds_damage_and_fetch_repairs_it(fake, isolated_home):
    folder = store.fetch("fake-1", fake.archive)
    assert store.verify("fake-1").clean
    originals = damage(folder)
    found = store.verify("fake-1")
    assert [(p.path, p.kind) for p in found.problems] == [
        ("data/dataset-1_bow_normal_002.bvh", "missing"),
        ("data/dataset-1_walk-left_sad_001.json", "damaged"),
        ("data/dataset-1_walk_happy_001.bvh", "damaged"),
        ("data/dataset-1_walk_happy_099.bvh", "extra"),
    ]
    assert (found.count("damaged"), found.count("missing"), found.count("extra")) == (2, 1, 1)
    assert store.verify("fake-1").problems == found.problems  # verify changes nothing
    os.remove(isolated_home / "archives" / fake.info.archive)  # repair from the source given
    assert store.fetch("fake-1", fake.archive) == folder
    assert store.verify("fake-1").clean
    for name, raw in originals.items():
        assert (folder / "data" / name).read_bytes() == raw
    assert not (folder / "data" / "dataset-1_walk_happy_099.bvh").exists()
    assert hidden(isolated_home) == []


def test_repair_touches_nothing_when_intact(fake, isolated_home, monkeypatch):
    store.fetch("fake-1", fake.archive)

    def no_archive(*args):
        raise AssertionError("an intact data set needs no archive")

    monkeypatch.setattr(store, "_archive_for_repair", no_archive)
    assert store.repair("fake-1").clean


def test_repair_restores_folder_gone_and_marker(fake, isolated_home):
    folder = store.fetch("fake-1", fake.archive)
    (folder / store.MARKER).unlink()
    found = store.verify("fake-1")
    assert [(p.path, p.kind) for p in found.problems] == [(store.MARKER, "missing")]
    store.repair("fake-1")
    assert store.is_cached("fake-1") and store.verify("fake-1").clean
    for path in sorted(folder.rglob("*"), reverse=True):
        path.rmdir() if path.is_dir() else path.unlink()
    folder.rmdir()
    assert [p.path for p in store.verify("fake-1").problems] == ["."]
    store.repair("fake-1", fake.archive)
    assert store.verify("fake-1").clean and len(list(folder.rglob("*.bvh"))) == 18


def test_verify_never_unpacked_is_a_typed_error(fake, no_shared_data):
    with pytest.raises(DataError, match=r"'fake-1' is not unpacked in the cache .*nothing to "
                                        r"verify; run `emotive data fetch fake-1` first"):
        store.verify("fake-1")


def test_cache_without_manifest_gets_one_from_the_archive(fake, isolated_home, no_shared_data):
    folder = store.fetch("fake-1", fake.archive)
    manifest = manifest_path(folder)
    made = manifest.read_text()
    manifest.unlink()
    assert store.verify("fake-1").clean  # from the cache's archive
    assert manifest.read_text() == made
    manifest.unlink()
    os.remove(isolated_home / "archives" / fake.info.archive)
    with pytest.raises(DataError, match=r"manifest.json is missing or out of date and no "
                                        r"archive .*emotive data fetch fake-1 --force"):
        store.verify("fake-1")
    (folder / "data" / "dataset-1_bow_happy_001.bvh").unlink()
    store.fetch("fake-1", fake.archive)  # makes the manifest from the source, then repairs
    assert manifest.read_text() == made and store.verify("fake-1").clean


def test_real_datasets_verify_clean(home):
    for name in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        found = store.verify(name)
        assert found.clean, found.problems[:5]
        on_disk = [p for p in found.folder.rglob("*") if p.is_file()]
        assert found.files == len(on_disk) - 1  # all but the marker
        assert found.hashed_bytes == sum(p.stat().st_size for p in on_disk if
                                         p.name != store.MARKER)
        assert sum(p.suffix == ".bvh" for p in on_disk) == registry.get_dataset(name).clips
