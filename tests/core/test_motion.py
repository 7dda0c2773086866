"""Tests for emotive.core.motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.errors import EmotiveError
from emotive.transforms.np_rotations import axis_angle_to_quaternion, quaternion_normalize

SK = Skeleton(
    ("Root", "A", "B"), [-1, 0, 1], [[0, 0, 0], [1, 0, 0], [1, 0, 0]],
    end_site_parents=[2, 2], end_site_offsets=[[0.5, 0, 0], [0, 0.5, 0]],
)


def motion(frames: int = 4, seed: int = 0) -> Motion:
    rng = np.random.default_rng(seed)
    rot = quaternion_normalize(rng.normal(size=(frames, 3, 4)))
    pos = np.broadcast_to(SK.offsets, (frames, 3, 3)).copy()
    pos[:, 0] = rng.normal(size=(frames, 3))
    return Motion(SK, rot, pos, 30, {"name": "clip"})


class TestMotion:
    def test_smoke(self):
        m = motion()
        assert m.num_frames == 4 and m.fps == 30.0 and isinstance(m.fps, float)
        assert math.isclose(m.duration, 4 / 30)
        np.testing.assert_array_equal(m.root_positions, m.positions[:, 0])
        assert m.rotations.dtype == np.float64

    def test_zero_frames(self):
        m = Motion(SK, np.zeros((0, 3, 4)), np.zeros((0, 3, 3)), 30)
        assert m.num_frames == 0 and m.duration == 0
        assert m.positions_with_end_sites().shape == (0, 5, 3)

    @pytest.mark.parametrize(
        ("rot", "pos", "fps", "match"),
        [
            (np.zeros((2, 2, 4)), np.zeros((2, 3, 3)), 30, "rotations must have shape"),
            (np.zeros((2, 3, 3)), np.zeros((2, 3, 3)), 30, "rotations must have shape"),
            (np.zeros((2, 3, 4)), np.zeros((3, 3, 3)), 30, "positions must have shape"),
            (np.zeros((2, 3, 4)), np.zeros((2, 3, 3)), 0, "fps must be positive"),
        ],
    )
    def test_invalid(self, rot, pos, fps, match):
        with pytest.raises(EmotiveError, match=match):
            Motion(SK, rot, pos, fps)

    def test_replace(self):
        m = motion()
        m2 = m.replace(fps=60)
        assert m2.fps == 60 and m2.rotations is m.rotations and m.fps == 30
        with pytest.raises(AttributeError):
            m.fps = 10

    def test_global_transforms_known_pose(self):
        rot = np.zeros((1, 3, 4))
        rot[..., 0] = 1.0
        rot[0, 1] = axis_angle_to_quaternion(np.array([0.0, 0.0, math.pi / 2]))
        pos = np.broadcast_to(SK.offsets, (1, 3, 3)).copy()
        pos[0, 0] = [0, 1, 0]
        m = Motion(SK, rot, pos, 30)
        expected = [[0, 1, 0], [1, 1, 0], [1, 2, 0]]
        np.testing.assert_allclose(m.global_positions()[0], expected, atol=1e-12)
        grot, gpos = m.global_transforms()
        assert grot.shape == (1, 3, 4)
        np.testing.assert_allclose(gpos, m.global_positions())
        # End sites hang off joint B, turned 90 degrees about Z with A.
        ends = m.positions_with_end_sites()[0, 3:]
        np.testing.assert_allclose(ends, [[1, 2.5, 0], [0.5, 2, 0]], atol=1e-12)

    def test_positions_with_end_sites_batch(self):
        m = motion(6)
        out = m.positions_with_end_sites()
        assert out.shape == (6, 5, 3)
        np.testing.assert_allclose(out[:, :3], m.global_positions())
