"""Many processes unpacking into one empty cache at once, and the lock that makes it safe."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from emotive.data import registry, store
from emotive.data.lock import file_lock
from emotive.errors import DataError

#: A child process: register the data set it is given, wait for the start signal, then ask for
#: the data set folder and print what it holds.
CHILD = """
import json, os, sys, time
from pathlib import Path
from emotive.data import registry, store
from emotive.data.registry import DatasetInfo
spec, go = json.loads(sys.argv[1]), Path(sys.argv[2])
fields = {k: tuple(v) if isinstance(v, list) else v for k, v in spec.items()}
registry.REGISTRY[spec["name"]] = DatasetInfo(**fields)
(go.parent / f"{go.name}.ready.{os.getpid()}").touch()
deadline = time.monotonic() + 60
while not go.exists() and time.monotonic() < deadline:
    time.sleep(0.002)
folder = store.dataset_dir(spec["name"])
files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
print(json.dumps({"folder": str(folder), "files": files}))
"""


def unpack_at_once(info: registry.DatasetInfo, shared: Path, home: Path, tmp: Path, n: int):
    """Start ``n`` processes doing their first ``dataset_dir`` into ``home`` together."""
    go = tmp / f"go-{n}"
    env = dict(os.environ, EMOTIVE_HOME=str(home), EMOTIVE_DATA=str(shared))
    spec = json.dumps(dataclasses.asdict(info))
    procs = [
        subprocess.Popen([sys.executable, "-c", CHILD, spec, str(go)], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(n)
    ]
    # Every child imported and at the start line (each says so with a file), however busy the
    # machine; the limit only guards against a hang.
    deadline = time.monotonic() + 300
    while (len(list(tmp.glob(f"{go.name}.ready.*"))) < n and time.monotonic() < deadline
           and all(proc.poll() is None for proc in procs)):
        time.sleep(0.05)
    go.touch()
    results = []
    for proc in procs:
        out, err = proc.communicate(timeout=120)
        results.append((proc.returncode, out, err))
    return results


def expected_files(source: Path) -> list[str]:
    return sorted([str(p.relative_to(source)) for p in source.rglob("*")] + [store.MARKER])


@pytest.mark.parametrize("n", [4, 8])
def test_first_unpack_by_many_processes(n, fake, tmp_path, isolated_home):
    results = unpack_at_once(fake.info, fake.archive.parent, isolated_home, tmp_path, n)
    assert [rc for rc, _, _ in results] == [0] * n, [err for _, _, err in results]
    target = isolated_home / "datasets" / fake.info.folder
    want = expected_files(fake.folder)
    for _, out, _ in results:
        seen = json.loads(out)
        assert seen == {"folder": str(target), "files": want}
    # One complete folder and its manifest: no second copy, temporary folder or lock file.
    assert sorted(p.name for p in (isolated_home / "datasets").iterdir()) == [
        fake.info.folder, fake.info.folder + ".manifest.json"
    ]
    assert store.is_cached("fake-1")


def test_first_unpack_of_real_dataset1_by_four_processes(shared_data, tmp_path):
    info = registry.get_dataset("bandai-namco-1")
    home = tmp_path / "home"
    results = unpack_at_once(info, shared_data, home, tmp_path, 4)
    assert [rc for rc, _, _ in results] == [0] * 4, [err for _, _, err in results]
    listings = [json.loads(out) for _, out, _ in results]
    assert all(seen == listings[0] for seen in listings)
    assert sum(f.endswith(".bvh") for f in listings[0]["files"]) == info.clips
    assert sorted(p.name for p in (home / "datasets").iterdir()) == [
        info.folder, info.folder + ".manifest.json"
    ]


def test_lock_excludes_a_second_holder_and_times_out(tmp_path):
    lock = tmp_path / ".x.lock"
    with file_lock(lock, what="unpacking x"):
        start = time.monotonic()
        with pytest.raises(DataError, match=r"another process has been unpacking x .*lock"):
            with file_lock(lock, what="unpacking x", timeout_s=0.2):
                pass
        assert time.monotonic() - start >= 0.2
    assert not lock.exists()
    with file_lock(lock, what="unpacking x", timeout_s=0.2):
        assert lock.exists()
