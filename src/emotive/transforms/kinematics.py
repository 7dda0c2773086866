"""Forward kinematics for batched motion, differentiable in torch.

Legend: ``B`` batch dimensions (any number, possibly none), ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from emotive.transforms.numpy_bridge import numpy_kernel
from emotive.transforms.rotations import quaternion_apply, quaternion_multiply


def depth_levels(parents: Sequence[int]) -> list[list[int]]:
    """Group joint indices by depth in the tree (root level first).

    ``parents`` must be in topological order (``parents[j] < j``, root ``-1``).
    """
    depth: list[int] = []
    for j, p in enumerate(parents):
        if p >= j:
            raise ValueError(f"parents must be topologically ordered; joint {j} has parent {p}")
        depth.append(0 if p < 0 else depth[p] + 1)
    levels: list[list[int]] = [[] for _ in range(max(depth, default=-1) + 1)]
    for j, d in enumerate(depth):
        levels[d].append(j)
    return levels


def forward_kinematics(
    local_rotations: torch.Tensor,
    local_positions: torch.Tensor,
    parents: Sequence[int],
) -> tuple[torch.Tensor, torch.Tensor]:
    """Global rotations and positions of every joint.

    The global transform of joint ``j`` is its parent's global transform composed with the
    local transform (translate by ``local_positions[j]``, then rotate by
    ``local_rotations[j]``): ``X_j = R_p(j) t_j + X_p(j)`` and ``R_j = R_p(j) q_j``.
    Root joints (parent ``-1``) take their local transform as global.

    Joints are processed level by level (all joints of one tree depth at once), so the Python
    loop runs over the tree depth, not over joints.

    Args:
        local_rotations: ``(B..., J, 4)`` unit quaternions, ``w, x, y, z``.
        local_positions: ``(B..., J, 3)`` joint offsets (or animated translations), broadcastable
            to the rotations' leading shape; for the root, its position.
        parents: ``J`` parent indices in topological order.

    Returns:
        ``(global_rotations (B..., J, 4), global_positions (B..., J, 3))``.
    """
    if local_rotations.shape[-1] != 4 or local_positions.shape[-1] != 3:
        raise ValueError(
            "expected rotations (..., J, 4) and positions (..., J, 3), got "
            f"{tuple(local_rotations.shape)} and {tuple(local_positions.shape)}"
        )
    n_joints = len(parents)
    if local_rotations.shape[-2] != n_joints or local_positions.shape[-2] != n_joints:
        raise ValueError(f"expected {n_joints} joints to match parents")
    lead = torch.broadcast_shapes(local_rotations.shape[:-2], local_positions.shape[:-2])
    lrot = local_rotations.expand(*lead, n_joints, 4)
    lpos = local_positions.expand(*lead, n_joints, 3).to(lrot.dtype)
    grot = [None] * n_joints
    gpos = [None] * n_joints
    parent_arr = np.asarray(parents)
    for level in depth_levels(parents):
        idx = torch.as_tensor(level)
        if parent_arr[level[0]] < 0:
            rots, poss = lrot[..., idx, :], lpos[..., idx, :]
        else:
            pidx = parent_arr[level]
            prot = torch.stack([grot[p] for p in pidx], -2)
            ppos = torch.stack([gpos[p] for p in pidx], -2)
            rots = quaternion_multiply(prot, lrot[..., idx, :])
            poss = quaternion_apply(prot, lpos[..., idx, :]) + ppos
        for n, j in enumerate(level):
            grot[j] = rots[..., n, :]
            gpos[j] = poss[..., n, :]
    return torch.stack(grot, -2), torch.stack(gpos, -2)


def forward_kinematics_np(
    local_rotations: np.ndarray, local_positions: np.ndarray, parents: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """NumPy wrapper of :func:`forward_kinematics` (same shapes, dtype preserved)."""
    return numpy_kernel(forward_kinematics)(local_rotations, local_positions, list(parents))
