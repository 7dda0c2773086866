"""Shared helpers of the crowd tests: small scenes written as TOML."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("shapely", reason="the crowd extra is not installed")

CORRIDOR = """
[area]
polygon = [[0, 0], [7, 0], [7, 3], [0, 3]]

[[groups]]
name = "east"
spawn = [[0, 0], [1.6, 0], [1.6, 3], [0, 3]]
count = {count}
goal = [[6, 0], [7, 0], [7, 3], [6, 3]]
emotion = {{ choices = ["happy", "angry", "neutral"] }}

[[groups]]
name = "west"
spawn = [[5.4, 0], [7, 0], [7, 3], [5.4, 3]]
count = {count}
goal = [[0, 0], [1, 0], [1, 3], [0, 3]]
emotion = "valence=0.6,arousal=0.2"
"""


def write_scene(folder: Path, text: str, name: str = "scene.toml") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def corridor(tmp_path) -> Path:
    return write_scene(tmp_path, CORRIDOR.format(count=4))
