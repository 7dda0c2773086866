"""Splits by clip: disjoint, covering, every style in every part, deterministic."""

from __future__ import annotations

import random
from collections import Counter
from dataclasses import dataclass

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.data.clips import list_clips, load_clips
from emotive.data.splits import SPLITS, assign_splits, split_clips
from emotive.errors import DataError


@dataclass(frozen=True)
class C:
    name: str
    content: str
    style: str


def check_split(clips, parts) -> None:
    """Disjoint, covering, and every style with >= 3 clips present in every part."""
    names = [c.name for c in clips]
    seen = [c.name for s in SPLITS for c in parts[s]]
    assert sorted(seen) == sorted(names)
    assert len(set(seen)) == len(seen)
    per_style = Counter(c.style for c in clips)
    for split in SPLITS:
        styles = {c.style for c in parts[split]}
        for style, n in per_style.items():
            if n >= 3:
                assert style in styles, (split, style)
            elif split != "train":
                assert style not in styles, (split, style)


clip_sets = st.lists(
    st.tuples(st.sampled_from("abcde"), st.sampled_from(["walk", "run", "bow"]), st.integers(1, 9)),
    min_size=1, max_size=60, unique=True,
).map(lambda rows: [C(f"{s}_{c}_{t:03d}", c, s) for s, c, t in rows])


@settings(max_examples=60, deadline=None)
@given(clip_sets, st.integers(0, 5))
def test_properties(clips, seed):
    parts = split_clips(clips, seed=seed)
    check_split(clips, parts)
    shuffled = list(clips)
    random.Random(seed).shuffle(shuffled)
    assert assign_splits(shuffled, seed=seed) == assign_splits(clips, seed=seed)


def test_round_robin_over_contents():
    clips = [C(f"s_{c}_{t:03d}", c, "s") for c in ("walk", "run", "bow", "kick") for t in range(10)]
    parts = split_clips(clips, val_fraction=0.1, test_fraction=0.1)
    assert len(parts["test"]) == len(parts["val"]) == 4
    assert {c.content for c in parts["test"]} == {"walk", "run", "bow", "kick"}
    assert {c.content for c in parts["val"]} == {"walk", "run", "bow", "kick"}


def test_sizes_and_zero_fraction():
    clips = [C(f"x{i}", "walk", "happy") for i in range(3)]
    assert Counter(assign_splits(clips).values()) == {"train": 1, "val": 1, "test": 1}
    assert Counter(assign_splits(clips, val_fraction=0.0).values()) == {"train": 2, "test": 1}


def test_seed_changes_the_draw():
    clips = [C(f"x{i}", "walk", "happy") for i in range(50)]
    assert assign_splits(clips, seed=0) != assign_splits(clips, seed=1)


@pytest.mark.parametrize(("val", "test"), [(-0.1, 0.1), (0.5, 0.5), (1.0, 0.0)])
def test_bad_fractions(val, test):
    with pytest.raises(DataError, match="must each be in"):
        assign_splits([C("a", "walk", "s")], val, test)


def test_repeated_names():
    with pytest.raises(DataError, match="repeat"):
        assign_splits([C("a", "walk", "s"), C("a", "run", "s")])


@pytest.mark.parametrize(
    ("name", "locomotion"),
    [("bandai-namco-1", False), ("bandai-namco-1", True), ("bandai-namco-2-locomotion", False)],
)
def test_real_datasets(home, name, locomotion):
    clips = list_clips(name, locomotion=locomotion)
    parts = split_clips(clips)
    check_split(clips, parts)
    assert len(parts["train"]) > len(parts["val"]) > 0 and len(parts["test"]) > 0
    assert split_clips(list(reversed(clips))) == {s: list(reversed(v)) for s, v in parts.items()}


def test_loaded_clips_split_like_their_infos(home):
    loaded = load_clips("bandai-namco-1", locomotion=True)
    by_info = split_clips([c.info for c in loaded])
    by_clip = split_clips(loaded)
    assert {s: [c.info for c in v] for s, v in by_clip.items()} == by_info
