"""Fixtures of the resampler tests."""

from __future__ import annotations

import pytest

from emotive.data.clips import Clip
from lgb_clips import synthetic_clip


@pytest.fixture(scope="session")
def sad_clips() -> list[Clip]:
    """Three sad clips of 160 frames (435 closed frames) and one happy clip."""
    return [synthetic_clip(160, s) for s in range(3)] + [synthetic_clip(160, 9, "happy")]
