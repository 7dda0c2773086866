"""The BVH reader's text layer: lines within the budget, whatever their ends."""

from __future__ import annotations

import pytest

from emotive.errors import BVHError
from emotive.io import bvh_limits as limits
from emotive.io.bvh_text import BVHLines, HierarchyWords, open_bvh_text


def lines_of(path, width=None) -> list[str]:
    with open_bvh_text(path) as fh:
        lines = BVHLines(str(path), fh)
        out = []
        while (line := lines.next(width)) is not None:
            out.append(line)
        assert lines.number == len(out)
    return out


@pytest.mark.parametrize("end", ["\n", "\r\n", "\r"])
def test_line_ends_are_read_alike(tmp_path, end):
    path = tmp_path / "x.bvh"
    path.write_bytes(end.join(["a b", "", "c"]).encode() + end.encode())
    assert lines_of(path) == ["a b", "", "c"]


def test_a_line_at_the_limit_is_read_and_one_character_more_is_not(tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "MAX_LINE_CHARS", 64)
    path = tmp_path / "x.bvh"
    path.write_text("ok\n" + "y" * 64 + "\n" + "z" * 64)
    assert lines_of(path) == ["ok", "y" * 64, "z" * 64]
    path.write_text("ok\n" + "y" * 65 + "\n")
    with pytest.raises(BVHError, match="longer than 64 characters") as info:
        lines_of(path)
    assert info.value.line == 2


def test_a_long_row_is_refused_by_its_width_first(tmp_path, monkeypatch):
    monkeypatch.setattr(limits, "MAX_LINE_CHARS", 64)
    path = tmp_path / "x.bvh"
    path.write_text("1 2 3 " + " " * 70 + "\n")
    with pytest.raises(BVHError, match="longer than 64"):
        lines_of(path, width=3)
    path.write_text("1 2 3 4" + " " * 70 + "\n")
    with pytest.raises(BVHError, match="more than the 3 values"):
        lines_of(path, width=3)


def test_words_stop_after_the_motion_line_and_keep_their_lines(tmp_path):
    path = tmp_path / "x.bvh"
    path.write_bytes(b"\xef\xbb\xbfHIERARCHY\nROOT H\xc3\xa9\n\nMOTION\nFrames: 1\n")
    with open_bvh_text(path) as fh:
        lines = BVHLines(str(path), fh)
        words = HierarchyWords(lines)
        got = []
        while words.peek() is not None:
            got.append((words.next("a word"), words.last_line))
        assert got == [("HIERARCHY", 1), ("ROOT", 2), ("Hé", 2), ("MOTION", 4)]
        assert words.motion_line == 4 and lines.next() == "Frames: 1"


def test_a_latin1_name_is_kept(tmp_path):
    path = tmp_path / "x.bvh"
    path.write_bytes(b"ROOT H\xefps\nMOTION\n")
    with open_bvh_text(path) as fh:
        words = HierarchyWords(BVHLines(str(path), fh))
        assert [words.next("w"), words.next("w")] == ["ROOT", "H\u00efps"]
