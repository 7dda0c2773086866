"""Tests of :mod:`emotive.core.rig_layouts`: exact relayouts of Bandai clips."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.rig_layouts import LAYOUT_TABLE, LAYOUTS, Along, to_layout
from emotive.errors import RigError
from emotive.io.bvh import read_bvh, write_bvh
from layout_clips import bandai_clip, synthetic_clip


def corresponding(layout: str, source_names: tuple[str, ...]) -> list[tuple[int, int]]:
    """(layout joint index, Bandai joint index) of every joint standing for a Bandai joint."""
    specs = LAYOUT_TABLE[layout].joints
    return [(k, source_names.index(s.source)) for k, s in enumerate(specs)
            if isinstance(s.source, str) and s.source in source_names]


def world_error(source, target, layout: str) -> float:
    pairs = corresponding(layout, source.skeleton.names)
    k, j = np.array(pairs).T
    return float(np.abs(target.global_positions()[:, k] - source.global_positions()[:, j]).max())


@pytest.mark.parametrize("layout", LAYOUTS)
def test_synthetic_pose_is_kept(layout: str) -> None:
    source = synthetic_clip()
    target = to_layout(source, layout)
    assert world_error(source, target, layout) < 1e-6
    assert len(corresponding(layout, source.skeleton.names)) == source.skeleton.num_joints
    assert target.num_frames == source.num_frames and target.fps == source.fps
    assert target.metadata["layout"] == layout
    assert target.metadata["file_unit"] == LAYOUT_TABLE[layout].file_unit


@pytest.mark.parametrize("layout", LAYOUTS)
def test_layout_shape(layout: str) -> None:
    spec = LAYOUT_TABLE[layout]
    sk = to_layout(synthetic_clip(frames=2), layout).skeleton
    leaves = {j for j in range(sk.num_joints)} - set(sk.parents.tolist())
    assert leaves <= set(sk.end_site_parents.tolist()), "every leaf joint needs an end site"
    assert {sk.rotation_order(j) for j in range(sk.num_joints)} == {spec.rotation_order}
    assert sk.animated_translation[0]
    assert sk.num_joints > 22 or layout == "cmu-plain" or layout == "smpl"


def test_inserted_joints_carry_identity_rotations() -> None:
    target = to_layout(synthetic_clip(), "unreal")
    extra = [k for k, s in enumerate(LAYOUT_TABLE["unreal"].joints) if isinstance(s.source, Along)]
    assert len(extra) > 10
    np.testing.assert_allclose(np.abs(target.rotations[:, extra, 0]), 1.0, atol=1e-9)


def test_bandai_walk_on_every_layout_round_trips_through_bvh(bandai1_dir, tmp_path) -> None:
    source = bandai_clip(bandai1_dir, frames=20)
    for layout in LAYOUTS:
        target = to_layout(source, layout)
        assert world_error(source, target, layout) < 1e-6
        back = read_bvh(write_bvh(target, tmp_path / f"{layout}.bvh"))
        assert back.metadata["file_unit"] == LAYOUT_TABLE[layout].file_unit
        assert back.skeleton.names == target.skeleton.names
        assert np.abs(back.global_positions() - target.global_positions()).max() < 1e-5


def test_names_and_prefixes() -> None:
    source = synthetic_clip(frames=2)
    assert to_layout(source, "mixamo").skeleton.names[0] == "mixamorig:Hips"
    assert to_layout(source, "mixamo", prefix="mixamorig1:").skeleton.names[0] == "mixamorig1:Hips"
    assert to_layout(source, "mixamo", prefix="").skeleton.names[0] == "Hips"
    cmu = to_layout(source, "cmu").skeleton
    assert [cmu.names[k] for k in cmu.children[0]] == ["LHipJoint", "RHipJoint", "LowerBack"]
    assert {"Neck1", "LeftFingerBase", "LThumb", "LeftHandIndex1"} <= set(cmu.names)
    plain = to_layout(source, "cmu-plain").skeleton.names
    assert not {"LHipJoint", "LowerBack", "Neck1"} & set(plain)
    unreal = to_layout(source, "unreal").skeleton.names
    assert {f"spine_0{k}" for k in range(1, 6)} | {"ball_r", "calf_twist_01_l"} <= set(unreal)
    smplx = to_layout(source, "smplx").skeleton.names
    assert {"jaw", "left_eye_smplhf", "left_index3", "right_thumb1"} <= set(smplx)
    assert len(to_layout(source, "smpl").skeleton.names) == 24


def test_refuses_other_rigs_and_unknown_layouts() -> None:
    source = synthetic_clip(frames=2)
    with pytest.raises(RigError, match="unknown rig layout 'maya'"):
        to_layout(source, "maya")
    with pytest.raises(RigError, match="lacks the joints"):
        to_layout(to_layout(source, "cmu"), "mixamo")


def test_zero_frame_clip() -> None:
    source = synthetic_clip(frames=2)
    empty = source.replace(rotations=source.rotations[:0], positions=source.positions[:0])
    target = to_layout(empty, "cmu")
    assert target.num_frames == 0
    assert np.allclose(target.skeleton.offsets, to_layout(source, "cmu").skeleton.offsets)
