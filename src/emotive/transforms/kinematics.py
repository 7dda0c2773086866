"""Forward kinematics for batched motion, differentiable in torch.

Legend: ``B`` batch dimensions (any number, possibly none), ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch

from emotive.transforms.fast_np import qmatrix
from emotive.transforms.numpy_bridge import numpy_kernel
from emotive.transforms.rotations import (
    quaternion_apply,
    quaternion_multiply,
    quaternion_rotate,
)


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
    loop runs over the tree depth, not over joints. The results are views with the joint axis
    second to last; call ``.contiguous()`` where a dense layout matters.

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
    # Joints first and contiguous: each level's gathers then copy whole blocks of memory.
    lrot = local_rotations.expand(*lead, n_joints, 4).movedim(-2, 0).contiguous()
    lpos = local_positions.expand(*lead, n_joints, 3).to(lrot.dtype).movedim(-2, 0).contiguous()
    levels = depth_levels(parents)
    # Every joint of depth d has its parent at depth d - 1: gather parents from the previous
    # level's block by their place in it, then put the blocks back in joint order at the end.
    place = np.empty(n_joints, dtype=np.int64)
    for level in levels:
        place[level] = np.arange(len(level))
    parent_arr = np.asarray(parents)
    rot_blocks: list[torch.Tensor] = []
    pos_blocks: list[torch.Tensor] = []
    device = lrot.device
    for level in levels:
        idx = torch.as_tensor(level, device=device)
        rots, poss = lrot.index_select(0, idx), lpos.index_select(0, idx)
        if parent_arr[level[0]] >= 0:
            pidx = torch.as_tensor(place[parent_arr[level]], device=device)
            prot = rot_blocks[-1].index_select(0, pidx)
            poss = quaternion_apply(prot, poss) + pos_blocks[-1].index_select(0, pidx)
            rots = quaternion_multiply(prot, rots)
        rot_blocks.append(rots)
        pos_blocks.append(poss)
    order = torch.as_tensor(np.argsort(np.concatenate(levels)), device=device)
    return (
        torch.cat(rot_blocks, 0).index_select(0, order).movedim(0, -2),
        torch.cat(pos_blocks, 0).index_select(0, order).movedim(0, -2),
    )


def forward_kinematics_np(
    local_rotations: np.ndarray, local_positions: np.ndarray, parents: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """NumPy wrapper of :func:`forward_kinematics` (same shapes, dtype preserved)."""
    return numpy_kernel(forward_kinematics)(local_rotations, local_positions, list(parents))


class _Tree(NamedTuple):
    """:class:`PoseFK`'s index arrays and offsets in one backend."""

    levels: list
    parents: list
    offsets: list
    end_parents: object
    end_offsets: object


