"""Tests of :mod:`emotive.eval.pose_errors` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stick_figures import unit_quaternions

from emotive.eval import pose_errors
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    euler_to_quaternion,
    quaternion_multiply,
    quaternion_normalize,
)


def test_identical_motions_have_zero_errors(rng):
    pos = rng.normal(size=(3, 10, 6, 3))
    q = unit_quaternions(rng, (3, 10, 6))
    np.testing.assert_allclose(pose_errors.pose_error(pos, pos), 0.0, atol=1e-12)
    np.testing.assert_allclose(pose_errors.pose_error(pos, pos, root_index=None), 0.0, atol=1e-12)
    np.testing.assert_allclose(pose_errors.rotation_error(q, q), 0.0, atol=1e-5)
    np.testing.assert_allclose(pose_errors.rotation_error(-q, q), 0.0, atol=1e-5)
    np.testing.assert_allclose(pose_errors.euler_angle_error(q, q, "ZXY"), 0.0, atol=1e-5)
    assert pose_errors.pose_error(pos, pos).shape == (3,)
    assert pose_errors.rotation_error(q, q, reduction="frame").shape == (3, 10)
    assert pose_errors.euler_angle_error(q, q, "XYZ", reduction="none").shape == (3, 10, 6)


def test_pose_error_is_relative_to_the_bounding_box_diagonal():
    # Two joints spanning a 1 x 2 x 2 box: diagonal 3, in every frame, wherever the body is.
    target = np.array([[[0.0, 0, 0], [1, 2, 2]]]).repeat(5, 0)
    target += np.arange(5)[:, None, None] * np.array([10.0, 0, 0])
    assert pose_errors.bounding_box_diagonal(target) == pytest.approx(3.0)
    predicted = target.copy()
    predicted[:, 1, 1] += 0.3
    assert pose_errors.pose_error(predicted, target) == pytest.approx(0.1)
    # World positions average the root's zero error in.
    assert pose_errors.pose_error(predicted, target, root_index=None) == pytest.approx(0.05)
    assert pose_errors.pose_error(predicted, target, scale=1.0) == pytest.approx(0.3)
    # A shifted trajectory leaves the root-relative pose error at zero.
    shifted = target + np.array([0.5, 0.0, -0.2])
    assert pose_errors.pose_error(shifted, target) == pytest.approx(0.0)
    assert pose_errors.pose_error(shifted, target, root_index=None) > 0


@settings(max_examples=40, deadline=None)
@given(
    q=st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(lambda v: np.linalg.norm(v) > 0.1),
    axis=st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
        lambda v: np.linalg.norm(v) > 0.1),
    degrees=st.floats(0.0, 179.5),
)
def test_a_rotation_offset_gives_its_angle(q, axis, degrees):
    q = quaternion_normalize(np.array(q))
    axis = np.array(axis) / np.linalg.norm(axis)
    offset = axis_angle_to_quaternion(axis * np.radians(degrees))
    for predicted in (quaternion_multiply(q, offset), -quaternion_multiply(offset, q)):
        error = pose_errors.rotation_error(predicted[None, None], q[None, None])
        assert error == pytest.approx(degrees, abs=1e-6)


def test_euler_error_of_a_known_offset_and_across_the_wrap():
    orders = ["ZXY", "XYZ"]
    true = np.radians([[[30.0, 20.0, -40.0], [179.0, 10.0, 5.0]]])
    pred = true.copy()
    pred[0, 0, 2] += np.radians(10.0)  # third angle of joint 0 off by 10 degrees
    pred[0, 1, 0] = np.radians(-179.0)  # first angle of joint 1 across +-180: 2 degrees off
    qt = np.stack([euler_to_quaternion(true[:, j], o) for j, o in enumerate(orders)], 1)
    qp = np.stack([euler_to_quaternion(pred[:, j], o) for j, o in enumerate(orders)], 1)
    np.testing.assert_allclose(
        pose_errors.euler_angle_error(qp[None], qt[None], orders, reduction="none"),
        [[[10.0, 2.0]]], atol=1e-6,
    )
    with pytest.raises(ValueError, match="one per joint"):
        pose_errors.euler_angle_error(qp, qt, ["ZXY"])


@pytest.mark.parametrize(
    ("fn", "a", "b"),
    [
        (pose_errors.pose_error, np.zeros((4, 3, 3)), np.zeros((4, 2, 3))),
        (pose_errors.pose_error, np.zeros((4, 3)), np.zeros((4, 3))),
        (pose_errors.rotation_error, np.zeros((4, 3, 3)), np.zeros((4, 3, 3))),
        (pose_errors.rotation_error, np.ones((2, 3, 4)), np.ones((1, 3, 4))),
    ],
)
def test_errors_reject_bad_shapes(fn, a, b):
    with pytest.raises(ValueError, match="shape"):
        fn(a, b)
