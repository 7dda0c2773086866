"""Helpers of the gait network tests: a small Bandai-named rig, random poses and inputs.

A module of its own (not ``conftest``) so that test modules can import it by a unique name.
"""

from __future__ import annotations

import numpy as np
import torch

from emotive.core import Skeleton
from emotive.models.gait import GaitConfig, GaitInputs
from emotive.transforms.np_rotations import euler_to_quaternion
from rigs import RIG

NUM_JOINTS = len(RIG)
#: Euler orders cycled over the joints, so per-joint orders matter in the motion loss.
ORDERS = ("ZXY", "XYZ", "YZX")


def make_skeleton() -> Skeleton:
    """The :data:`RIG` with a translated root and joint ``j`` rotating in ``ORDERS[j % 3]``."""
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    channels = []
    for j in range(NUM_JOINTS):
        rot = tuple(f"{a}rotation" for a in ORDERS[j % len(ORDERS)])
        channels.append(("Xposition", "Yposition", "Zposition", *rot) if j == 0 else rot)
    return Skeleton(
        tuple(r[0] for r in RIG), np.array([r[1] for r in RIG]),
        np.array([r[2] for r in RIG], dtype=float), tuple(channels),
        end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends],
    )


def random_pose(
    skeleton: Skeleton, shape: tuple[int, ...], seed: int = 0, spread: float = 0.6
) -> tuple[torch.Tensor, torch.Tensor, np.ndarray]:
    """Random float64 local rotations ``(*shape, J, 4)``, local positions ``(*shape, J, 3)``
    (root moved about) and the Euler angles ``(*shape, J, 3)`` used, in each joint's order."""
    rng = np.random.default_rng(seed)
    euler = rng.uniform(-spread, spread, (*shape, NUM_JOINTS, 3))
    rotations = np.stack(
        [euler_to_quaternion(euler[..., j, :], skeleton.rotation_order(j))
         for j in range(NUM_JOINTS)], -2,
    )
    positions = np.broadcast_to(skeleton.offsets, (*shape, NUM_JOINTS, 3)).copy()
    positions[..., 0, :] += rng.normal(0, 1, (*shape, 3))
    return torch.from_numpy(rotations), torch.from_numpy(positions), euler


def random_inputs(
    config: GaitConfig, batch: int, frames: int | None, seed: int = 0,
    dtype: torch.dtype = torch.float64,
) -> GaitInputs:
    """Random network inputs: ``(B, T, ...)`` windows, or one ``(B, ...)`` frame when
    ``frames`` is None. Emotions are random convex combinations (per frame)."""
    g = torch.Generator().manual_seed(seed)
    lead = (batch,) if frames is None else (batch, frames)

    def randn(*size: int) -> torch.Tensor:
        return torch.randn(*lead, *size, generator=g, dtype=dtype)

    rotations = randn(config.num_joints, 4)
    rotations = rotations / rotations.norm(dim=-1, keepdim=True)
    emotion = torch.rand(*lead, config.num_labels, generator=g, dtype=dtype)
    return GaitInputs(
        rotations, randn(18), emotion / emotion.sum(-1, keepdim=True), randn(5), randn(3)
    )
