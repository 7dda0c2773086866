"""The MAR index of the default data sets: which clips go in, where it is cached, and its key.

The file name holds a hash of the config, the data sets' archives and the source of the
modules that compute the index (:data:`INDEX_SOURCES`), so a change to any of them builds a
new index on first use.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from emotive.data.clips import load_clips
from emotive.data.registry import get_dataset
from emotive.data.store import emotive_home
from emotive.models.mar.build import build_database
from emotive.models.mar.config import MARConfig
from emotive.models.mar.database import INDEX_FORMAT, Example, MARDatabase

__all__ = [
    "INDEX_SOURCES",
    "build_default_index",
    "clip_examples",
    "default_index_path",
    "index_key",
    "load_default_index",
]

log = logging.getLogger(__name__)

#: Modules whose source determines the index (part of the default file name).
INDEX_SOURCES = (
    "emotive.models.mar.database", "emotive.models.mar.build",
    "emotive.models.mar.default_index", "emotive.models.mar.registration",
    "emotive.models.mar.representation", "emotive.features.contacts",
)


def clip_examples(config: MARConfig, exclude: Sequence[str] = ()) -> list[Example]:
    """The labelled clips of the config's data sets and actions (minus ``exclude``)."""
    out = []
    for name in config.datasets:
        info = get_dataset(name)
        wanted = [a for a in config.actions if a in info.contents]
        if not wanted:
            continue
        for clip in load_clips(name, contents=wanted, progress=True):
            if clip.name in exclude:
                continue
            out.append(Example(clip.motion, name, clip.content, clip.info.emotion, clip.name))
    return out


def index_key(config: MARConfig) -> str:
    """Short hash naming the default index of a config.

    The data sets' archives and the source of the modules that compute the index
    (:data:`INDEX_SOURCES`).
    """
    digest = hashlib.sha256()
    for module in INDEX_SOURCES:
        digest.update(Path(importlib.import_module(module).__file__ or "").read_bytes())
    payload: dict[str, Any] = {
        "format": INDEX_FORMAT, "config": config.to_dict(), "code": digest.hexdigest(),
        "archives": [get_dataset(d).sha256 for d in config.datasets],
    }
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()[:16]


def default_index_path(config: MARConfig | None = None) -> Path:
    """``$EMOTIVE_HOME/mar/index-<key>.npz``."""
    return emotive_home() / "mar" / f"index-{index_key(config or MARConfig())}.npz"


def build_default_index(config: MARConfig | None = None, path: str | Path | None = None,
                        progress: bool = True) -> Path:
    """Build the index of the config's data sets and write it (default location if None)."""
    config = config or MARConfig()
    path = Path(path) if path is not None else default_index_path(config)
    db = build_database(clip_examples(config), config, progress=progress)
    return db.save(path)


def load_default_index(config: MARConfig | None = None, progress: bool = True) -> MARDatabase:
    """The default index, built on first use (with a progress bar)."""
    path = default_index_path(config)
    if not path.is_file():
        log.info("building the MAR index %s (once)", path)
        build_default_index(config, path, progress)
    return MARDatabase.load(path)
