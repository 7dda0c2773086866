"""The compact frame layout (version 2): quantization bounds, the layout, world positions."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from emotive.serve.frames import (
    HEADER_V2,
    MAGIC_V2,
    Frame,
    decode_frame,
    encode_frame,
    frame_bytes,
)
from emotive.serve.quantize import (
    ROTATION_ERROR_RADIANS,
    SIGNED_ERROR,
    WEIGHT_ERROR,
    int16_to_signed,
    quaternion_to_smallest_three,
    signed_to_int16,
    smallest_three_to_quaternion,
    uint8_to_unit,
    unit_to_uint8,
)
from emotive.serve.rig import FrameRig
from emotive.transforms.fast_np import qapply
from emotive.transforms.kinematics import forward_kinematics_np

#: Float32 arithmetic on top of the quantization (relative to values of about 1).
FLOAT32 = 1e-6

finite = st.floats(-1e3, 1e3, allow_nan=False, width=64)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(...)`` rotation angle between unit quaternions (q and -q the same rotation)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    gap = np.minimum(np.linalg.norm(a - b, axis=-1), np.linalg.norm(a + b, axis=-1))
    return 4.0 * np.arcsin(np.minimum(gap / 2.0, 1.0))


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 40), st.just(4)), elements=finite)
       .filter(lambda q: (np.linalg.norm(q, axis=-1) > 1e-3).all()))
def test_rotations_round_trip_within_the_stated_angle(q):
    codes = quaternion_to_smallest_three(q)
    assert codes.dtype == np.uint16 and codes.shape == (len(q), 3)
    back = smallest_three_to_quaternion(codes)
    assert back.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(back, axis=-1), 1.0, atol=FLOAT32)
    assert _angle(back.astype(np.float64), q).max() <= ROTATION_ERROR_RADIANS + FLOAT32


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 3), st.floats(0.5, 1.0), st.integers(0, 2**32 - 1))
def test_the_worst_case_quaternions_stay_within_the_bound(largest, size, seed):
    # The largest component near 1/2 (four equal components) is where the implied one errs most.
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.0, 1.0, (200, 4))
    q[:, largest] = size
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    back = smallest_three_to_quaternion(quaternion_to_smallest_three(q))
    assert _angle(back.astype(np.float64), q).max() <= ROTATION_ERROR_RADIANS + FLOAT32
    # The bound is about 1.5e-4 rad (0.0086 degrees).
    assert ROTATION_ERROR_RADIANS == pytest.approx(1.495e-4, rel=1e-3)


def test_special_rotations():
    q = np.array([[1, 0, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1], [0.5, 0.5, 0.5, 0.5],
                  [0, 0, 0, 0], [0, -1e-9, 0, 0]], dtype=np.float64)
    back = smallest_three_to_quaternion(quaternion_to_smallest_three(q))
    assert _angle(back[:4].astype(np.float64), q[:4]).max() <= ROTATION_ERROR_RADIANS
    np.testing.assert_allclose(back[4], [1, 0, 0, 0])  # zero: the identity, not NaN
    assert np.isfinite(back).all()
    with pytest.raises(ValueError, match="4"):
        quaternion_to_smallest_three(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="3"):
        smallest_three_to_quaternion(np.zeros((2, 4), dtype=np.uint16))


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, st.integers(0, 50), elements=st.floats(-2, 2, width=64)))
def test_weights_and_signed_values_round_trip_within_their_bounds(v):
    unit = np.clip(v, 0.0, 1.0)
    assert np.abs(uint8_to_unit(unit_to_uint8(v)) - unit).max(initial=0) <= WEIGHT_ERROR + 1e-7
    signed = np.clip(v, -1.0, 1.0)
    assert (np.abs(int16_to_signed(signed_to_int16(v)) - signed).max(initial=0)
            <= SIGNED_ERROR + 1e-7)


def _frame(b: int, j: int = 5, c: int = 3, seed: int = 0) -> Frame:
    rng = np.random.default_rng(seed)
    rotations = rng.normal(size=(b, j, 4))
    rotations /= np.linalg.norm(rotations, axis=-1, keepdims=True)
    return Frame(4_000_000_000, 12.5, np.arange(100, 100 + b), rng.uniform(-1, 1, (b, 2)),
                 rng.random((b, c)), rng.normal(size=(b, 3)) * 50, rotations, None)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 30), st.integers(1, 25), st.integers(0, 21), st.integers(0, 1000))
def test_frames_round_trip_within_the_bounds(b, j, c, seed):
    frame = _frame(b, j, c, seed)
    data = encode_frame(frame, 2)
    assert len(data) == frame_bytes(2, b, j, 0, c) and len(data) % 4 == 0
    back = decode_frame(data)
    assert (back.number, back.time, back.world) == (frame.number, frame.time, None)
    np.testing.assert_array_equal(back.ids, frame.ids)
    np.testing.assert_array_equal(back.root, frame.root.astype(np.float32))
    assert np.abs(back.valence_arousal - frame.valence_arousal).max(initial=0) <= (
        SIGNED_ERROR + 1e-7)
    assert np.abs(back.emotion - frame.emotion).max(initial=0) <= WEIGHT_ERROR + 1e-7
    if b:
        assert _angle(back.rotations.astype(np.float64), frame.rotations).max() <= (
            ROTATION_ERROR_RADIANS + FLOAT32)


def test_layout_matches_the_documented_offsets():
    b, j, c = 3, 2, 3
    frame = _frame(b, j, c)
    data = encode_frame(frame, 2)
    assert HEADER_V2.size == 32 and data[:4] == MAGIC_V2
    assert struct.unpack_from("<I", data, 4)[0] == 4_000_000_000
    assert struct.unpack_from("<d", data, 8)[0] == 12.5
    assert struct.unpack_from("<4I", data, 16) == (b, j, c, 0)
    assert struct.unpack_from("<3i", data, 32) == (100, 101, 102)
    offset = 32 + 4 * b
    root = np.frombuffer(data, "<f4", 3 * b, offset)
    np.testing.assert_array_equal(root, frame.root.astype(np.float32).ravel())
    offset += 12 * b
    codes = np.frombuffer(data, "<u2", 3 * b * j, offset)
    np.testing.assert_array_equal(codes, quaternion_to_smallest_three(frame.rotations).ravel())
    offset += 6 * b * j + (-(6 * b * j) % 4)
    va = np.frombuffer(data, "<i2", 2 * b, offset)
    np.testing.assert_array_equal(va, np.rint(frame.valence_arousal * 32767).ravel())
    offset += 4 * b
    weights = np.frombuffer(data, "u1", b * c, offset)
    np.testing.assert_array_equal(weights, np.rint(frame.emotion * 255).ravel())
    assert len(data) == offset + b * c + (-(b * c) % 4)
    # A version-1 frame of the gait rig (J 22, P 27, C 19) is over 4.5 times larger.
    assert frame_bytes(1, 2000, 22, 27, 19) / frame_bytes(2, 2000, 22, 0, 19) > 4.5


def test_codes_made_elsewhere_stand_in_for_the_rotations():
    # The step workers code their rotations; the server then joins codes, not quaternions.
    frame = _frame(4)
    codes = quaternion_to_smallest_three(frame.rotations)
    assert encode_frame(frame._replace(rotations=None), 2, codes) == encode_frame(frame, 2)


def test_refuses_bad_frames():
    data = encode_frame(_frame(3), 2)
    with pytest.raises(ValueError, match="bytes"):
        decode_frame(data[:-4])
    with pytest.raises(ValueError, match="magic"):
        decode_frame(b"EMF3" + data[4:])
    with pytest.raises(ValueError, match="encoding"):
        encode_frame(_frame(3), 7)
    with pytest.raises(ValueError, match="world"):
        encode_frame(_frame(3), 1)
    with pytest.raises(ValueError, match="rotation codes"):
        encode_frame(_frame(3), 2, rotation_codes=np.zeros((3, 4, 3), np.uint16))


def test_world_positions_from_the_rig_match_forward_kinematics(random_motion):
    # The mover (here the root) takes its world position from the frame; every other joint
    # and end site hangs from it by the rig's offsets, turned by the rotations.
    motion = random_motion(frames=12)
    sk = motion.skeleton
    positions = np.broadcast_to(sk.offsets, motion.positions.shape).copy()
    positions[:, 0] = motion.positions[:, 0]
    glob_r, glob_x = forward_kinematics_np(motion.rotations, positions, sk.parents)
    ends = np.asarray(sk.end_site_parents)
    end_x = qapply(glob_r[:, ends], np.asarray(sk.end_site_offsets)) + glob_x[:, ends]
    expected = np.concatenate((glob_x, end_x), axis=1)
    rig = FrameRig(sk.parents, sk.offsets, 0, sk.end_site_parents, sk.end_site_offsets)
    np.testing.assert_allclose(rig.world(motion.rotations, glob_x[:, 0]), expected, atol=1e-9)
    # Through the compact frame: each joint turned by at most the stated angle per rotation
    # above it, so a point moves at most that angle times the lengths of the bones above it.
    frame = Frame(0, 0.0, np.arange(12), np.zeros((12, 2)), np.zeros((12, 1)),
                  glob_x[:, 0], motion.rotations, None)
    back = decode_frame(encode_frame(frame, 2), rig)
    reach = np.linalg.norm(sk.offsets, axis=-1).sum() + np.linalg.norm(
        np.asarray(sk.end_site_offsets), axis=-1).sum()
    bound = ROTATION_ERROR_RADIANS * sk.num_joints * reach + 1e-5
    assert np.abs(back.world - expected).max() <= bound


def test_rig_refuses_bad_shapes():
    with pytest.raises(ValueError, match="offsets"):
        FrameRig([-1, 0], np.zeros((3, 3)), 0)
    with pytest.raises(ValueError, match="mover"):
        FrameRig([-1, 0], np.zeros((2, 3)), 5)
    rig = FrameRig([-1, 0], np.zeros((2, 3)), 0)
    with pytest.raises(ValueError, match="rotations"):
        rig.world(np.zeros((1, 3, 4)), np.zeros((1, 3)))
