"""Atomic output files."""

from __future__ import annotations

import stat

import pytest

from emotive.io.atomic import atomic_output


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
