"""Shared fixtures of the MAR tests: the synthetic database and its search."""

from __future__ import annotations

import pytest
from mar_helpers import CONFIG, STYLES, examples

from emotive.models.mar.build import build_database


@pytest.fixture(scope="session")
def mar_db():
    """A database of every synthetic clip except take 2 of each (the held-out inputs)."""
    held = tuple(f"synthetic_{a}_{s}_2" for a in ("walk", "wave") for s in STYLES)
    return build_database(examples(3, skip=held), CONFIG)


@pytest.fixture(scope="session")
def mar_search(mar_db):
    from emotive.models.mar.search import PointCloudSearch

    return PointCloudSearch(mar_db)
