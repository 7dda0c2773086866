"""The plain NumPy kernels (``emotive.transforms.fast_np``) equal the torch kernels, and
``PoseFK`` gives the same positions for NumPy and torch input."""

from __future__ import annotations

import numpy as np
import torch

from emotive.transforms import fast_np
from emotive.transforms import np_rotations as ref
from emotive.transforms.kinematics import PoseFK, forward_kinematics_np

#: A small tree with two branches and two end sites.
PARENTS = (-1, 0, 1, 2, 0, 4, 1)
ENDS = (3, 5)


def test_kernels_equal_the_torch_kernels():
    rng = np.random.default_rng(0)
    q = rng.normal(size=(50, 4))
    p = rng.normal(size=(50, 4))
    v = rng.normal(size=(50, 3))
    aa = np.concatenate((rng.normal(size=(40, 3)), 1e-6 * rng.normal(size=(10, 3))))
    np.testing.assert_allclose(fast_np.qmul(q, p), ref.quaternion_multiply(q, p), atol=1e-12)
    unit = fast_np.qnormalize(q)
    np.testing.assert_allclose(unit, ref.quaternion_normalize(q), atol=1e-12)
    np.testing.assert_allclose(fast_np.qapply(unit, v), ref.quaternion_apply(unit, v),
                               atol=1e-12)
    np.testing.assert_allclose(fast_np.qmatrix(q), ref.quaternion_to_matrix(q), atol=1e-12)
    np.testing.assert_allclose(fast_np.expmap_to_quat(aa), ref.axis_angle_to_quaternion(aa),
                               atol=1e-12)
    np.testing.assert_allclose(fast_np.quat_to_expmap(q), ref.quaternion_to_axis_angle(q),
                               atol=1e-12)
    yaw = rng.uniform(-4, 4, 7)
    np.testing.assert_allclose(fast_np.yaw_quat(yaw), ref.yaw_quaternion(yaw), atol=1e-12)


def test_pose_fk_is_the_same_for_numpy_and_torch_and_matches_forward_kinematics():
    rng = np.random.default_rng(1)
    offsets = rng.normal(size=(len(PARENTS), 3))
    end_offsets = rng.normal(size=(len(ENDS), 3))
    fk = PoseFK(PARENTS, offsets, ENDS, end_offsets, dtype=torch.float64)
    rot = ref.quaternion_normalize(rng.normal(size=(4, len(PARENTS), 4)))
    out_np = fk(rot)
    out_torch = fk(torch.from_numpy(rot))
    assert isinstance(out_np, np.ndarray) and out_np.dtype == np.float64
    assert out_np.shape == (4, len(PARENTS) + len(ENDS), 3)
    np.testing.assert_allclose(out_np, out_torch.numpy(), atol=1e-12)
    _, joints = forward_kinematics_np(rot, np.broadcast_to(offsets, (4, *offsets.shape)), PARENTS)
    np.testing.assert_allclose(out_np[:, : len(PARENTS)], joints, atol=1e-12)
