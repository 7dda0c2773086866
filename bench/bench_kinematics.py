"""Forward-kinematics throughput: level-by-level batched FK against a joint-by-joint loop."""

from __future__ import annotations

import numpy as np
import torch

from bench.common import comparison, median_seconds
from emotive.core import Motion
from emotive.transforms.kinematics import forward_kinematics
from emotive.transforms.rotations import quaternion_apply, quaternion_multiply


def joint_loop_fk(rot: torch.Tensor, pos: torch.Tensor, parents) -> torch.Tensor:
    """Reference FK with one step per joint (the common straightforward implementation)."""
    grot, gpos = [], []
    for j, p in enumerate(parents):
        if p < 0:
            grot.append(rot[..., j, :])
            gpos.append(pos[..., j, :])
        else:
            grot.append(quaternion_multiply(grot[p], rot[..., j, :]))
            gpos.append(quaternion_apply(grot[p], pos[..., j, :]) + gpos[p])
    return torch.stack(gpos, -2)


def run(
    motion: Motion, sizes: tuple[tuple[int, int], ...] = ((1, 120), (64, 120), (1000, 1))
) -> list[dict]:
    """Frames per second of FK on ``(batch, window, J)`` windows of ``motion``'s rig.

    ``(1000, 1)`` is the shape of one streaming step of 1000 agents.
    """
    return [r for batch, window in sizes for r in _run_size(motion, batch, window)]


def _run_size(motion: Motion, batch: int, window: int) -> list[dict]:
    parents = list(motion.skeleton.parents)
    rng = np.random.default_rng(0)
    starts = rng.integers(0, max(1, motion.num_frames - window), batch)
    idx = (starts[:, None] + np.arange(window)[None]) % motion.num_frames
    rot = torch.from_numpy(motion.rotations[idx]).float()
    pos = torch.from_numpy(motion.positions[idx]).float()
    frames = batch * window
    with torch.no_grad():
        ours = median_seconds(lambda: forward_kinematics(rot, pos, parents), repeats=9)
        loop = median_seconds(lambda: joint_loop_fk(rot, pos, parents), repeats=9)
    return [
        comparison(f"fk_torch_float32[{batch}x{window}x{len(parents)}]", "frames/s",
                   frames / ours, frames / loop, "joint-by-joint loop"),
    ]
