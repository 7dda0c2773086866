"""Feature throughput: the batched affective-feature kernel against a per-frame loop of it."""

from __future__ import annotations

import torch

from bench.common import comparison, median_seconds
from emotive.core import Motion
from emotive.core.roles import resolve_roles
from emotive.features.affective import affective_features, affective_features_np


def run(motion: Motion, repeats: int = 5) -> list[dict]:
    """Frames per second of the features of ``motion`` (one clip, ``T`` frames)."""
    roles = resolve_roles(motion.skeleton)
    points = motion.positions_with_end_sites()
    frames = len(points)
    tensor = torch.from_numpy(points)

    def per_frame() -> None:
        with torch.no_grad():
            for t in range(frames):
                affective_features(tensor[t], roles)

    batched = median_seconds(lambda: affective_features_np(points, roles), repeats=repeats)
    looped = median_seconds(per_frame, repeats=max(1, repeats // 2))
    return [
        comparison(f"affective_features[{frames} frames]", "frames/s", frames / batched,
                   frames / looped, "per-frame loop of the same kernel"),
    ]
