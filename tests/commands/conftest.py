"""Fixtures of the command tests: a synthetic style-transfer index and walk (no data needed)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from emotive.io.bvh import write_bvh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "models" / "mar"))
from mar_helpers import CONFIG, examples, styled


@pytest.fixture(scope="module")
def index(tmp_path_factory) -> Path:
    """A synthetic style-transfer index."""
    from emotive.models.mar.build import build_database

    return build_database(examples(3), CONFIG).save(tmp_path_factory.mktemp("idx") / "i.npz")


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    """A synthetic walk, alone in its folder."""
    return write_bvh(styled("walk", "neutral", take=2),
                     tmp_path_factory.mktemp("clip") / "walk.bvh", unit="cm")
