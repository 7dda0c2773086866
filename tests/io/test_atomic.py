"""Atomic output files: whole or absent, and every write fault one typed error."""

from __future__ import annotations

import errno
import os
import stat

import pytest

from disk_faults import fill_disk, refuse_files
from emotive.errors import OutputError
from emotive.io.atomic import atomic_output, check_writable


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
