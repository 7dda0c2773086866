"""Pose vectors: encoding, decoding and streaming agree."""

from __future__ import annotations

import numpy as np
import pytest
from mar_helpers import styled

from emotive.models.mar.config import TransferError
from emotive.models.mar.representation import CodecState, RigCodec, RigMappingError


def test_decoding_the_encoded_clip_gives_back_its_world_positions():
    motion = styled("walk", "proud", frames=40)
    codec = RigCodec.for_motion(motion)
    vectors, points = codec.encode_motion(motion)
    assert vectors.shape == (40, codec.dim) and points.shape == (40, 21, 3)
    _, gpos, _ = codec.world_points(motion.rotations[:1], motion.positions[:1])
    roots, yaws, _ = codec.integrate(vectors[1:], np.ones(39),
                                     CodecState(gpos[0, codec.mover].copy(), 0.0))
    root0 = gpos[0, codec.mover][[0, 2]]
    rot, pos = codec.decode(vectors, np.concatenate((root0[None], roots)),
                            np.concatenate(([0.0], yaws)))
    rebuilt = motion.replace(rotations=rot, positions=pos).global_positions()
    np.testing.assert_allclose(rebuilt, motion.global_positions(), atol=1e-6)


def test_a_stream_of_frames_encodes_like_the_whole_clip():
    motion = styled("walk", "sad", frames=20)
    codec = RigCodec.for_motion(motion)
    whole, _ = codec.encode_motion(motion)
    state = None
    rows = []
    for t in range(20):
        v, _, state = codec.encode(motion.rotations[t:t + 1], motion.positions[t:t + 1], state)
        rows.append(v[0])
    np.testing.assert_allclose(np.stack(rows)[1:], whole[1:], atol=1e-9)


def test_lengths_are_in_leg_lengths_so_a_bigger_rig_encodes_alike():
    small = RigCodec.for_motion(styled("walk", "neutral", frames=10))
    big_motion = styled("walk", "neutral", frames=10, scale=1.5)
    big = RigCodec.for_motion(big_motion)
    assert big.leg == pytest.approx(1.5 * small.leg)
    np.testing.assert_allclose(big.encode_motion(big_motion)[0],
                               small.encode_motion(styled("walk", "neutral", frames=10))[0],
                               atol=1e-9)


def test_bad_rigs_and_nan_frames_raise_typed_errors():
    bad = styled("walk", "neutral", frames=10, rename={"UpperLeg_L": "thigh"})
    # The Bandai names lack the renamed joint (without a map its shape would name it).
    with pytest.raises(RigMappingError, match=r"synthetic_walk_neutral_0.*--roles"):
        RigCodec.for_motion(bad, "bandai")
    motion = styled("walk", "neutral", frames=10)
    rot = motion.rotations.copy()
    rot[4, 3, 0] = np.nan
    with pytest.raises(TransferError, match="frame 4 holds NaN"):
        RigCodec.for_motion(motion).encode_motion(motion.replace(rotations=rot))


def test_joints_near_180_degrees_encode_continuously_relative_to_the_reference():
    """Regression: a thigh hanging from the hips rotated by about pi (the Bandai rigs) flipped
    between ``theta n`` and ``-(2 pi - theta) n`` from frame to frame, so every average or
    regression of neighbours' poses gave nonsense legs."""
    from emotive.models.mar.representation import (
        rebase,
        reference_rotations,
        slot_quaternions,
    )
    from emotive.transforms.np_rotations import axis_angle_to_quaternion, quaternion_multiply

    motion = styled("walk", "neutral", frames=30)
    codec = RigCodec.for_motion(motion)
    thigh = int(np.flatnonzero(codec.below == motion.skeleton.names.index("UpperLeg_L"))[0])
    flip = axis_angle_to_quaternion(np.array([np.pi, 0.0, 0.0]))
    rot = motion.rotations.copy()
    rot[:, codec.below[thigh]] = quaternion_multiply(flip, rot[:, codec.below[thigh]])
    flipped = motion.replace(rotations=rot)
    plain, _ = codec.encode_motion(flipped)
    slot = slice(4 + 3 * (1 + thigh), 4 + 3 * (2 + thigh))
    # Without a reference the thigh's exponential map jumps by about 2 pi somewhere.
    assert np.abs(np.diff(plain[:, slot], axis=0)).max() > 3.0
    ref = reference_rotations([slot_quaternions(plain)])
    based = codec.with_reference(ref)
    vectors, _ = based.encode_motion(flipped)
    np.testing.assert_allclose(vectors, rebase(plain, ref), atol=1e-9)
    assert np.abs(np.diff(vectors[:, slot], axis=0)).max() < 0.2
    # The mean of two frames' exponential maps is a pose between them, and decoding is exact.
    rot_back, _ = based.decode(vectors, np.zeros((30, 2)), np.zeros(30))
    dots = np.abs((rot_back[:, codec.below] * flipped.rotations[:, codec.below]).sum(-1))
    np.testing.assert_allclose(dots, 1.0, atol=1e-9)
