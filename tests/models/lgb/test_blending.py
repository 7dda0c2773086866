"""Closing clips into one continuous sequence and fading joint-rotation jumps."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.models.lgb.blending import blend_jumps, close_sequences
from emotive.models.lgb.bootstrap import LGBError
from emotive.transforms.np_rotations import axis_angle_to_quaternion, quaternion_to_axis_angle


def test_close_sequences_is_continuous_and_closed():
    a = np.zeros((40, 2))
    b = np.ones((50, 2))
    out = close_sequences([a, b], blend=10)
    assert out.shape == (40 + 50 - 20, 2)
    # Every step, including the wrap-around from the last row to the first, is small.
    steps = np.abs(np.diff(np.concatenate((out, out[:1])), axis=0))
    assert steps.max() < 0.2
    with pytest.raises(LGBError, match="more than 20 frames"):
        close_sequences([a[:15], b], blend=10)


def test_blend_jumps_is_continuous_and_fades():
    t = np.linspace(0, 1, 40)
    aa = np.zeros((40, 2, 3))
    aa[:, 0, 0] = 0.2 * t
    aa[20:, 0, 0] += 0.8  # a jump of 0.8 rad at frame 20
    aa[:, 1, 1] = -0.1
    rot = axis_angle_to_quaternion(aa)
    jumps = np.zeros(40, bool)
    jumps[20] = True
    out = quaternion_to_axis_angle(blend_jumps(rot, jumps, 0.9))
    step = np.abs(np.diff(out[:, 0, 0]))
    assert step.max() < 0.1  # the 0.8 rad jump is spread out
    np.testing.assert_allclose(out[:20], aa[:20], atol=1e-12)  # untouched before the jump
    np.testing.assert_allclose(out[:, 1], aa[:, 1], atol=1e-12)  # still joints stay still
    gap = np.abs(out[20:, 0, 0] - aa[20:, 0, 0])
    assert np.all(np.diff(gap) < 0) and gap[-1] < 0.2 * gap[0]  # fades back to the data