class PoseFK:
    """Joint and end-site positions of one rig with fixed bone offsets, for many poses fast.

    :func:`forward_kinematics` takes any translations and recomputes the tree's levels on
    every call; streaming animation calls FK once per frame on a fixed rig, where that
    overhead dominates. Here levels, parents and offsets are prepared once and the rotations
    are composed one tree level at a time (NumPy: as matrices; torch: as quaternions).

    Args:
        parents: ``J`` parent indices in topological order.
        offsets: ``(J, 3)`` local translations (the roots' their positions).
        end_site_parents: ``E`` joints the end sites hang from.
        end_site_offsets: ``(E, 3)`` end-site offsets.
        dtype: float type of the computation.
    """

    def __init__(self, parents: Sequence[int], offsets: torch.Tensor | np.ndarray,
                 end_site_parents: Sequence[int] = (),
                 end_site_offsets: torch.Tensor | np.ndarray | None = None,
                 dtype: torch.dtype = torch.float32) -> None:
        levels = [np.asarray(level, dtype=np.int64) for level in depth_levels(parents)]
        ends = np.zeros((0, 3)) if end_site_offsets is None else np.asarray(end_site_offsets)
        self.num_joints = len(parents)
        # Index arrays and offsets once per backend: NumPy input is composed in float64
        # NumPy without a round trip through torch (faster for one streamed frame).
        # Offsets shaped (n, 1, 3, 1) per level: n joints, broadcast over the poses.
        column = np.array(offsets, dtype=np.float64)[:, None, :, None]
        self._numpy = _Tree(
            levels, [np.asarray(parents, dtype=np.int64)[level] for level in levels],
            [column[level] for level in levels],
            np.array(end_site_parents, dtype=np.int64),
            ends.reshape(-1, 1, 3, 1).astype(np.float64),
        )
        self._levels = [torch.as_tensor(level) for level in levels]
        # The torch path composes world rotations level by level into a tensor that only
        # grows (levels in order: no in-place writes, so it traces into ONNX), then rotates
        # every bone offset at once and sums the bones from the root to each point with one
        # product by the constant ancestor matrix.
        order = [int(j) for level in levels for j in level]
        at = {j: k for k, j in enumerate(order)}
        self._grown = [None if p[0] < 0 else torch.as_tensor([at[int(j)] for j in p])
                       for p in self._numpy.parents]
        bones = [j for j in range(self.num_joints) if parents[j] >= 0]
        ends_parents = [int(p) for p in self._numpy.end_parents]
        points = self.num_joints + len(ends_parents)
        self._bone_parent = torch.as_tensor([at[int(parents[j])] for j in bones] +
                                            [at[p] for p in ends_parents], dtype=torch.long)
        self._bone_offset = torch.as_tensor(np.concatenate(
            (np.asarray(offsets, dtype=np.float64)[bones], ends), 0)[:, :, None], dtype=dtype)
        ancestors = np.zeros((points, len(bones) + len(ends_parents)))
        root_offset = np.zeros((points, 3))
        column_of = {j: n for n, j in enumerate(bones)}
        chain_parent = list(parents) + ends_parents
        for p in range(points):
            j = p
            if p >= self.num_joints:
                ancestors[p, len(bones) + p - self.num_joints] = 1.0
                j = chain_parent[p]
            while parents[j] >= 0:
                ancestors[p, column_of[j]] = 1.0
                j = parents[j]
            root_offset[p] = np.asarray(offsets, dtype=np.float64)[j]
        self._ancestors = torch.as_tensor(ancestors, dtype=dtype)
        self._root_offset = torch.as_tensor(root_offset[:, :, None], dtype=dtype)

    def __call__(self, rotations: torch.Tensor | np.ndarray) -> torch.Tensor | np.ndarray:
        """``(B, J + E, 3)`` world positions of ``(B, J, 4)`` local unit quaternions.

        A tensor of the class's dtype for a tensor, float64 NumPy for NumPy.
        """
        # Joints first, poses second: each tree level then reads and writes whole contiguous
        # blocks of (B, 3, 3) matrices (1,000 poses: 30 % faster than poses first).
        if not isinstance(rotations, np.ndarray):
            return self._compose(rotations)
        tree, cat = self._numpy, np.concatenate
        local = qmatrix(np.swapaxes(rotations, 0, 1))
        world_r = np.empty((self.num_joints, rotations.shape[0], 3, 3))
        world_x = np.empty((self.num_joints, rotations.shape[0], 3, 1))
        for level, par, offsets in zip(tree.levels, tree.parents, tree.offsets, strict=True):
            if par[0] < 0:
                world_r[level] = local[level]
                world_x[level] = offsets
            else:
                pr = world_r[par]
                world_r[level] = pr @ local[level]
                world_x[level] = pr @ offsets + world_x[par]
        if len(tree.end_parents):
            ends = world_r[tree.end_parents] @ tree.end_offsets + world_x[tree.end_parents]
            world_x = cat((world_x, ends), 0)
        return world_x[..., 0].swapaxes(0, 1)

    def _compose(self, rotations: torch.Tensor) -> torch.Tensor:
        """The torch path of :meth:`__call__`: ``(B, J, 4)`` -> ``(B, J + E, 3)``."""
        rotations = rotations.to(self._ancestors.dtype).permute(1, 2, 0).contiguous()
        return self.batch_last(rotations).permute(2, 0, 1)

    def batch_last(self, rotations: torch.Tensor) -> torch.Tensor:
        """``(J + E, 3, B)`` points of ``(J, 4, B)`` rotations: the torch path, batch last.

        ``rotations`` must be of the class's dtype. With the poses last every product runs
        over long contiguous rows. World rotations are quaternion products per level; each
        point is its root's offset plus the sum of its bones rotated by their parents'
        world rotations (one matrix product over all points). On 1,000 poses this took 0.6
        of the time, and a fifth of the operations, of composing positions level by level
        with the poses first.
        """
        world_q = rotations
        for level, grown in zip(self._levels, self._grown, strict=True):
            if grown is None:
                world_q = rotations.index_select(0, level)
            else:
                world_q = torch.cat((world_q, quaternion_multiply(
                    world_q.index_select(0, grown), rotations.index_select(0, level), -2)), 0)
        bones = quaternion_rotate(world_q.index_select(0, self._bone_parent),
                                  self._bone_offset, -2)
        points = self._ancestors @ bones.flatten(1)
        return points.unflatten(1, (3, -1)) + self._root_offset
