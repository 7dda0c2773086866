"""Fixtures of the data tests: an isolated cache, a synthetic data set, a local HTTP server and
the real Bandai Namco archives unpacked once per session.

Every data test runs with ``EMOTIVE_HOME`` in a temporary folder; tests on real data ask for the
``home`` fixture, which points it at a session folder where each archive is unpacked once.
"""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import re
import tarfile
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from types import SimpleNamespace

import pytest

from emotive.data import registry, store
from emotive.data.registry import DatasetInfo

REPO = Path(__file__).resolve().parents[2]
REAL = ("bandai-namco-1", "bandai-namco-2-locomotion")


def require_data_or_skip(reason: str) -> None:
    """``tests/conftest.py::require_data_or_skip``, loaded by path (``tests`` is no package)."""
    spec = importlib.util.spec_from_file_location(
        "_emotive_root_conftest", REPO / "tests" / "conftest.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.require_data_or_skip(reason)


@pytest.fixture(autouse=True)
def isolated_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A fresh, empty ``EMOTIVE_HOME`` for every data test; no download base URL."""
    home = tmp_path / "emotive-home"
    monkeypatch.setenv("EMOTIVE_HOME", str(home))
    monkeypatch.delenv("EMOTIVE_DATA_URL", raising=False)
    return home


@pytest.fixture
def no_shared_data(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Hide every shared data folder: no EMOTIVE_DATA, a bare working folder, no repo root."""
    monkeypatch.delenv("EMOTIVE_DATA", raising=False)
    work = tmp_path / "work" / "project"
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    monkeypatch.setattr(store, "_repo_root", lambda: None)


# --- a synthetic data set ------------------------------------------------------------------

FAKE_CONTENTS = ("walk", "walk-left", "bow")
FAKE_STYLES = ("normal", "happy", "sad")


def fake_bvh(frames: int, phase: float) -> str:
    """A 3-joint BVH in centimetres (6 root channels, 3 per leg) of ``frames`` frames."""
    header = """HIERARCHY
ROOT Hips
{
  OFFSET 0 90 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Leg_L
  {
    OFFSET 10 -5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -80 0
    }
  }
  JOINT Leg_R
  {
    OFFSET -10 -5 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 -80 0
    }
  }
}
MOTION
"""
    rows = []
    for f in range(frames):
        a = 20.0 * ((f * 0.37 + phase) % 2.0 - 1.0)
        rows.append(f"{f * 2.0} 90 {phase} {a} 0 {a / 2} {a} {-a / 3} 0 {-a} {a / 3} 0")
    return header + f"Frames: {frames}\nFrame Time: 0.0333333\n" + "\n".join(rows) + "\n"


@dataclass
class FakeDataset:
    """A synthetic data set registered as ``fake-1``."""

    info: DatasetInfo
    archive: Path
    folder: Path
    frames: dict[str, int] = field(default_factory=dict)


def write_fake_folder(root: Path, folder: str = "Fake-Motiondataset-1") -> tuple[Path, dict]:
    """Write the unpacked synthetic data set; return its folder and ``{clip: frames}``."""
    top = root / folder
    (top / "cfg").mkdir(parents=True)
    (top / "data").mkdir()
    cfg = top / "cfg"
    cfg.joinpath("content_label.txt").write_text("\n".join(f"dataset-1_{c}" for c in FAKE_CONTENTS))
    cfg.joinpath("style_label.txt").write_text("\n".join(f"dataset-1_{s}" for s in FAKE_STYLES))
    (top / "LICENSE").write_text("test data\n")
    frames = {}
    n = 0
    for ci, content in enumerate(FAKE_CONTENTS):
        for si, style in enumerate(FAKE_STYLES):
            for take in (1, 2):
                name = f"dataset-1_{content}_{style}_{take:03d}"
                count = 12 + 3 * n
                n += 1
                (top / "data" / f"{name}.bvh").write_text(fake_bvh(count, phase=float(n)))
                (top / "data" / f"{name}.json").write_text(json.dumps({"content": ci, "style": si}))
                frames[name] = count
    return top, frames


def pack(
    folder: Path, archive: Path, extra: list[tuple[tarfile.TarInfo, bytes | None]] = ()
) -> str:
    """Write ``folder`` (plus raw ``extra`` members) to a ``.tar.gz``; return its sha256."""
    with tarfile.open(archive, "w:gz") as tar:
        tar.add(folder, arcname=folder.name)
        for info, data in extra:
            tar.addfile(info, io.BytesIO(data) if data is not None else None)
    return hashlib.sha256(archive.read_bytes()).hexdigest()


def fake_info(sha256: str, folder: str = "Fake-Motiondataset-1") -> DatasetInfo:
    return DatasetInfo(
        name="fake-1", title="Fake-Motiondataset-1", archive="fake-motion-1.tar.gz",
        sha256=sha256, folder=folder, contents=FAKE_CONTENTS, styles=FAKE_STYLES,
        locomotion=("walk", "walk-left"), clips=18,
    )


@pytest.fixture
def fake_tools() -> SimpleNamespace:
    """The synthetic data set builders: ``write_folder``, ``pack`` and ``info``."""
    return SimpleNamespace(write_folder=write_fake_folder, pack=pack, info=fake_info)


@pytest.fixture
def fake(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> FakeDataset:
    """A synthetic data set: archive in ``tmp/source``, registered as ``fake-1``."""
    src = tmp_path / "source"
    src.mkdir()
    folder, frames = write_fake_folder(tmp_path / "unpacked")
    archive = src / "fake-motion-1.tar.gz"
    info = fake_info(pack(folder, archive))
    monkeypatch.setitem(registry.REGISTRY, info.name, info)
    return FakeDataset(info, archive, folder, frames)


# --- a local HTTP server with Range support -------------------------------------------------


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), _Handler)
        #: path -> (body, mode); mode "range" honours Range, "norange" ignores it, "truncate"
        #: declares the full length but sends half and closes.
        self.routes: dict[str, tuple[bytes, str]] = {}
        #: (path, Range header, status) of every request.
        self.log: list[tuple[str, str | None, int]] = []

    def url(self, path: str) -> str:
        return f"http://127.0.0.1:{self.server_address[1]}{path}"


