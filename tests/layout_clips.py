"""Clips on the Bandai rig for the rig-family tests (imported by name: ``tests/`` is on the path).

Other rig families are built from these with :func:`emotive.core.rig_layouts.to_layout`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.io.bvh import read_bvh
from emotive.transforms.np_rotations import euler_to_quaternion
from rigs import RIG


def synthetic_clip(frames: int = 12, seed: int = 0) -> Motion:
    """The small Bandai-named rig of :data:`rigs.RIG` in random poses, gliding forward."""
    rng = np.random.default_rng(seed)
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    sk = Skeleton(
        tuple(r[0] for r in RIG), np.array([r[1] for r in RIG]),
        np.array([r[2] for r in RIG], dtype=float),
        end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends],
    )
    rotations = euler_to_quaternion(rng.uniform(-0.5, 0.5, (frames, len(RIG), 3)), "ZXY")
    positions = np.broadcast_to(sk.offsets, (frames, len(RIG), 3)).copy()
    positions[:, 0, 2] += np.linspace(0.0, 1.0, frames)
    return Motion(sk, rotations, positions, 30.0, {"name": "synthetic"})


def bandai_clip(bandai1_dir: Path, frames: int = 30) -> Motion:
    """The first ``frames`` frames of a real dataset-1 walk."""
    motion = read_bvh(bandai1_dir / "data" / "dataset-1_walk_happy_001.bvh")
    return motion.replace(rotations=motion.rotations[:frames],
                          positions=motion.positions[:frames])
