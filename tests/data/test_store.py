"""Locating, fetching (HTTP and local copy), checking and unpacking data sets."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import os
import re
import tarfile
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from emotive.data import download as download_mod
from emotive.data import registry, store
from emotive.errors import ChecksumError, DataError


@pytest.fixture(params=["synthetic", "bandai-namco-1"])
def served(request, fake, http):
    """An archive on the local HTTP server: the synthetic one, and the real shared archive."""
    if request.param == "synthetic":
        info, path = fake.info, fake.archive
    else:
        shared = request.getfixturevalue("shared_data")
        info = registry.get_dataset("bandai-namco-1")
        path = shared / info.archive
    body = path.read_bytes()
    http.routes["/files/" + info.archive] = (body, "range")
    return info, body, http.url("/files/" + info.archive)


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


class TestDownload:
    def test_good_download(self, served, http, isolated_home):
        info, _, url = served
        out = store.fetch_archive(info.name, url)
        assert out == isolated_home / "archives" / info.archive
        assert sha(out) == info.sha256
        assert not out.with_name(out.name + ".part").exists()
        assert [(r, s) for _, r, s in http.log] == [(None, 200)]

    def test_resumes_partial_download(self, served, http, isolated_home):
        info, body, url = served
        part = isolated_home / "archives" / (info.archive + ".part")
        part.parent.mkdir(parents=True)
        cut = len(body) * 2 // 5
        part.write_bytes(body[:cut])
        out = store.fetch_archive(info.name, url)
        assert sha(out) == info.sha256
        assert http.log == [("/files/" + info.archive, f"bytes={cut}-", 206)]
        assert not part.exists()

    def test_corrupt_download_rejected_and_removed(self, served, http, isolated_home):
        info, body, url = served
        broken = bytearray(body)
        broken[len(broken) // 2] ^= 0xFF
        http.routes["/files/" + info.archive] = (bytes(broken), "range")
        with pytest.raises(ChecksumError, match=rf"sha256 .* {info.sha256}.*removed"):
            store.fetch_archive(info.name, url)
        archives = isolated_home / "archives"
        assert not (archives / info.archive).exists()
        assert not (archives / (info.archive + ".part")).exists()

    def test_interrupted_download_keeps_part_and_resumes(self, fake, http, isolated_home):
        body = fake.archive.read_bytes()
        http.routes["/a.tar.gz"] = (body, "truncate")
        with pytest.raises(DataError, match="run the same command again to resume"):
            store.fetch_archive("fake-1", http.url("/a.tar.gz"))
        part = isolated_home / "archives" / (fake.info.archive + ".part")
        assert 0 < part.stat().st_size < len(body)
        http.routes["/a.tar.gz"] = (body, "range")
        out = store.fetch_archive("fake-1", http.url("/a.tar.gz"))
        assert sha(out) == fake.info.sha256
        assert http.log[-1][1:] == (f"bytes={len(body) // 2}-", 206)

    def test_server_without_range_restarts(self, fake, http, isolated_home):
        body = fake.archive.read_bytes()
        http.routes["/a.tar.gz"] = (body, "norange")
        part = isolated_home / "archives" / (fake.info.archive + ".part")
        part.parent.mkdir(parents=True)
        part.write_bytes(b"garbage from an older attempt")
        out = store.fetch_archive("fake-1", http.url("/a.tar.gz"))
        assert sha(out) == fake.info.sha256
        assert http.log[-1][2] == 200

    def test_complete_part_is_fetched_again(self, fake, http, isolated_home):
        body = fake.archive.read_bytes()
        http.routes["/a.tar.gz"] = (body, "range")
        part = isolated_home / "archives" / (fake.info.archive + ".part")
        part.parent.mkdir(parents=True)
        part.write_bytes(body + b"extra")
        out = store.fetch_archive("fake-1", http.url("/a.tar.gz"))
        assert sha(out) == fake.info.sha256
        assert [s for _, _, s in http.log] == [416, 200]

    def test_http_error(self, fake, http):
        with pytest.raises(DataError, match="HTTP 404"):
            store.fetch_archive("fake-1", http.url("/nothing.tar.gz"))

    def test_unreachable_server(self, fake):
        with pytest.raises(DataError, match="cannot reach"):
            store.fetch_archive("fake-1", "http://127.0.0.1:9/fake-motion-1.tar.gz")

    def test_base_url_from_environment(self, fake, http, monkeypatch, no_shared_data):
        http.routes["/mirror/" + fake.info.archive] = (fake.archive.read_bytes(), "range")
        monkeypatch.setenv("EMOTIVE_DATA_URL", http.url("/mirror/"))
        folder = store.fetch("fake-1", progress=True)
        assert (folder / "data").is_dir()


class _Endless(BaseHTTPRequestHandler):
    """Streams up to 8 MiB with no Content-Length (a server that never says how big)."""

    def log_message(self, *args: object) -> None:
        pass

    def do_GET(self) -> None:
        self.send_response(200)
        self.end_headers()
        with contextlib.suppress(OSError):
            for _ in range(128):
                self.wfile.write(b"x" * (64 << 10))


@pytest.fixture
def endless_url():
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Endless)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/fake-motion-1.tar.gz"
    finally:
        server.shutdown()
        server.server_close()


class TestDownloadLimits:
    def test_declared_size_over_limit_refused(self, fake, http, monkeypatch, isolated_home):
        http.routes["/big.tar.gz"] = (b"x" * (1 << 20), "range")
        monkeypatch.setattr(download_mod, "MAX_DOWNLOAD_BYTES", 64 << 10)
        with pytest.raises(DataError, match=r"1048576 bytes or more, over the limit of 65536"):
            store.fetch_archive("fake-1", http.url("/big.tar.gz"))
        assert list((isolated_home / "archives").iterdir()) == []

    def test_undeclared_stream_stopped_at_limit(self, fake, endless_url, monkeypatch,
                                                isolated_home):
        monkeypatch.setattr(download_mod, "MAX_DOWNLOAD_BYTES", 256 << 10)
        with pytest.raises(DataError, match=r"over the limit of 262144 bytes.*removed"):
            store.fetch_archive("fake-1", endless_url)
        assert list((isolated_home / "archives").iterdir()) == []

    def test_full_disk_during_download_removes_part(self, fake, http, monkeypatch,
                                                    isolated_home):
        http.routes["/a.tar.gz"] = (fake.archive.read_bytes(), "range")
        real_open = open

        class FullDisk(io.FileIO):
            def write(self, block):
                raise OSError(errno.ENOSPC, "No space left on device")

        def open_full(path, mode="r", *args, **kwargs):
            if mode in ("wb", "ab"):
                return FullDisk(path, mode)
            return real_open(path, mode, *args, **kwargs)

        monkeypatch.setattr(download_mod, "open", open_full, raising=False)
        with pytest.raises(DataError, match=r"no space left on the disk holding .*archives"):
            store.fetch_archive("fake-1", http.url("/a.tar.gz"))
        assert list((isolated_home / "archives").iterdir()) == []


class TestLocalCopy:
    def test_copy_from_file(self, fake, isolated_home):
        out = store.fetch_archive("fake-1", fake.archive)
        assert out.parent == isolated_home / "archives" and sha(out) == fake.info.sha256

    def test_copy_from_folder(self, fake):
        out = store.fetch_archive("fake-1", fake.archive.parent)
        assert sha(out) == fake.info.sha256

    def test_missing_source(self, fake, tmp_path):
        with pytest.raises(DataError, match="does not exist"):
            store.fetch_archive("fake-1", tmp_path / "nowhere")

    def test_corrupt_copy_removed_source_kept(self, fake, tmp_path, isolated_home):
        bad = tmp_path / "bad" / fake.info.archive
        bad.parent.mkdir()
        bad.write_bytes(fake.archive.read_bytes()[:-10])
        with pytest.raises(ChecksumError, match="corrupt"):
            store.fetch_archive("fake-1", bad)
        assert bad.exists()
        assert list((isolated_home / "archives").iterdir()) == []

    def test_no_source_known(self, fake, no_shared_data):
        with pytest.raises(DataError, match=r"--source .*EMOTIVE_DATA_URL"):
            store.fetch_archive("fake-1")


def unsafe_member(top: str, kind: str, name: str, target: str = "") -> tuple:
    member = tarfile.TarInfo(name.replace("TOP", top))
    data: bytes | None = None
    if kind == "file":
        member.size, data = 4, b"evil"
    else:
        member.type = {"sym": tarfile.SYMTYPE, "hard": tarfile.LNKTYPE, "fifo": tarfile.FIFOTYPE,
                       "chr": tarfile.CHRTYPE}[kind]
        member.linkname = target.replace("TOP", top)
    return member, data


#: Archives with members that must never be written: (kind, name, link target) per member.
UNSAFE = {
    "traversal": [("file", "TOP/../../evil.txt")],
    "absolute-path": [("file", "/tmp/evil.txt")],
    "outside-folder": [("file", "Other/evil.txt")],
    "absolute-link": [("sym", "TOP/link", "/etc/passwd")],
    # A chain of links that each stay inside the tree but together point outside it, then a
    # file written through the chain (the tarfile "data" filter bypass of 2025).
    "link-chain": [("sym", "TOP/data/a", "."), ("sym", "TOP/data/a/b", "../.."),
                   ("sym", "TOP/data/out", "a/b/../.."), ("file", "TOP/data/out/evil.txt")],
    "hard-link": [("hard", "TOP/data/hard", "TOP/LICENSE")],
    "fifo": [("fifo", "TOP/data/pipe")],
    "device": [("chr", "TOP/data/dev")],
}


class TestUnpack:
    def test_fetch_unpacks_into_cache(self, fake, isolated_home):
        folder = store.fetch("fake-1", fake.archive)
        assert folder == isolated_home / "datasets" / fake.info.folder
        assert len(list((folder / "data").glob("*.bvh"))) == 18
        assert json.loads((folder / store.MARKER).read_text())["sha256"] == fake.info.sha256
        assert store.dataset_state("fake-1").state == "cached"
        assert store.fetch("fake-1") == folder
        assert not [p for p in (isolated_home / "datasets").iterdir() if p.name.startswith(".")]

    def test_force_fetches_again(self, fake):
        folder = store.fetch("fake-1", fake.archive)
        (folder / "data" / "stray.txt").write_text("x")
        assert store.fetch("fake-1", fake.archive, force=True) == folder
        assert not (folder / "data" / "stray.txt").exists()

    @pytest.mark.parametrize("kind", sorted(UNSAFE))
    def test_unsafe_archive_rejected(self, kind, fake_tools, tmp_path, monkeypatch, isolated_home):
        folder, _ = fake_tools.write_folder(tmp_path / "unpacked")
        extra = [unsafe_member(folder.name, *spec) for spec in UNSAFE[kind]]
        archive = tmp_path / "fake-motion-1.tar.gz"
        info = fake_tools.info(fake_tools.pack(folder, archive, extra))
        monkeypatch.setitem(registry.REGISTRY, info.name, info)
        first = extra[0][0].name
        with pytest.raises(DataError, match=re.escape(repr(first))) as exc:
            store.fetch("fake-1", archive)
        assert "fetch it again" in str(exc.value)
        assert not (isolated_home / "datasets" / info.folder).exists()
        assert not any(p.name == "evil.txt" for p in tmp_path.rglob("*"))
        assert list((isolated_home / "datasets").iterdir()) == []

    def test_unpacks_the_bytes_it_checked(self, fake, fake_tools, tmp_path, monkeypatch,
                                          isolated_home):
        """An archive swapped on disk between the check and the unpack changes nothing."""
        evil_folder, _ = fake_tools.write_folder(tmp_path / "evil")
        (evil_folder / "data" / "evil.txt").write_text("evil")
        evil = tmp_path / "evil.tar.gz"
        fake_tools.pack(evil_folder, evil)
        shared = tmp_path / "shared"
        shared.mkdir()
        archive = shared / fake.info.archive
        archive.write_bytes(fake.archive.read_bytes())
        check = store._check_open

        def check_then_swap(*args, **kwargs):
            check(*args, **kwargs)
            os.replace(evil, archive)

        monkeypatch.setattr(store, "_check_open", check_then_swap)
        folder = store.extract_archive("fake-1", archive)
        assert not (folder / "data" / "evil.txt").exists()
        assert len(list((folder / "data").glob("*.bvh"))) == 18

    def test_stale_folder_replaced_finished_copy_kept(self, fake, monkeypatch, isolated_home):
        target = isolated_home / "datasets" / fake.info.folder
        (target / "data").mkdir(parents=True)
        (target / "data" / "half-written.bvh").write_text("x")
        folder = store.extract_archive("fake-1", fake.archive)
        assert not (folder / "data" / "half-written.bvh").exists()
        assert store.is_cached("fake-1")

        def no_unpack(*args):
            raise AssertionError("a finished copy must be used as it is")

        monkeypatch.setattr(store, "_unpack_into", no_unpack)
        assert store.extract_archive("fake-1", fake.archive) == folder
        assert store.dataset_dir("fake-1") == folder

    def test_too_large_local_archive_refused(self, fake, monkeypatch, isolated_home):
        monkeypatch.setattr(store, "MAX_DOWNLOAD_BYTES", 100)
        with pytest.raises(DataError, match=r"over the limit of 100 bytes"):
            store.fetch_archive("fake-1", fake.archive)
        assert list((isolated_home / "archives").iterdir()) == []


class TestLocate:
    def test_default_home(self, monkeypatch, tmp_path):
        monkeypatch.delenv("EMOTIVE_HOME")
        monkeypatch.setenv("HOME", str(tmp_path))
        assert store.emotive_home() == tmp_path / ".cache" / "emotive"

    def test_missing_says_fetch(self, fake, no_shared_data):
        assert store.dataset_state("fake-1").state == "missing"
        with pytest.raises(DataError, match="run `emotive data fetch fake-1`"):
            store.dataset_dir("fake-1")

    def test_emotive_data_used_automatically(self, fake, monkeypatch, no_shared_data):
        monkeypatch.setenv("EMOTIVE_DATA", str(fake.archive.parent))
        state = store.dataset_state("fake-1")
        assert (state.state, state.location) == ("shared", fake.archive)
        folder = store.dataset_dir("fake-1")
        assert (folder / "data").is_dir()
        assert store.dataset_state("fake-1").state == "cached"

    def test_shared_data_beside_working_folder(self, fake, tmp_path, monkeypatch, no_shared_data):
        shared = tmp_path / "work" / "shared" / "data"
        shared.mkdir(parents=True)
        (shared / fake.info.archive).write_bytes(fake.archive.read_bytes())
        assert store.find_shared_archive("fake-1") == shared / fake.info.archive

    def test_shared_data_beside_repository(self, fake, tmp_path, monkeypatch, no_shared_data):
        shared = tmp_path / "elsewhere" / "shared" / "data"
        shared.mkdir(parents=True)
        (shared / fake.info.archive).write_bytes(fake.archive.read_bytes())
        monkeypatch.setattr(store, "_repo_root", lambda: tmp_path / "elsewhere" / "repo")
        assert store.find_shared_archive("fake-1") == shared / fake.info.archive

    def test_repo_root_of_editable_install(self):
        root = store._repo_root()
        assert root is not None and (root / "src" / "emotive" / "data" / "store.py").is_file()

    def test_corrupt_shared_archive_is_not_deleted(
        self, fake, tmp_path, monkeypatch, no_shared_data
    ):
        shared = tmp_path / "shared-bad"
        shared.mkdir()
        (shared / fake.info.archive).write_bytes(b"not an archive")
        monkeypatch.setenv("EMOTIVE_DATA", str(shared))
        with pytest.raises(ChecksumError):
            store.dataset_dir("fake-1")
        assert (shared / fake.info.archive).exists()


def test_real_datasets_unpacked_once(home):
    for name in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        state = store.dataset_state(name)
        assert state.state == "cached"
        assert state.location == home / "datasets" / registry.get_dataset(name).folder
    assert (home / "archives" / "bandai-namco-motion-1.tar.gz").is_file()