class _Handler(BaseHTTPRequestHandler):
    server: _Server

    def log_message(self, *args: object) -> None:
        pass

    def do_GET(self) -> None:
        rng = self.headers.get("Range")
        route = self.server.routes.get(self.path)
        if route is None:
            self.server.log.append((self.path, rng, 404))
            self.send_error(404)
            return
        body, mode = route
        start = 0
        status = 200
        match = re.fullmatch(r"bytes=(\d+)-", rng or "")
        if match and mode != "norange":
            start = int(match.group(1))
            if start >= len(body):
                self.server.log.append((self.path, rng, 416))
                self.send_response(416)
                self.send_header("Content-Range", f"bytes */{len(body)}")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            status = 206
        self.server.log.append((self.path, rng, status))
        self.send_response(status)
        if status == 206:
            self.send_header("Content-Range", f"bytes {start}-{len(body) - 1}/{len(body)}")
        payload = body[start:]
        self.send_header("Content-Length", str(len(payload)))
        self.send_header("Accept-Ranges", "bytes")
        self.end_headers()
        self.wfile.write(payload[: len(payload) // 2] if mode == "truncate" else payload)
        self.close_connection = True


@pytest.fixture(scope="session")
def _http_server() -> Iterator[_Server]:
    server = _Server()
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield server
    server.shutdown()
    server.server_close()


@pytest.fixture
def http(_http_server: _Server) -> _Server:
    """The local server on 127.0.0.1, with no routes and an empty log."""
    _http_server.routes.clear()
    _http_server.log.clear()
    return _http_server


# --- the real archives, unpacked once per session --------------------------------------------


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The folder holding both real archives (skips, or fails under EMOTIVE_REQUIRE_DATA=1)."""
    infos = [registry.get_dataset(n) for n in REAL]
    for folder in store.shared_data_dirs():
        if all((folder / i.archive).is_file() for i in infos):
            return folder
    require_data_or_skip(
        "the Bandai Namco archives are not in EMOTIVE_DATA or ../shared/data "
        "(see the README.md beside the data)"
    )
    raise AssertionError("unreachable")


@pytest.fixture(scope="session")
def data_home(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """A session cache with data set 1 fetched (copied, checked, unpacked) and data set 2
    unpacked on first use by :func:`dataset_dir`: each archive is unpacked once per session."""
    home = tmp_path_factory.mktemp("emotive-home-real")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("EMOTIVE_HOME", str(home))
        mp.setenv("EMOTIVE_DATA", str(shared_data))
        store.fetch("bandai-namco-1", source=shared_data)
        store.dataset_dir("bandai-namco-2-locomotion")
    return home


@pytest.fixture
def home(
    data_home: Path, shared_data: Path, isolated_home: Path, monkeypatch: pytest.MonkeyPatch
) -> Path:
    """Point ``EMOTIVE_HOME`` at the session cache holding both real data sets (read only!)."""
    monkeypatch.setenv("EMOTIVE_HOME", str(data_home))
    monkeypatch.setenv("EMOTIVE_DATA", str(shared_data))
    return data_home
