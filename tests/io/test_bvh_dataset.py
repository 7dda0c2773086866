"""Round trip read -> write -> read over every clip of both real datasets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from emotive.io.bvh import read_bvh, write_bvh

pytestmark = pytest.mark.data


def raw_channels(path: Path) -> np.ndarray:
    """``(T, C)`` channel values exactly as written in the file, parsed independently."""
    lines = path.read_text().splitlines()
    start = next(n for n, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1
    rows = [ln for ln in lines[start:] if ln.strip()]
    return np.loadtxt(rows, ndmin=2) if rows else np.zeros((0, 0))


def rotation_columns(path: Path) -> np.ndarray:
    tokens = path.read_text().split("MOTION")[0].split()
    kinds = []
    for n, tok in enumerate(tokens):
        if tok == "CHANNELS":
            count = int(tokens[n + 1])
            kinds += [c.endswith("rotation") for c in tokens[n + 2 : n + 2 + count]]
    return np.array(kinds)


def assert_round_trip(path: Path, tmp: Path) -> None:
    motion = read_bvh(path)
    out = write_bvh(motion, tmp / path.name)
    back = read_bvh(out)
    before, after = raw_channels(path), raw_channels(out)
    assert before.shape == after.shape, path.name
    rot = rotation_columns(path)
    diff = after - before
    # Angles are equal modulo 360 degrees (+180 and -180 are the same channel value).
    diff[:, rot] = (diff[:, rot] + 180.0) % 360.0 - 180.0
    assert np.abs(diff).max(initial=0.0) < 1e-4, f"{path.name}: channel error {np.abs(diff).max()}"
    # Joint positions within 1e-4 of the file's unit (centimetres) = 1e-6 m.
    err = np.abs(back.global_positions() - motion.global_positions()).max(initial=0.0)
    assert err < 1e-6, f"{path.name}: joint position error {err} m"
    assert back.skeleton.same_as(motion.skeleton) and back.fps == motion.fps


def test_round_trip_every_clip_dataset1(bandai1_dir, tmp_path):
    clips = sorted((bandai1_dir / "data").glob("*.bvh"))
    assert len(clips) == 174
    for path in clips:
        assert_round_trip(path, tmp_path)


def test_round_trip_every_clip_dataset2(bandai2_dir, tmp_path):
    clips = sorted((bandai2_dir / "data").glob("*.bvh"))
    assert len(clips) == 962
    for path in clips:
        assert_round_trip(path, tmp_path)
        (tmp_path / path.name).unlink()
