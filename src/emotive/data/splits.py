"""Deterministic train/validation/test splits by clip.

The rule (copied into the README):

1. The unit is the clip: one take, one file. Windows, frames and mirrored copies of a clip
   always land in the clip's part, so no recording is seen in two parts.
2. Clips are grouped by style (emotion). Within a style, every clip gets a key: the sha256 of
   ``"{seed}/{clip name}"``. Clips of each content are ranked by key, and the style's clips are
   ordered by (rank within their content, key): a round robin over the contents in a random but
   fixed order, so each part draws from as many contents as it can.
3. A style with ``n >= 3`` clips gives the first ``max(1, round(n * test_fraction))`` clips of
   that order to *test*, the next ``max(1, round(n * val_fraction))`` to *val* and the rest (at
   least one) to *train*; every such style is in all three parts. A style with fewer than 3
   clips goes to *train* only. (A fraction of exactly 0 leaves that part empty.)
4. The result depends only on the set of clips, the fractions and the seed, never on the order
   the clips are given in, the machine or the Python hash seed. The split is made over the clips
   passed in: filter first (e.g. locomotion only), then split.

Defaults: ``val_fraction = test_fraction = 0.1``, ``seed = 0``.
"""

from __future__ import annotations

import hashlib
from collections import defaultdict
from collections.abc import Iterable, Sequence
from typing import Protocol, TypeVar

import numpy as np

from emotive.errors import DataError

SPLITS: tuple[str, ...] = ("train", "val", "test")
#: Styles with fewer clips than this are kept in train only.
MIN_CLIPS_PER_STYLE = 3


class _Labelled(Protocol):
    @property
    def name(self) -> str: ...
    @property
    def content(self) -> str: ...
    @property
    def style(self) -> str: ...


C = TypeVar("C", bound=_Labelled)
T = TypeVar("T")


def _key(seed: int, name: str) -> str:
    return hashlib.sha256(f"{seed}/{name}".encode()).hexdigest()


def _part_sizes(n: int, val_fraction: float, test_fraction: float) -> tuple[int, int]:
    if n < MIN_CLIPS_PER_STYLE:
        return 0, 0
    n_test = max(1, round(n * test_fraction)) if test_fraction > 0 else 0
    n_val = max(1, round(n * val_fraction)) if val_fraction > 0 else 0
    while n_test + n_val > n - 1:
        if n_test >= n_val:
            n_test -= 1
        else:
            n_val -= 1
    return n_val, n_test


def assign_splits(
    clips: Iterable[C], val_fraction: float = 0.1, test_fraction: float = 0.1, seed: int = 0
) -> dict[str, str]:
    """``{clip name: "train" | "val" | "test"}`` by the rule in the module docstring.

    Args:
        clips: objects with ``name``, ``content`` and ``style`` (e.g. :class:`ClipInfo`).
        val_fraction: share of each style's clips for validation.
        test_fraction: share of each style's clips for testing.
        seed: changes the draw; the same seed gives the same split.

    Raises:
        DataError: fractions outside ``[0, 1)`` or summing to 1 or more, or repeated names.
    """
    if not (0 <= val_fraction < 1 and 0 <= test_fraction < 1 and val_fraction + test_fraction < 1):
        raise DataError(
            f"val_fraction={val_fraction} and test_fraction={test_fraction} must each be in "
            "[0, 1) and sum to less than 1"
        )
    clips = list(clips)
    names = [c.name for c in clips]
    if len(set(names)) != len(names):
        dup = sorted({n for n in names if names.count(n) > 1})
        raise DataError(f"clip names repeat ({dup[:3]}): split the clips of one data set at a time")
    by_style: dict[str, list[C]] = defaultdict(list)
    for clip in clips:
        by_style[clip.style].append(clip)
    out: dict[str, str] = {}
    for members in by_style.values():
        by_content: dict[str, list[C]] = defaultdict(list)
        for clip in members:
            by_content[clip.content].append(clip)
        rank: dict[str, int] = {}
        for group in by_content.values():
            for r, clip in enumerate(sorted(group, key=lambda c: _key(seed, c.name))):
                rank[clip.name] = r
        order = sorted(members, key=lambda c: (rank[c.name], _key(seed, c.name)))
        n_val, n_test = _part_sizes(len(order), val_fraction, test_fraction)
        for i, clip in enumerate(order):
            out[clip.name] = "test" if i < n_test else "val" if i < n_test + n_val else "train"
    return out


def split_clips(
    clips: Sequence[C], val_fraction: float = 0.1, test_fraction: float = 0.1, seed: int = 0
) -> dict[str, list[C]]:
    """The clips in ``{"train": [...], "val": [...], "test": [...]}``, each in input order.

    See :func:`assign_splits` for the arguments.
    """
    parts = assign_splits(clips, val_fraction, test_fraction, seed)
    return {s: [c for c in clips if parts[c.name] == s] for s in SPLITS}


def spread(items: Sequence[T], count: int) -> list[T]:
    """At most ``count`` items evenly spread over ``items``, in order (all when ``count`` is 0).

    For quick runs on a few clips of each split (the trainers' ``max_clips``): the kept items
    are at indices ``round(linspace(0, n - 1, count))``, so they cover the whole list, and the
    same list and count always keep the same items.

    Args:
        items: the ``n`` items, e.g. a split's clips.
        count: how many to keep (``0``: all).

    Returns:
        The kept items (``min(count, n)`` of them, or all ``n``).
    """
    if not count or count >= len(items):
        return list(items)
    keep = np.unique(np.linspace(0, len(items) - 1, count).round().astype(np.int64))
    return [items[i] for i in keep]
