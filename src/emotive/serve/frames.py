"""The binary frame layout of ``docs/serve.md``: one message per simulation frame.

Little-endian, every block 4-byte aligned: a 32-byte header (magic ``EMF1``, frame number
``uint32``, simulation time ``float64`` seconds, ``B``, ``J``, ``P``, ``C`` as ``uint32``),
then ``int32[B]`` agent ids, ``float32[B, 2]`` valence/arousal, ``float32[B, C]`` emotion
weights, ``float32[B, 3]`` mover world positions (metres), ``float32[B, J, 4]`` local
rotations ``(w, x, y, z)`` and ``float32[B, P, 3]`` world positions of joints then end sites.

Legend: ``B`` agents, ``J`` joints, ``P = J + E`` points (joints then end sites), ``C``
emotion labels.

Each frame is encoded once (:func:`encode_frame`) and the same bytes go to every client;
:func:`decode_frame` is its inverse, for tests, benchmarks and Python clients.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

import numpy as np

#: The first four bytes of every frame.
MAGIC = b"EMF1"
#: Header: magic, frame number, simulation time, B, J, P, C.
HEADER = struct.Struct("<4sIdIIII")


class Frame(NamedTuple):
    """One decoded frame.

    Attributes:
        number: frame number, from 0 at server start.
        time: simulation time, seconds.
        ids: ``(B,)`` agent ids.
        valence_arousal: ``(B, 2)`` valence and arousal on -1..1.
        emotion: ``(B, C)`` emotion weights.
        root: ``(B, 3)`` world position of the mover joint, metres.
        rotations: ``(B, J, 4)`` local rotations ``(w, x, y, z)``.
        world: ``(B, P, 3)`` world positions of joints then end sites, metres.
    """

    number: int
    time: float
    ids: np.ndarray
    valence_arousal: np.ndarray
    emotion: np.ndarray
    root: np.ndarray
    rotations: np.ndarray
    world: np.ndarray


def _f32(array: np.ndarray) -> bytes:
    return np.ascontiguousarray(array, dtype="<f4").tobytes()


def encode_frame(frame: Frame) -> bytes:
    """The bytes of one frame (see the module docstring).

    Args:
        frame: the frame; arrays of any float type, shapes as :class:`Frame` documents.

    Raises:
        ValueError: arrays whose shapes do not agree.
    """
    ids = np.asarray(frame.ids, dtype="<i4").reshape(-1)
    b = len(ids)
    rotations = np.asarray(frame.rotations)
    world = np.asarray(frame.world)
    emotion = np.asarray(frame.emotion)
    j = rotations.shape[1] if rotations.ndim == 3 else 0
    p = world.shape[1] if world.ndim == 3 else 0
    c = emotion.shape[1] if emotion.ndim == 2 else 0
    expected = {"valence_arousal": (b, 2), "emotion": (b, c), "root": (b, 3),
                "rotations": (b, j, 4), "world": (b, p, 3)}
    for name, shape in expected.items():
        got = np.shape(getattr(frame, name))
        if got != shape:
            raise ValueError(f"frame {name} has shape {got}, expected {shape}")
    header = HEADER.pack(MAGIC, frame.number & 0xFFFFFFFF, float(frame.time), b, j, p, c)
    return b"".join((header, ids.tobytes(), _f32(frame.valence_arousal), _f32(emotion),
                     _f32(frame.root), _f32(rotations), _f32(world)))


def decode_frame(data: bytes) -> Frame:
    """A frame from its bytes; the arrays are read-only views of ``data``.

    Raises:
        ValueError: not a frame (wrong magic) or a length that disagrees with the header.
    """
    if len(data) < HEADER.size:
        raise ValueError(f"a frame has at least {HEADER.size} bytes, got {len(data)}")
    magic, number, time, b, j, p, c = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise ValueError(f"not an emotive frame: magic {magic!r}, expected {MAGIC!r}")
    sizes = (b, b * 2, b * c, b * 3, b * j * 4, b * p * 3)
    expected = HEADER.size + 4 * sum(sizes)
    if len(data) != expected:
        raise ValueError(f"frame of B={b}, J={j}, P={p}, C={c} has {expected} bytes, "
                         f"got {len(data)}")
    offset, blocks = HEADER.size, []
    for k, count in enumerate(sizes):
        dtype = "<i4" if k == 0 else "<f4"
        blocks.append(np.frombuffer(data, dtype=dtype, count=count, offset=offset))
        offset += 4 * count
    ids, va, emotion, root, rotations, world = blocks
    return Frame(number, time, ids, va.reshape(b, 2), emotion.reshape(b, c), root.reshape(b, 3),
                 rotations.reshape(b, j, 4), world.reshape(b, p, 3))
