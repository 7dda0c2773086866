"""BVH reader and writer: formats, round trips and the malformed-file corpus."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from emotive.errors import BVHError, OutputError
from emotive.io import bvh as bvh_module
from emotive.io.bvh import read_bvh, write_bvh
from emotive.transforms.np_rotations import euler_to_quaternion

VALID = """HIERARCHY
ROOT Hips
{
  OFFSET 0 90 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 60 0
    }
  }
  JOINT Leg
  {
    OFFSET 10 -5 0
    CHANNELS 3 Yrotation Zrotation Xrotation
    End Site
    {
      OFFSET 0 -80 0
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
1 90 2 10 20 30 5 -5 45 0 0 0
2 91 3 11 21 31 6 -6 46 1 1 1
3 92 4 12 22 32 7 -7 47 2 2 2
"""
# Line numbers of VALID (1-based) used by the corpus below.
FIRST_FRAME_LINE = 28


def write(tmp_path: Path, text: str, name: str = "clip.bvh", newline: str = "\n") -> Path:
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path


class TestReadBVH:
    def test_valid_file(self, tmp_path):
        m = read_bvh(write(tmp_path, VALID))
        assert m.skeleton.names == ("Hips", "Spine", "Leg")
        assert list(m.skeleton.parents) == [-1, 0, 0]
        assert m.num_frames == 3 and m.fps == 30.0
        assert m.metadata["file_unit"] == "cm"
        np.testing.assert_allclose(m.root_positions[1], [0.02, 0.91, 0.03])
        np.testing.assert_allclose(m.skeleton.end_site_offsets, [[0, 0.6, 0], [0, -0.8, 0]])
        # Hips "Zrotation Xrotation Yrotation" 10 20 30 -> order ZXY.
        expected = euler_to_quaternion(np.deg2rad([10.0, 20.0, 30.0]), "ZXY")
        np.testing.assert_allclose(m.rotations[0, 0], expected, atol=1e-12)
        assert m.skeleton.rotation_order(2) == "YZX"

    def test_crlf_tabs_and_scientific_notation(self, tmp_path):
        text = VALID.replace("  ", "\t").replace("OFFSET 0 90 0", "OFFSET 0e0 9.0E+01 -0.0e-3")
        m = read_bvh(write(tmp_path, text, newline="\r\n"))
        ref = read_bvh(write(tmp_path, VALID, name="ref.bvh"))
        np.testing.assert_allclose(m.rotations, ref.rotations)
        np.testing.assert_allclose(m.skeleton.offsets, ref.skeleton.offsets)

    def test_zero_frames(self, tmp_path):
        text = VALID.split("Frames:")[0] + "Frames: 0\nFrame Time: 0.04\n"
        m = read_bvh(write(tmp_path, text))
        assert m.num_frames == 0 and m.fps == 25.0
        out = write_bvh(m, tmp_path / "out.bvh")
        assert read_bvh(out).num_frames == 0

    def test_unit_choice(self, tmp_path):
        path = write(tmp_path, VALID)
        assert read_bvh(path, unit="m").skeleton.offsets[0, 1] == pytest.approx(90.0)
        assert read_bvh(path).skeleton.offsets[0, 1] == pytest.approx(0.9)
        with pytest.raises(ValueError, match="unit"):
            read_bvh(path, unit="furlong")


class TestWriteBVH:
    @pytest.mark.parametrize("orders", [("ZXY",), ("XYZ", "YXZ", "ZYX"), ("XZY", "YZX")])
    def test_round_trip_synthetic(self, tmp_path, random_motion, orders):
        m = random_motion(orders=orders)
        back = read_bvh(write_bvh(m, tmp_path / "m.bvh"))
        assert back.skeleton.same_as(m.skeleton)
        np.testing.assert_allclose(back.global_positions(), m.global_positions(), atol=1e-8)
        dots = np.abs((back.rotations * m.rotations).sum(-1))
        np.testing.assert_allclose(dots, 1.0, atol=1e-9)

    def test_written_file_has_one_root_and_channels(self, tmp_path, random_motion):
        m = random_motion()
        text = write_bvh(m, tmp_path / "m.bvh").read_text()
        assert text.count("ROOT") == 1 and text.count("End Site") == 2
        assert "Frames: 20" in text

    def test_atomic_no_partial_file(self, tmp_path, random_motion, monkeypatch):
        m = random_motion()
        with pytest.raises(BVHError, match="folder does not exist"):
            write_bvh(m, tmp_path / "missing" / "m.bvh")
        target = tmp_path / "m.bvh"

        def fail_midway(fh, *args, **kwargs):
            fh.write("0 1 2\n")
            raise OSError("disk full")

        monkeypatch.setattr(bvh_module.np, "savetxt", fail_midway)
        # atomic_output may pass the OSError on or wrap it in an OutputError.
        with pytest.raises((OSError, OutputError), match="disk full"):
            write_bvh(m, target)
        assert list(tmp_path.iterdir()) == []


def _mutate(old: str, new: str, text: str = VALID) -> str:
    assert old in text
    return text.replace(old, new, 1)


# (name, text, line of the problem or None, words the message must contain)
CORPUS = [
    ("empty", "", 1, "empty"),
    ("no_hierarchy", "ROOT Hips\n{\n}\n", 1, "HIERARCHY"),
    ("empty_hierarchy", "HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 2, "empty hierarchy"),
    ("missing_motion", VALID.split("MOTION")[0], 24, "MOTION part is missing"),
    ("truncated_hierarchy", VALID[: VALID.index("JOINT Leg")], 14, "truncated"),
    ("truncated_frames", VALID.rsplit("3 92", 1)[0], None, "truncated"),
    ("extra_frames", VALID + "4 93 5 13 23 33 8 -8 48 3 3 3\n", 31, "more frame lines"),
    ("wrong_channel_count", _mutate("CHANNELS 3 Xrotation", "CHANNELS 4 Xrotation"), 9,
     "CHANNELS 4"),
    ("bad_channel_name",
     _mutate("Yrotation Zrotation Xrotation", "Yrotation Zrotation Wrotation"), 18,
     "invalid channels"),
    ("short_row", _mutate("2 91 3 11 21 31 6 -6 46 1 1 1", "2 91 3 11 21 31 6 -6 46 1 1"),
     FIRST_FRAME_LINE + 1, "12 numbers"),
    ("long_rows", re.sub(r" (\d) \1 \1\n", r" \1 \1 \1 9\n", VALID), FIRST_FRAME_LINE,
     "channel count"),
    ("non_numeric", _mutate("3 92 4 12", "3 92 four 12"), FIRST_FRAME_LINE + 2, "non-numeric"),
    ("nan_value", _mutate("2 91 3 11", "2 91 nan 11"), FIRST_FRAME_LINE + 1, "NaN"),
    ("inf_offset", _mutate("OFFSET 0 10 0", "OFFSET 0 inf 0"), 8, "finite"),
    ("text_offset", _mutate("OFFSET 0 10 0", "OFFSET 0 ten 0"), 8, "must be a number"),
    ("duplicate_names", _mutate("JOINT Leg", "JOINT Spine"), 15, "duplicate joint name 'Spine'"),
    ("unbalanced_braces", _mutate("  }\n  JOINT Leg", "  JOINT Leg"), None, "not closed"),
    ("two_roots",
     VALID.split("MOTION")[0] + "ROOT Other\n{\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n", 25,
     "several ROOT"),
    ("bad_frames", _mutate("Frames: 3", "Frames: three"), 26, "whole number"),
    ("bad_frame_time", _mutate("Frame Time: 0.0333333", "Frame Time: -1"), 27, "positive"),
    ("no_offset", _mutate("    OFFSET 0 10 0\n", ""), 6, "no OFFSET"),
]


class TestMalformedCorpus:
    @pytest.mark.parametrize(("name", "text", "line", "words"), CORPUS, ids=[c[0] for c in CORPUS])
    def test_typed_error_names_file_line_and_problem(self, tmp_path, name, text, line, words):
        path = write(tmp_path, text, name=f"{name}.bvh")
        with pytest.raises(BVHError) as info:
            read_bvh(path)
        err = info.value
        assert err.path == str(path)
        assert words in str(err)
        assert f"{name}.bvh" in str(err)
        if line is not None:
            assert err.line == line, str(err)
        assert "\n" not in str(err)

    def test_directory(self, tmp_path):
        with pytest.raises(BVHError, match="is a directory"):
            read_bvh(tmp_path)

    def test_binary_file(self, tmp_path):
        path = tmp_path / "x.bvh"
        path.write_bytes(bytes(range(256)) * 4)
        with pytest.raises(BVHError, match="binary"):
            read_bvh(path)

    def test_missing_file(self, tmp_path):
        with pytest.raises(BVHError, match="no such file"):
            read_bvh(tmp_path / "nope.bvh")
