"""Atomic output files: whole or absent, and every write fault one typed error; the outputs of
one transaction all or none."""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from disk_faults import fill_disk, refuse_files
from emotive.errors import OutputError
from emotive.io.atomic import atomic_output, check_writable, output_transaction


def test_success_renames_into_place(tmp_path):
    dest = tmp_path / "out.csv"
    with atomic_output(dest) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".csv" and tmp != dest
        tmp.write_text("a,b\n")
        assert not dest.exists()
    assert dest.read_text() == "a,b\n"
    assert stat.S_IMODE(dest.stat().st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_failure_keeps_the_previous_file_and_leaves_nothing(tmp_path):
    dest = tmp_path / "out.csv"
    dest.write_text("old")
    with pytest.raises(KeyboardInterrupt), atomic_output(dest) as tmp:
        tmp.write_text("half")
        raise KeyboardInterrupt
    assert dest.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


@pytest.mark.parametrize(("code", "words"), [
    (errno.EROFS, ["read-only", "choose another folder"]),
    (errno.EACCES, ["permission denied", "choose a folder you may write to"]),
    (errno.EPERM, ["may not be changed", "choose another folder"]),
])
def test_a_folder_that_refuses_files_is_an_output_error(tmp_path, monkeypatch, code, words):
    refuse_files(monkeypatch, code)
    dest = tmp_path / "out.csv"
    with pytest.raises(OutputError) as exc, atomic_output(dest) as tmp:
        tmp.write_text("never")
    assert str(dest) in str(exc.value) and all(w in str(exc.value) for w in words)
    assert list(tmp_path.iterdir()) == []


def test_a_full_disk_is_an_output_error_and_leaves_nothing(tmp_path, monkeypatch):
    dest = tmp_path / "out.csv"
    dest.write_text("old")
    fill_disk(monkeypatch)
    with pytest.raises(OutputError, match=r"disk is full.*free space") as exc, \
            atomic_output(dest) as tmp, open(tmp, "w") as fh:
        fh.write("a,b\n" * 10)
    assert isinstance(exc.value.__cause__, OSError) and exc.value.__cause__.errno == errno.ENOSPC
    assert "\n" not in str(exc.value) and str(dest) in str(exc.value)
    assert dest.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.csv"]


def test_a_writer_that_swallows_the_error_is_still_caught(tmp_path, monkeypatch):
    # The temporary file is not a plain file any more: never renamed into place.
    fill_disk(monkeypatch)
    with pytest.raises(OutputError), atomic_output(tmp_path / "out.csv"):
        pass
    assert list(tmp_path.iterdir()) == []


def test_a_folder_named_as_the_file_is_an_output_error(tmp_path):
    (tmp_path / "out.csv").mkdir()
    with pytest.raises(OutputError, match="a folder has that name"), \
            atomic_output(tmp_path / "out.csv") as tmp:
        tmp.write_text("x")
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_the_file_is_flushed_before_the_rename(tmp_path, monkeypatch):
    synced = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: synced.append(fd) or real(fd))
    dest = tmp_path / "out.csv"
    with atomic_output(dest) as tmp:
        tmp.write_text("a")
    assert synced and dest.read_text() == "a"


def test_check_writable(tmp_path, monkeypatch):
    check_writable(tmp_path)
    assert list(tmp_path.iterdir()) == []
    refuse_files(monkeypatch, errno.EROFS)
    with pytest.raises(OutputError, match=f"cannot write {tmp_path}: the folder is on a read"):
        check_writable(tmp_path)


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_a_real_unwritable_folder(tmp_path):
    with pytest.raises(OutputError, match=r"cannot write /proc/out\.csv"), \
            atomic_output("/proc/out.csv") as tmp:
        tmp.write_text("x")


