"""BVH parsing throughput: emotive's reader against bvhio, side by side on the same clips."""

from __future__ import annotations

from pathlib import Path

from bench.common import comparison, median_seconds
from emotive.io.bvh import read_bvh


def run(clips: list[Path], repeats: int = 3) -> list[dict]:
    """Frames per second parsing ``clips`` with each reader (median of ``repeats`` passes)."""
    import bvhio  # noqa: PLC0415 (heavy: bvhio)

    frames = sum(read_bvh(p).num_frames for p in clips)
    ours = median_seconds(lambda: [read_bvh(p) for p in clips], repeats=repeats, warmup=0)
    theirs = median_seconds(
        lambda: [bvhio.readAsBvh(str(p)) for p in clips], repeats=repeats, warmup=0
    )
    return [
        comparison(f"bvh_parse[{len(clips)} clips, {frames} frames]", "frames/s",
                   frames / ours, frames / theirs, "bvhio.readAsBvh"),
    ]
