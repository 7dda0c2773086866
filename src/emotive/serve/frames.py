"""The binary frame layouts of ``docs/serve.md``: one message per simulation frame.

Two layouts, both little-endian with every block 4-byte aligned and a 32-byte header whose
first eight bytes are the same (a 4-byte magic, then the frame number ``uint32``):

* **version 2**, magic ``EMF2`` (the default): header (magic, frame number, simulation time
  ``float64`` seconds, ``B``, ``J``, ``C``, a reserved ``uint32`` 0), then ``int32[B]`` agent
  ids, ``float32[B, 3]`` mover world positions (metres), ``uint16[B, J, 3]`` local rotations
  in the smallest-three code of :mod:`~emotive.serve.quantize`, ``int16[B, 2]`` valence
  and arousal (``round(32767 v)``) and ``uint8[B, C]`` emotion weights (``round(255 w)``),
  each block padded with zeros to a multiple of 4 bytes. No world positions: a client computes
  them from the rotations and the rig (:class:`~emotive.serve.rig.FrameRig`). About 171
  bytes per agent of the gait rig.
* **version 1**, magic ``EMF1``: header (magic, frame number, simulation time, ``B``, ``J``,
  ``P``, ``C`` as ``uint32``), then ``int32[B]`` agent ids and ``float32`` blocks:
  ``[B, 2]`` valence/arousal, ``[B, C]`` emotion weights, ``[B, 3]`` mover world positions,
  ``[B, J, 4]`` local rotations ``(w, x, y, z)`` and ``[B, P, 3]`` world positions of joints
  then end sites. About 776 bytes per agent.

Legend: ``B`` agents, ``J`` joints, ``P = J + E`` points (joints then end sites), ``C``
emotion labels.

Each frame is encoded once per layout some client asked for (:func:`encode_frame`) and the
same bytes go to every client of that layout; :func:`decode_frame` reads both, for tests,
benchmarks and Python clients.
"""

from __future__ import annotations

import struct
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from emotive.serve.quantize import (
    int16_to_signed,
    quaternion_to_smallest_three,
    signed_to_int16,
    smallest_three_to_quaternion,
    uint8_to_unit,
    unit_to_uint8,
)

if TYPE_CHECKING:
    from emotive.serve.rig import FrameRig