class TestOutputTransaction:
    """All or none across files: nothing is renamed into place until every file is written."""

    @staticmethod
    def snapshot(folder) -> dict[str, bytes]:
        return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}

    def test_files_appear_together_at_the_end(self, tmp_path):
        (tmp_path / "a.bvh").write_text("old")
        with output_transaction() as outputs:
            for name in ("a.bvh", "b.gif"):
                with atomic_output(tmp_path / name) as tmp:
                    tmp.write_text(f"new {name}")
            assert (tmp_path / "a.bvh").read_text() == "old"
            assert not (tmp_path / "b.gif").exists()
        assert outputs.written == [tmp_path / "a.bvh", tmp_path / "b.gif"]
        assert self.snapshot(tmp_path) == {"a.bvh": b"new a.bvh", "b.gif": b"new b.gif"}

    def test_a_failure_in_the_block_leaves_every_file_as_it_was(self, tmp_path):
        (tmp_path / "a.bvh").write_text("old")
        with pytest.raises(KeyboardInterrupt), output_transaction():
            with atomic_output(tmp_path / "a.bvh") as tmp:
                tmp.write_text("new")
            with atomic_output(tmp_path / "b.gif") as tmp:
                raise KeyboardInterrupt
        assert self.snapshot(tmp_path) == {"a.bvh": b"old"}

    @staticmethod
    def fail_renames_onto(monkeypatch, name: str) -> None:
        """Make every rename onto a file called ``name`` fail with ``EIO``."""
        real = os.replace

        def replace(src, dst, **kwargs):
            if os.path.basename(dst) == name:
                raise OSError(errno.EIO, "Input/output error")
            real(src, dst, **kwargs)

        monkeypatch.setattr(os, "replace", replace)

    def test_a_failed_rename_puts_the_renamed_files_back(self, tmp_path, monkeypatch):
        for name in ("a.bvh", "b.npz"):
            (tmp_path / name).write_text(f"old {name}")
        before = self.snapshot(tmp_path)
        self.fail_renames_onto(monkeypatch, "c.gif")
        with pytest.raises(OutputError, match=r"cannot write .*c\.gif: the disk reported"), \
                output_transaction():
            for name in ("a.bvh", "new.csv", "b.npz", "c.gif"):
                with atomic_output(tmp_path / name) as tmp:
                    tmp.write_text("new")
        assert self.snapshot(tmp_path) == before

    def test_without_hard_links_the_old_files_are_copied_aside(self, tmp_path, monkeypatch):
        def no_links(*args, **kwargs):
            raise OSError(errno.EPERM, "Operation not permitted")

        (tmp_path / "a.bvh").write_text("old")
        monkeypatch.setattr(os, "link", no_links)
        self.fail_renames_onto(monkeypatch, "b.gif")
        with pytest.raises(OutputError), output_transaction():
            for name in ("a.bvh", "b.gif"):
                with atomic_output(tmp_path / name) as tmp:
                    tmp.write_text("new")
        assert self.snapshot(tmp_path) == {"a.bvh": b"old"}

    def test_the_same_file_twice_is_refused(self, tmp_path):
        with pytest.raises(OutputError, match="names it twice"), output_transaction():
            for _ in range(2):
                with atomic_output(tmp_path / "a.bvh") as tmp:
                    tmp.write_text("new")
        assert list(tmp_path.iterdir()) == []

    def test_an_inner_transaction_joins_the_outer_one(self, tmp_path):
        with pytest.raises(RuntimeError), output_transaction():
            with output_transaction(), atomic_output(tmp_path / "a.bvh") as tmp:
                tmp.write_text("new")
            assert not (tmp_path / "a.bvh").exists()
            raise RuntimeError
        assert list(tmp_path.iterdir()) == []


@settings(max_examples=60, deadline=None)
@given(existed=st.lists(st.booleans(), min_size=1, max_size=4), data=st.data())
def test_any_failure_leaves_the_folder_as_it_was(existed, data):
    """Outputs ``i`` that existed or not; a failure while writing output ``k`` (``k < n``), at
    the rename of output ``k - n`` (``n <= k < 2n``), or none (``k = 2n``)."""
    n = len(existed)
    fail = data.draw(st.integers(0, 2 * n), label="failure")
    real = os.replace
    renames = []

    def replace(src, dst, **kwargs):
        if os.path.basename(dst).startswith("out"):
            renames.append(dst)
            if len(renames) == fail - n + 1:
                raise OSError(errno.EIO, "Input/output error")
        real(src, dst, **kwargs)

    with tempfile.TemporaryDirectory() as name, pytest.MonkeyPatch.context() as mp:
        folder = Path(name)
        for i, old in enumerate(existed):
            if old:
                (folder / f"out{i}.bin").write_bytes(b"old %d" % i)
        before = {p.name: p.read_bytes() for p in folder.iterdir()}
        mp.setattr(os, "replace", replace)
        try:
            with output_transaction():
                for i in range(n):
                    with atomic_output(folder / f"out{i}.bin") as tmp:
                        if i == fail:
                            raise OSError(errno.ENOSPC, "No space left on device")
                        tmp.write_bytes(b"new %d" % i)
        except OutputError:
            assert fail < 2 * n
            assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
        else:
            assert fail == 2 * n
            assert {p.name: p.read_bytes() for p in folder.iterdir()} == {
                f"out{i}.bin": b"new %d" % i for i in range(n)}
