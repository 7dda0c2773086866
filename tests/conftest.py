"""Shared test helpers: real-data location and synthetic fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def require_data_or_skip(reason: str) -> None:
    """Skip a data test, or fail when CI demands the data (``EMOTIVE_REQUIRE_DATA=1``)."""
    if os.environ.get("EMOTIVE_REQUIRE_DATA") == "1":
        pytest.fail(f"EMOTIVE_REQUIRE_DATA=1 but the data is missing: {reason}")
    pytest.skip(reason)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)
