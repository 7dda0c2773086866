"""Length-unit detection from the figure's standing height (:mod:`emotive.io.bvh_limits`)."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core import Skeleton
from emotive.core.rig_layouts import to_layout
from emotive.io import bvh_limits as limits
from emotive.io.bvh import read_bvh, write_bvh
from layout_clips import bandai_clip, synthetic_clip

UNITS = ("m", "cm", "mm", "in", "cmu")


def t_pose(motion):
    """The clip with its rig's arms held out sideways in the rest pose (a T-pose rig)."""
    sk = motion.skeleton
    offsets = sk.offsets.copy()
    for side, sign in (("L", 1.0), ("R", -1.0)):
        for name in (f"LowerArm_{side}", f"Hand_{side}"):
            j = sk.index(name)
            offsets[j] = (sign * np.linalg.norm(offsets[j]), 0.0, 0.0)
    rig = Skeleton(sk.names, sk.parents, offsets, sk.channels, sk.end_site_parents,
                   sk.end_site_offsets)
    positions = np.where(sk.animated_translation[None, :, None], motion.positions, offsets)
    return motion.replace(skeleton=rig, positions=positions)


@pytest.mark.parametrize("layout", ["bandai", "cmu", "mixamo", "unreal", "smplx"])
@pytest.mark.parametrize("unit", UNITS)
def test_each_unit_is_detected_on_every_layout(tmp_path, unit, layout):
    clip = synthetic_clip(frames=3)
    motion = clip if layout == "bandai" else to_layout(clip, layout)
    back = read_bvh(write_bvh(motion, tmp_path / "clip.bvh", unit=unit))
    assert back.metadata["file_unit"] == unit
    assert 1.6 < back.metadata["height_m"] < 1.9
    np.testing.assert_allclose(back.skeleton.offsets, motion.skeleton.offsets, atol=1e-6)


def test_a_cmu_figure_of_25_to_39_units_reads_as_cmu():
    for height in (22.0, 25.0, 30.0, 39.0):
        assert limits.detect_unit(height) == "cmu"
    assert limits.UNITS["cmu"] == pytest.approx(0.0254 / 0.45)
    assert limits.detect_unit(60.0) == "in" and limits.detect_unit(170.0) == "cm"


def test_height_is_standing_height_whatever_the_rest_pose(tmp_path):
    clip = synthetic_clip(frames=3)
    arms_down = read_bvh(write_bvh(clip, tmp_path / "down.bvh", unit="cm"))
    spread = read_bvh(write_bvh(t_pose(clip), tmp_path / "t.bvh", unit="cm"))
    assert spread.metadata["height_m"] == pytest.approx(arms_down.metadata["height_m"])
    # Head top to toe of this rig is 1.75 m.
    assert spread.metadata["height_m"] == pytest.approx(1.75, abs=0.1)
    back = read_bvh(write_bvh(t_pose(clip), tmp_path / "t.in.bvh", unit="in"))
    assert back.metadata["file_unit"] == "in"


def test_rigs_without_roles_fall_back_to_the_rest_pose_extent():
    sk = Skeleton(("a", "b", "c"), [-1, 0, 0], [[0, 0, 0], [0, 90, 0], [0, -80, 0]])
    assert limits.standing_height(sk) == pytest.approx(170.0)
    assert limits.detect_unit(limits.standing_height(sk)) == "cm"


def test_bandai_rest_laid_along_x_and_its_cmu_layout(bandai1_dir, tmp_path):
    clip = bandai_clip(bandai1_dir, frames=3)
    assert clip.metadata["file_unit"] == "cm"
    assert 1.4 < clip.metadata["height_m"] < 1.8
    for unit in UNITS:
        back = read_bvh(write_bvh(to_layout(clip, "cmu"), tmp_path / f"{unit}.bvh", unit=unit))
        assert back.metadata["file_unit"] == unit
        assert back.metadata["height_m"] == pytest.approx(clip.metadata["height_m"], rel=1e-6)
    cmu = read_bvh(write_bvh(to_layout(clip, "cmu"), tmp_path / "default.bvh"))
    assert cmu.metadata["file_unit"] == "cmu"
    sk = cmu.skeleton.scaled(1.0 / limits.UNITS["cmu"])
    assert 21 < limits.standing_height(sk) < 39
