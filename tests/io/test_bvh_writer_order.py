"""The BVH writer on rigs listed breadth first and on joints without channels."""

from __future__ import annotations

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.io.bvh import depth_first_order, read_bvh, write_bvh
from emotive.transforms.np_rotations import euler_to_quaternion


def _clip(channels=()) -> Motion:
    # Breadth first, as SMPL lists its joints: root, both hips, then both knees.
    names = ("pelvis", "left_hip", "right_hip", "left_knee", "right_knee")
    parents = np.array([-1, 0, 0, 1, 2])
    offsets = np.array([[0, 1, 0], [0.1, -0.05, 0], [-0.1, -0.05, 0], [0, -0.45, 0],
                        [0, -0.45, 0]], dtype=float)
    sk = Skeleton(names, parents, offsets, channels, end_site_parents=[3, 4],
                  end_site_offsets=[[0, -0.45, 0], [0, -0.45, 0]])
    rng = np.random.default_rng(0)
    rot = euler_to_quaternion(rng.uniform(-0.5, 0.5, (6, 5, 3)), "ZXY")
    if channels:
        rot[:, [j for j, c in enumerate(channels) if not any("rotation" in x for x in c)]] = \
            [1.0, 0.0, 0.0, 0.0]
    pos = np.broadcast_to(offsets, (6, 5, 3)).copy()
    pos[:, 0, 2] = np.linspace(0, 0.5, 6)
    return Motion(sk, rot, pos, 30.0)


def test_depth_first_order_lists_each_subtree_whole():
    assert depth_first_order(_clip().skeleton) == [0, 1, 3, 2, 4]


def test_a_breadth_first_rig_reads_back_with_the_same_pose(tmp_path):
    clip = _clip()
    back = read_bvh(write_bvh(clip, tmp_path / "bf.bvh", unit="m"))
    by_name = [back.skeleton.names.index(n) for n in clip.skeleton.names]
    np.testing.assert_allclose(back.global_positions()[:, by_name], clip.global_positions(),
                               atol=1e-6)


def test_a_joint_without_channels_is_written_with_zero_rotations(tmp_path):
    rot = ("Zrotation", "Xrotation", "Yrotation")
    channels = (("Xposition", "Yposition", "Zposition", *rot), rot, rot, (), rot)
    clip = _clip(channels)
    back = read_bvh(write_bvh(clip, tmp_path / "fixed.bvh", unit="m"))
    knee = back.skeleton.names.index("left_knee")
    np.testing.assert_allclose(back.rotations[:, knee], [[1.0, 0.0, 0.0, 0.0]] * 6, atol=1e-9)
    by_name = [back.skeleton.names.index(n) for n in clip.skeleton.names]
    np.testing.assert_allclose(back.global_positions()[:, by_name], clip.global_positions(),
                               atol=1e-6)
