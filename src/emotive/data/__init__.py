"""Data: the data set registry, download and cache, clip labels, splits, windows and emotions.

Modules:

* :mod:`~emotive.data.registry` -- known data sets, their archives, checksums and license.
* :mod:`~emotive.data.store` -- where data lives (``$EMOTIVE_HOME``, ``$EMOTIVE_DATA``,
  ``../shared/data``), fetching, checking, unpacking, verifying and repairing;
  :func:`dataset_dir`.
* :mod:`~emotive.data.manifest` -- each unpacked file's size and sha256, from the archive.
* :mod:`~emotive.data.clips` -- labelled clips, loading through a preprocessing cache.
* :mod:`~emotive.data.splits` -- deterministic train/val/test split by clip.
* :mod:`~emotive.data.windows` -- fixed-length windows, resampling, mirror augmentation.
* :mod:`~emotive.data.emotion` -- the one emotion model: weights over labels,
  valence/arousal, schedules over time.
* :mod:`~emotive.data.stats` -- frames per split, content and style.

The names below are imported from their modules on first access, so that importing the light
modules (``registry``, ``store``) does not load torch through the motion types.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Clip": "clips", "ClipInfo": "clips", "list_clips": "clips", "load_clips": "clips",
    "select_clips": "clips",
    "ALL_LABELS": "emotion", "DEFAULT_LABELS": "emotion", "VALENCE_AROUSAL": "emotion",
    "Emotion": "emotion", "EmotionSchedule": "emotion", "style_to_label": "emotion",
    "valence_arousal": "emotion", "weights_from_valence_arousal": "emotion",
    "REGISTRY": "registry", "DatasetInfo": "registry", "get_dataset": "registry",
    "SPLITS": "splits", "assign_splits": "splits", "split_clips": "splits",
    "dataset_dir": "store", "dataset_state": "store", "emotive_home": "store", "fetch": "store",
    "Windows": "windows", "make_windows": "windows",
    "frame_stats": "stats",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)


def __dir__() -> list[str]:
    return sorted({*globals(), *_EXPORTS})
