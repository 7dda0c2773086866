"""Locating, fetching (HTTP and local copy), checking and unpacking data sets."""

from __future__ import annotations

import hashlib
import json
import tarfile
from pathlib import Path

import pytest

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

    @pytest.mark.parametrize("kind", ["traversal", "absolute-link", "outside-folder"])
    def test_unsafe_archive_rejected(self, kind, fake_tools, tmp_path, monkeypatch, isolated_home):
        folder, _ = fake_tools.write_folder(tmp_path / "unpacked")
        member = tarfile.TarInfo(
            {"traversal": f"{folder.name}/../../evil.txt", "absolute-link": f"{folder.name}/link",
             "outside-folder": "Other/evil.txt"}[kind]
        )
        data: bytes | None = b"evil"
        member.size = 4
        if kind == "absolute-link":
            member.type, member.linkname, member.size = tarfile.SYMTYPE, "/etc/passwd", 0
            data = None
        archive = tmp_path / "fake-motion-1.tar.gz"
        info = fake_tools.info(fake_tools.pack(folder, archive, [(member, data)]))
        monkeypatch.setitem(registry.REGISTRY, info.name, info)
        with pytest.raises(DataError, match=r"unpack|outside"):
            store.fetch("fake-1", archive)
        assert not (isolated_home / "datasets" / info.folder).exists()
        assert not any(p.name == "evil.txt" for p in tmp_path.rglob("*"))
        assert not [p for p in (isolated_home / "datasets").iterdir()]


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
