"""Tests for emotive.transforms.kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from emotive.transforms.kinematics import depth_levels, forward_kinematics, forward_kinematics_np
from emotive.transforms.rotations import (
    axis_angle_to_quaternion,
    quaternion_apply,
    quaternion_identity,
    quaternion_multiply,
    quaternion_normalize,
)

DT = torch.float64
CHAIN = [-1, 0, 1]
TREE = [-1, 0, 1, 1, 0, 4, 2]  # root, two branches, one of them forking


def rot_z(theta: float) -> torch.Tensor:
    return axis_angle_to_quaternion(torch.tensor([0.0, 0.0, theta], dtype=DT))


def loop_fk(lrot: torch.Tensor, lpos: torch.Tensor, parents: list[int]):
    """Reference FK, one joint at a time."""
    grot, gpos = [], []
    for j, p in enumerate(parents):
        if p < 0:
            grot.append(lrot[..., j, :])
            gpos.append(lpos[..., j, :])
        else:
            grot.append(quaternion_multiply(grot[p], lrot[..., j, :]))
            gpos.append(quaternion_apply(grot[p], lpos[..., j, :]) + gpos[p])
    return torch.stack(grot, -2), torch.stack(gpos, -2)


class TestDepthLevels:
    def test_levels(self):
        assert depth_levels(TREE) == [[0], [1, 4], [2, 3, 5], [6]]
        assert depth_levels([-1, -1, 0]) == [[0, 1], [2]]
        assert depth_levels([]) == []

    def test_not_topological(self):
        with pytest.raises(ValueError, match="topologically"):
            depth_levels([-1, 2, 0])


class TestForwardKinematics:
    offsets = torch.tensor([[0.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]], dtype=DT)

    def test_rest_pose_sums_offsets(self):
        grot, gpos = forward_kinematics(quaternion_identity((3,), dtype=DT), self.offsets, CHAIN)
        assert torch.allclose(gpos, torch.tensor([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]], dtype=DT))
        assert torch.equal(grot, quaternion_identity((3,), dtype=DT))

    def test_root_rotated_90_about_z(self):
        lrot = torch.stack((rot_z(math.pi / 2), *quaternion_identity((2,), dtype=DT)))
        _, gpos = forward_kinematics(lrot, self.offsets, CHAIN)
        expected = torch.tensor([[0.0, 0, 0], [0, 1, 0], [0, 2, 0]], dtype=DT)
        assert torch.allclose(gpos, expected, atol=1e-12)

    def test_two_joints_rotated_90_about_z(self):
        lrot = torch.stack((rot_z(math.pi / 2), rot_z(math.pi / 2), quaternion_identity(dtype=DT)))
        lpos = self.offsets + torch.tensor([[5.0, 0, 2], [0, 0, 0], [0, 0, 0]], dtype=DT)
        grot, gpos = forward_kinematics(lrot, lpos, CHAIN)
        # Root at (5, 0, 2); joint 1 one unit along +Y; joint 2 then turned a half turn: -X.
        expected = torch.tensor([[5.0, 0, 2], [5, 1, 2], [4, 1, 2]], dtype=DT)
        assert torch.allclose(gpos, expected, atol=1e-12)
        assert torch.allclose(grot[2].abs(), rot_z(math.pi).abs(), atol=1e-12)

    def test_batch_shapes_and_broadcast_offsets(self):
        g = torch.Generator().manual_seed(0)
        lrot = quaternion_normalize(torch.randn(2, 5, len(TREE), 4, generator=g, dtype=DT))
        offsets = torch.randn(len(TREE), 3, generator=g, dtype=DT)
        grot, gpos = forward_kinematics(lrot, offsets, TREE)
        assert grot.shape == (2, 5, len(TREE), 4) and gpos.shape == (2, 5, len(TREE), 3)
        ref_rot, ref_pos = loop_fk(lrot, offsets.expand(2, 5, -1, -1), TREE)
        assert torch.allclose(grot, ref_rot, atol=1e-12)
        assert torch.allclose(gpos, ref_pos, atol=1e-12)
        # Batched equals frame by frame.
        single_rot, single_pos = forward_kinematics(lrot[1, 3], offsets, TREE)
        assert torch.allclose(grot[1, 3], single_rot) and torch.allclose(gpos[1, 3], single_pos)

    def test_several_roots(self):
        lrot = quaternion_identity((3,), dtype=DT)
        lpos = torch.tensor([[1.0, 0, 0], [0, 2, 0], [0, 0, 3]], dtype=DT)
        _, gpos = forward_kinematics(lrot, lpos, [-1, -1, 1])
        assert torch.allclose(gpos, torch.tensor([[1.0, 0, 0], [0, 2, 0], [0, 2, 3]], dtype=DT))

    def test_gradient(self):
        g = torch.Generator().manual_seed(1)
        lrot = quaternion_normalize(torch.randn(2, len(TREE), 4, generator=g, dtype=DT))
        lpos = torch.randn(2, len(TREE), 3, generator=g, dtype=DT)
        assert torch.autograd.gradcheck(
            lambda a, b: forward_kinematics(a, b, TREE),
            (lrot.requires_grad_(), lpos.requires_grad_()),
        )

    def test_bad_shapes(self):
        with pytest.raises(ValueError, match="expected rotations"):
            forward_kinematics(torch.zeros(3, 3, dtype=DT), self.offsets, CHAIN)
        with pytest.raises(ValueError, match="3 joints"):
            forward_kinematics(quaternion_identity((2,), dtype=DT), self.offsets[:2], CHAIN)

    def test_numpy_wrapper(self):
        rng = np.random.default_rng(0)
        lrot = rng.normal(size=(4, len(TREE), 4))
        lrot /= np.linalg.norm(lrot, axis=-1, keepdims=True)
        lpos = rng.normal(size=(len(TREE), 3))
        grot, gpos = forward_kinematics_np(lrot, lpos, TREE)
        ref = forward_kinematics(torch.from_numpy(lrot), torch.from_numpy(lpos), TREE)
        assert isinstance(gpos, np.ndarray) and gpos.dtype == np.float64
        np.testing.assert_allclose(grot, ref[0].numpy())
        np.testing.assert_allclose(gpos, ref[1].numpy())


def test_pose_fk_matches_the_joint_loop_and_places_end_sites():
    from emotive.transforms.kinematics import PoseFK

    g = torch.Generator().manual_seed(4)
    offsets = torch.randn(len(TREE), 3, generator=g, dtype=DT)
    q = quaternion_normalize(torch.randn(5, len(TREE), 4, generator=g, dtype=DT))
    ends, end_offsets = [3, 6], torch.randn(2, 3, generator=g, dtype=DT)
    fk = PoseFK(TREE, offsets.numpy(), ends, end_offsets.numpy(), dtype=DT)
    got = fk(q)
    grot, gpos = loop_fk(q, offsets.expand(5, -1, -1), TREE)
    torch.testing.assert_close(got[:, :len(TREE)], gpos)
    expected = quaternion_apply(grot[:, ends], end_offsets) + gpos[:, ends]
    torch.testing.assert_close(got[:, len(TREE):], expected)
    assert PoseFK(CHAIN, np.zeros((3, 3)), dtype=DT)(q[:, :3]).shape == (5, 3, 3)


def test_pose_fk_batch_last_is_the_same_points_with_the_poses_last():
    from emotive.transforms.kinematics import PoseFK

    g = torch.Generator().manual_seed(5)
    offsets = torch.randn(len(TREE), 3, generator=g, dtype=DT)
    q = quaternion_normalize(torch.randn(7, len(TREE), 4, generator=g, dtype=DT))
    fk = PoseFK(TREE, offsets.numpy(), [3, 6], torch.randn(2, 3, generator=g, dtype=DT).numpy(),
                dtype=DT)
    last = fk.batch_last(q.permute(1, 2, 0).contiguous())
    assert last.shape == (len(TREE) + 2, 3, 7)
    torch.testing.assert_close(last.permute(2, 0, 1), fk(q))
    np.testing.assert_allclose(last.permute(2, 0, 1).numpy(), fk(q.numpy()), atol=1e-12)
