"""NumPy versions of :mod:`emotive.transforms.rotations` (same names, same conventions)."""

from __future__ import annotations

import numpy as np

from emotive.transforms import rotations as _r
from emotive.transforms.numpy_bridge import numpy_kernel

EULER_ORDERS = _r.EULER_ORDERS

quaternion_normalize = numpy_kernel(_r.quaternion_normalize)
quaternion_multiply = numpy_kernel(_r.quaternion_multiply)
quaternion_conjugate = numpy_kernel(_r.quaternion_conjugate)
quaternion_invert = numpy_kernel(_r.quaternion_invert)
quaternion_apply = numpy_kernel(_r.quaternion_apply)
quaternion_continuity = numpy_kernel(_r.quaternion_continuity)
quaternion_slerp = numpy_kernel(_r.quaternion_slerp)
quaternion_to_matrix = numpy_kernel(_r.quaternion_to_matrix)
matrix_to_quaternion = numpy_kernel(_r.matrix_to_quaternion)
euler_to_matrix = numpy_kernel(_r.euler_to_matrix)
matrix_to_euler = numpy_kernel(_r.matrix_to_euler)
euler_to_quaternion = numpy_kernel(_r.euler_to_quaternion)
quaternion_to_euler = numpy_kernel(_r.quaternion_to_euler)
axis_angle_to_quaternion = numpy_kernel(_r.axis_angle_to_quaternion)
quaternion_to_axis_angle = numpy_kernel(_r.quaternion_to_axis_angle)
matrix_to_rotation_6d = numpy_kernel(_r.matrix_to_rotation_6d)
rotation_6d_to_matrix = numpy_kernel(_r.rotation_6d_to_matrix)
quaternion_to_rotation_6d = numpy_kernel(_r.quaternion_to_rotation_6d)
rotation_6d_to_quaternion = numpy_kernel(_r.rotation_6d_to_quaternion)
quaternion_between = numpy_kernel(_r.quaternion_between)
yaw_quaternion = numpy_kernel(_r.yaw_quaternion)


def quaternion_mean(q, axis: int = 0):
    """Average rotation of unit quaternions along ``axis`` (NumPy only).

    Markley, Cheng, Crassidis and Oshman (2007), "Averaging quaternions": the eigenvector of the
    largest eigenvalue of ``sum q qᵀ``, which is blind to the sign of each ``q`` and needs no
    starting hemisphere. Returned with ``w >= 0``.

    Args:
        q: ``(..., N, ..., 4)`` unit quaternions, ``N`` along ``axis``.
        axis: the axis averaged over.

    Returns:
        The quaternions with ``axis`` removed, ``(..., 4)``; NaN where an input along ``axis``
        is not finite (as the other kernels, NaN in gives NaN out).
    """
    q = np.moveaxis(np.asarray(q, dtype=np.float64), axis, 0)
    scatter = np.einsum("n...i,n...k->...ik", q, q)
    bad = ~np.isfinite(scatter).all((-1, -2))
    scatter[bad] = np.eye(4)
    mean = np.linalg.eigh(scatter)[1][..., -1]
    mean = mean * np.where(mean[..., :1] < 0, -1.0, 1.0)
    mean[bad] = np.nan
    return mean
