"""Tests for emotive.core.skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

NAMES = ("Hips", "Spine", "Head", "LeftLeg", "RightLeg")
PARENTS = [-1, 0, 1, 0, 0]
OFFSETS = [[0, 1, 0], [0, 0.2, 0], [0, 0.5, 0], [0.1, 0, 0], [-0.1, 0, 0]]


def make(**kw) -> Skeleton:
    args = {"names": NAMES, "parents": PARENTS, "offsets": OFFSETS} | kw
    return Skeleton(**args)


class TestSkeleton:
    def test_smoke(self):
        sk = make(end_site_parents=[2], end_site_offsets=[[0, 0.1, 0]])
        assert sk.num_joints == 5
        assert sk.parents.dtype == np.int64 and sk.offsets.dtype == np.float64
        assert sk.end_site_offsets.shape == (1, 3)
        assert sk.index("LeftLeg") == 3

    def test_default_channels(self):
        sk = make()
        assert sk.channels[0][:3] == ("Xposition", "Yposition", "Zposition")
        assert sk.rotation_order(0) == "ZXY" and sk.rotation_order(1) == "ZXY"
        np.testing.assert_array_equal(sk.animated_translation, [True, False, False, False, False])

    def test_custom_channels(self):
        channels = [("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")]
        channels += [("Yrotation", "Xrotation", "Zrotation")] * 3 + [()]
        sk = make(channels=channels)
        assert sk.rotation_order(0) == "XYZ" and sk.rotation_order(1) == "YXZ"
        assert sk.rotation_order(4) == ""

    def test_children(self):
        assert make().children == [[1, 3, 4], [2], [], [], []]

    def test_immutable(self):
        sk = make()
        with pytest.raises(ValueError):
            sk.offsets[0, 0] = 5.0
        with pytest.raises(AttributeError):
            sk.names = ("x",)

    def test_scaled_and_same_as(self):
        sk = make(end_site_parents=[2], end_site_offsets=[[0, 0.1, 0]])
        big = sk.scaled(100.0)
        np.testing.assert_allclose(big.offsets, sk.offsets * 100)
        np.testing.assert_allclose(big.end_site_offsets, [[0, 10, 0]])
        assert sk.same_as(make()) and not sk.same_as(big)
        assert not sk.same_as(make(names=("A", "B", "C", "D", "E")))

    @pytest.mark.parametrize(
        ("kw", "match"),
        [
            ({"names": (), "parents": [], "offsets": np.zeros((0, 3))}, "at least one joint"),
            ({"names": ("A", "A", "B", "C", "D")}, "duplicate joint names"),
            ({"parents": [-1, 0, 1]}, "expected parents"),
            ({"offsets": np.zeros((5, 2))}, "expected parents"),
            ({"parents": [-1, 2, 1, 0, 0]}, "topological"),
            ({"parents": [-2, 0, 1, 0, 0]}, "topological"),
            ({"channels": [("Xrotation",)]}, "channels for 5 joints"),
            ({"end_site_parents": [7], "end_site_offsets": [[0, 0, 0]]}, "end sites"),
            ({"end_site_parents": [1, 2], "end_site_offsets": [[0, 0, 0]]}, "end sites"),
        ],
    )
    def test_invalid(self, kw, match):
        with pytest.raises(RigError, match=match):
            make(**kw)

    def test_unknown_joint(self):
        with pytest.raises(RigError, match="'Tail' is not in the rig"):
            make().index("Tail")


def test_between_lists_the_joints_on_the_path_from_an_ancestor():
    sk = Skeleton(("a", "b", "c", "d", "e"), np.array([-1, 0, 1, 2, 0]), np.zeros((5, 3)))
    assert sk.between(0, 3) == [1, 2]
    assert sk.between(2, 3) == []
    assert sk.between(4, 3) is None and sk.between(3, 0) is None
