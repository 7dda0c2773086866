"""Data-set loading: the preprocessing cache against parsing every BVH file again."""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

from bench.common import comparison, median_seconds
from emotive.data.clips import load_clips
from emotive.data.store import dataset_dir


def run(name: str = "bandai-namco-1", repeats: int = 3) -> list[dict]:
    """Seconds to load every clip of ``name`` from the cache against the first, parsing load.

    Runs in a private ``EMOTIVE_HOME`` so that the first load really parses the files.
    """
    old = os.environ.get("EMOTIVE_HOME")
    with tempfile.TemporaryDirectory() as home:
        os.environ["EMOTIVE_HOME"] = str(Path(home))
        try:
            dataset_dir(name)  # unpack outside the timing
            start = time.perf_counter()
            clips = load_clips(name)
            first = time.perf_counter() - start
            cached = median_seconds(lambda: load_clips(name), repeats=repeats, warmup=0)
        finally:
            if old is None:
                os.environ.pop("EMOTIVE_HOME", None)
            else:
                os.environ["EMOTIVE_HOME"] = old
    frames = sum(c.motion.num_frames for c in clips)
    return [
        comparison(f"load_clips[{name}, {len(clips)} clips, {frames} frames]", "s",
                   cached, first, "first load (parse + write cache)", higher_is_better=False),
    ]
