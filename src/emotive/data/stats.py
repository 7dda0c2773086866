"""Frame counts of a data set per split, content and style (the README's data table)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.data.clips import frame_counts, list_clips
from emotive.data.registry import get_dataset
from emotive.data.splits import SPLITS, assign_splits


@dataclass(frozen=True)
class FrameStats:
    """Frames and clips of one data set, per split.

    Attributes:
        dataset: registry name.
        contents: contents present, in the data set's label order (rows).
        styles: styles present, in label order (columns).
        frames: split (``train``, ``val``, ``test``, ``all``) -> ``(rows, columns)`` frames.
        clips: the same layout, counting clips.

    Frames are counted at the files' own rate (30 fps for the Bandai Namco data).
    """

    dataset: str
    contents: tuple[str, ...]
    styles: tuple[str, ...]
    frames: dict[str, np.ndarray]
    clips: dict[str, np.ndarray]


def frame_stats(
    name: str,
    *,
    locomotion: bool = False,
    val_fraction: float = 0.1,
    test_fraction: float = 0.1,
    seed: int = 0,
    progress: bool = False,
) -> FrameStats:
    """Count frames per style per content in each split of a data set.

    Args:
        name: registry name.
        locomotion: count only the locomotion contents (the split is made over those clips).
        val_fraction: share of validation clips, see :mod:`emotive.data.splits`.
        test_fraction: share of test clips, see :mod:`emotive.data.splits`.
        seed: seed of the split, see :mod:`emotive.data.splits`.
        progress: show a progress bar if the clips must be parsed first.
    """
    info = get_dataset(name)
    clips = list_clips(info, locomotion=locomotion)
    lengths = frame_counts(info, progress=progress)
    parts = assign_splits(clips, val_fraction, test_fraction, seed)
    contents = tuple(c for c in info.contents if any(x.content == c for x in clips))
    styles = tuple(s for s in info.styles if any(x.style == s for x in clips))
    frames = {s: np.zeros((len(contents), len(styles)), dtype=np.int64) for s in (*SPLITS, "all")}
    counts = {s: np.zeros_like(frames["all"]) for s in frames}
    for clip in clips:
        cell = contents.index(clip.content), styles.index(clip.style)
        for split in (parts[clip.name], "all"):
            frames[split][cell] += lengths[clip.name]
            counts[split][cell] += 1
    return FrameStats(info.name, contents, styles, frames, counts)