#: The first four bytes of every version-1 frame.
MAGIC = b"EMF1"
#: The first four bytes of every version-2 frame.
MAGIC_V2 = b"EMF2"
#: Version-1 header: magic, frame number, simulation time, B, J, P, C.
HEADER = struct.Struct("<4sIdIIII")
#: Version-2 header: magic, frame number, simulation time, B, J, C, reserved (0).
HEADER_V2 = struct.Struct("<4sIdIIII")
#: The layouts a client may ask for, by version number.
ENCODINGS = (1, 2)
#: The layout of a client that asks for none.
DEFAULT_ENCODING = 2


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
        world: ``(B, P, 3)`` world positions of joints then end sites, metres; ``None`` for a
            version-2 frame decoded without a rig.
    """

    number: int
    time: float
    ids: np.ndarray
    valence_arousal: np.ndarray
    emotion: np.ndarray
    root: np.ndarray
    rotations: np.ndarray
    world: np.ndarray | None = None


def _f32(array: np.ndarray) -> bytes:
    return np.ascontiguousarray(array, dtype="<f4").tobytes()


def _padded(data: bytes) -> bytes:
    return data + bytes(-len(data) % 4)


def _checked(frame: Frame, world: bool, codes: np.ndarray | None = None
             ) -> tuple[np.ndarray, int, int, int, int]:
    """``(ids, B, J, P, C)`` of a frame whose arrays agree (``P`` 0 without ``world``).

    With rotation ``codes`` the frame's float rotations may be ``None``.
    """
    ids = np.asarray(frame.ids, dtype="<i4").reshape(-1)
    b = len(ids)
    emotion = np.asarray(frame.emotion)
    c = emotion.shape[1] if emotion.ndim == 2 else 0
    p = 0
    expected = {"valence_arousal": (b, 2), "emotion": (b, c), "root": (b, 3)}
    if codes is None or frame.rotations is not None:
        rotations = np.asarray(frame.rotations)
        j = rotations.shape[1] if rotations.ndim == 3 else 0
        expected["rotations"] = (b, j, 4)
    else:
        j = codes.shape[1] if codes.ndim == 3 else 0
    if world:
        if frame.world is None:
            raise ValueError("a version-1 frame needs world positions; frame.world is None")
        shape = np.shape(frame.world)
        p = shape[1] if len(shape) == 3 else 0
        expected["world"] = (b, p, 3)
    for name, shape in expected.items():
        got = np.shape(getattr(frame, name))
        if got != shape:
            raise ValueError(f"frame {name} has shape {got}, expected {shape}")
    return ids, b, j, p, c


def encode_frame(frame: Frame, encoding: int = 1, rotation_codes: np.ndarray | None = None
                 ) -> bytes:
    """The bytes of one frame in layout ``encoding`` (see the module docstring).

    Args:
        frame: the frame; arrays of any float type, shapes as :class:`Frame` documents
            (``world`` is needed by version 1 only; ``rotations`` may be ``None`` in version
            2 when ``rotation_codes`` are given).
        encoding: the layout's version, 1 or 2.
        rotation_codes: version 2: ``(B, J, 3)`` smallest-three codes of ``frame.rotations``
            made already (e.g. by the step workers); ``None``: coded here.

    Raises:
        ValueError: an unknown version, or arrays whose shapes do not agree.
    """
    if encoding == 1:
        ids, b, j, p, c = _checked(frame, world=True)
        header = HEADER.pack(MAGIC, frame.number & 0xFFFFFFFF, float(frame.time), b, j, p, c)
        return b"".join((header, ids.tobytes(), _f32(frame.valence_arousal),
                         _f32(frame.emotion), _f32(frame.root), _f32(frame.rotations),
                         _f32(frame.world)))
    if encoding != 2:
        raise ValueError(f"frame encoding {encoding!r} is unknown; use one of {ENCODINGS}")
    given = None if rotation_codes is None else np.asarray(rotation_codes, dtype="<u2")
    ids, b, j, _, c = _checked(frame, world=False, codes=given)
    codes = quaternion_to_smallest_three(frame.rotations) if given is None else given
    if codes.shape != (b, j, 3):
        raise ValueError(f"rotation codes have shape {codes.shape}, expected {(b, j, 3)}")
    header = HEADER_V2.pack(MAGIC_V2, frame.number & 0xFFFFFFFF, float(frame.time), b, j, c, 0)
    return b"".join((header, ids.tobytes(), _f32(frame.root),
                     _padded(np.ascontiguousarray(codes, dtype="<u2").tobytes()),
                     signed_to_int16(frame.valence_arousal).tobytes(),
                     _padded(unit_to_uint8(frame.emotion).tobytes())))


def frame_bytes(encoding: int, agents: int, joints: int, points: int, labels: int) -> int:
    """Bytes of a frame of ``agents`` agents in layout ``encoding`` (1 or 2)."""
    b, j, p, c = agents, joints, points, labels
    if encoding == 1:
        return HEADER.size + 4 * b * (1 + 2 + c + 3 + 4 * j + 3 * p)

    def pad(n: int) -> int:
        return n + -n % 4

    return HEADER_V2.size + 20 * b + pad(6 * b * j) + pad(b * c)


def decode_frame(data: bytes, rig: FrameRig | None = None) -> Frame:
    """A frame from its bytes, in either layout (told apart by the magic).

    Version-1 arrays are read-only views of ``data``; version-2 arrays are decoded copies
    (``float32``), with ``world`` computed from the rotations when ``rig`` is given.

    Args:
        data: one binary websocket message.
        rig: the rig of ``/api/skeleton`` (:meth:`FrameRig.from_info`), for the world
            positions of version-2 frames.

    Raises:
        ValueError: not a frame (an unknown magic) or a length that disagrees with the header.
    """
    if len(data) < HEADER.size:
        raise ValueError(f"a frame has at least {HEADER.size} bytes, got {len(data)}")
    magic = bytes(data[:4])
    if magic == MAGIC_V2:
        return _decode_v2(data, rig)
    if magic != MAGIC:
        raise ValueError(f"not an emotive frame: magic {magic!r}, expected {MAGIC!r} or "
                         f"{MAGIC_V2!r}")
    _, number, time, b, j, p, c = HEADER.unpack_from(data)
    expected = frame_bytes(1, b, j, p, c)
    if len(data) != expected:
        raise ValueError(f"frame of B={b}, J={j}, P={p}, C={c} has {expected} bytes, "
                         f"got {len(data)}")
    offset, blocks = HEADER.size, []
    for k, count in enumerate((b, b * 2, b * c, b * 3, b * j * 4, b * p * 3)):
        dtype = "<i4" if k == 0 else "<f4"
        blocks.append(np.frombuffer(data, dtype=dtype, count=count, offset=offset))
        offset += 4 * count
    ids, va, emotion, root, rotations, world = blocks
    return Frame(number, time, ids, va.reshape(b, 2), emotion.reshape(b, c), root.reshape(b, 3),
                 rotations.reshape(b, j, 4), world.reshape(b, p, 3))


def _decode_v2(data: bytes, rig: FrameRig | None) -> Frame:
    _, number, time, b, j, c, _ = HEADER_V2.unpack_from(data)
    expected = frame_bytes(2, b, j, 0, c)
    if len(data) != expected:
        raise ValueError(f"version-2 frame of B={b}, J={j}, C={c} has {expected} bytes, "
                         f"got {len(data)}")
    offset = HEADER_V2.size

    def block(dtype: str, count: int) -> np.ndarray:
        nonlocal offset
        out = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
        offset += count * out.itemsize + -(count * out.itemsize) % 4
        return out

    ids = block("<i4", b)
    root = block("<f4", 3 * b).reshape(b, 3)
    rotations = smallest_three_to_quaternion(block("<u2", 3 * b * j).reshape(b, j, 3))
    va = int16_to_signed(block("<i2", 2 * b).reshape(b, 2))
    emotion = uint8_to_unit(block("u1", b * c).reshape(b, c))
    world = None if rig is None else rig.world(rotations, root)
    return Frame(number, time, ids, va, emotion, root.astype(np.float32), rotations, world)
