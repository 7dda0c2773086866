"""The binary frame layout: round trips, the documented offsets, refusals."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from emotive.serve.frames import HEADER, MAGIC, Frame, decode_frame, encode_frame


def _frame(b: int = 3, j: int = 4, p: int = 6, c: int = 5, seed: int = 0) -> Frame:
    rng = np.random.default_rng(seed)
    return Frame(7, 1.25, np.arange(10, 10 + b), rng.normal(size=(b, 2)),
                 rng.random((b, c)), rng.normal(size=(b, 3)), rng.normal(size=(b, j, 4)),
                 rng.normal(size=(b, p, 3)))


def test_round_trip_keeps_every_field_as_float32():
    frame = _frame()
    back = decode_frame(encode_frame(frame))
    assert (back.number, back.time) == (7, 1.25)
    np.testing.assert_array_equal(back.ids, frame.ids)
    for name in ("valence_arousal", "emotion", "root", "rotations", "world"):
        np.testing.assert_array_equal(getattr(back, name),
                                      getattr(frame, name).astype(np.float32))


def test_layout_matches_the_documented_offsets():
    frame = _frame(b=2, j=3, p=4, c=2)
    data = encode_frame(frame)
    assert data[:4] == MAGIC and HEADER.size == 32
    assert struct.unpack_from("<I", data, 4)[0] == 7
    assert struct.unpack_from("<d", data, 8)[0] == 1.25
    assert struct.unpack_from("<4I", data, 16) == (2, 3, 4, 2)
    assert struct.unpack_from("<2i", data, 32) == (10, 11)
    va = np.frombuffer(data, "<f4", 4, 40)
    np.testing.assert_array_equal(va, frame.valence_arousal.astype(np.float32).ravel())
    assert len(data) == 32 + 4 * (2 + 4 + 4 + 6 + 24 + 24)
    assert len(data) % 4 == 0


def test_empty_scene_frame():
    frame = Frame(0, 0.0, np.zeros(0), np.zeros((0, 2)), np.zeros((0, 19)), np.zeros((0, 3)),
                  np.zeros((0, 22, 4)), np.zeros((0, 27, 3)))
    back = decode_frame(encode_frame(frame))
    assert back.ids.shape == (0,) and back.rotations.shape == (0, 22, 4)
    assert back.world.shape == (0, 27, 3) and back.emotion.shape == (0, 19)


def test_refuses_bad_shapes_and_bytes():
    frame = _frame()
    with pytest.raises(ValueError, match="root"):
        encode_frame(frame._replace(root=np.zeros((2, 3))))
    data = encode_frame(frame)
    with pytest.raises(ValueError, match="magic"):
        decode_frame(b"XXXX" + data[4:])
    with pytest.raises(ValueError, match="bytes"):
        decode_frame(data[:-4])
    with pytest.raises(ValueError, match="at least"):
        decode_frame(data[:10])
