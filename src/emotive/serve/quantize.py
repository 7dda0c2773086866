"""Quantized numbers of the compact frame (``EMF2``): rotations in 48 bits, weights in 8.

Rotations use the *smallest three* code. A unit quaternion ``(w, x, y, z)`` and its negative
are the same rotation, so the one whose largest component (by magnitude) is positive is
kept; that component is then implied by the other three (``sqrt(1 - a² - b² - c²)``), which
all lie in ``[-1/√2, 1/√2]``. Each of those three is stored in 15 bits, and the index of the
largest component (0-3) in the top bits of the first two: ``uint16[3]`` per rotation,

* ``u[0] = q(a) | (i >> 1) << 15``, ``u[1] = q(b) | (i & 1) << 15``, ``u[2] = q(c)``,
* ``q(v) = round(16383 √2 v) + 16383`` in ``0..32766`` (0 is exact), and back
  ``v = (q - 16383) / (16383 √2)``,

where ``a, b, c`` are the components other than the largest, in ``w, x, y, z`` order. Each
stored component is off by at most half a step, ``1 / (2 √2 16383) = 2.16e-5``; the implied
one by at most three times that (the largest component is at least 1/2), so a decoded
rotation is within :data:`ROTATION_ERROR_RADIANS` of the encoded one.

Weights in ``[0, 1]`` are ``uint8`` (``round(255 w)``, error at most ``1/510``); values in
``[-1, 1]`` (valence, arousal) are ``int16`` (``round(32767 v)``, error at most
``1/65534``). Values outside the range are clipped to it first.

Legend: ``...`` any leading dimensions.
"""

from __future__ import annotations

import numpy as np

#: Code of a zero component; codes run from 0 to twice this (15 bits).
HALF = 16383
#: Components other than the largest, by the index of the largest (``w, x, y, z`` order).
OTHERS = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]], dtype=np.intp)
#: Largest angle (radians) between a unit quaternion's rotation and its decoded code: twice
#: the largest quaternion error ``√(3 + 9) / (2 √2 16383)`` (three stored components off by
#: half a step, the implied one by three halves), 1.5e-4 rad or 0.0086 degrees.
ROTATION_ERROR_RADIANS = 2.0 * float(np.sqrt(12.0) / (2.0 * np.sqrt(2.0) * HALF))
#: Largest error of a weight in ``[0, 1]`` after :func:`unit_to_uint8`.
WEIGHT_ERROR = 0.5 / 255.0
#: Largest error of a value in ``[-1, 1]`` after :func:`signed_to_int16`.
SIGNED_ERROR = 0.5 / 32767.0
_SQRT2 = float(np.sqrt(2.0))


def quaternion_to_smallest_three(q: np.ndarray) -> np.ndarray:
    """``(..., 3)`` ``uint16`` codes of ``(..., 4)`` quaternions ``(w, x, y, z)``.

    Quaternions need not be unit length (they are normalized first); a zero quaternion is
    coded as the identity.

    Raises:
        ValueError: the last axis is not 4 long.
    """
    q = np.asarray(q, dtype=np.float32)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternions have shape (..., 4), got {q.shape}")
    lead = q.shape[:-1]
    q = q.reshape(-1, 4)
    rows = np.arange(len(q))
    norm = np.sqrt(np.einsum("nk,nk->n", q, q))
    if not (norm > 1e-12).all():
        # A zero quaternion (never a rotation) becomes the identity, rather than NaNs.
        q = np.where((norm > 1e-12)[:, None], q, np.array([1, 0, 0, 0], np.float32))
        norm = np.maximum(norm, 1e-12)
    largest = np.abs(q).argmax(1)
    # One scale per quaternion: its norm, its sign (largest component positive) and the code.
    scale = np.where(q[rows, largest] < 0, -_SQRT2 * HALF, _SQRT2 * HALF) / np.where(
        norm > 1e-12, norm, 1.0)
    scaled = q * scale.astype(np.float32)[:, None]
    keep = np.ones(q.shape, dtype=bool)
    keep[rows, largest] = False
    rest = scaled[keep].reshape(-1, 3)
    np.rint(rest, out=rest)
    np.clip(rest, -HALF, HALF, out=rest)
    codes = (rest + HALF).astype(np.uint16)
    codes[:, 0] |= ((largest >> 1) << 15).astype(np.uint16)
    codes[:, 1] |= ((largest & 1) << 15).astype(np.uint16)
    return codes.reshape(*lead, 3)


def smallest_three_to_quaternion(codes: np.ndarray) -> np.ndarray:
    """``(..., 4)`` ``float32`` unit quaternions ``(w, x, y, z)`` of ``(..., 3)`` codes.

    The largest component of each result is non-negative.

    Raises:
        ValueError: the last axis is not 3 long.
    """
    codes = np.asarray(codes, dtype=np.uint16)
    if codes.shape[-1:] != (3,):
        raise ValueError(f"smallest-three codes have shape (..., 3), got {codes.shape}")
    largest = ((codes[..., 0] >> 15).astype(np.intp) << 1) | (codes[..., 1] >> 15)
    rest = ((codes & 0x7FFF).astype(np.float32) - HALF) * np.float32(1.0 / (_SQRT2 * HALF))
    implied = np.sqrt(np.maximum(1.0 - np.einsum("...k,...k->...", rest, rest), 0.0))
    out = np.empty((*codes.shape[:-1], 4), dtype=np.float32)
    np.put_along_axis(out, OTHERS[largest], rest, -1)
    np.put_along_axis(out, largest[..., None], implied[..., None], -1)
    return out


def unit_to_uint8(values: np.ndarray) -> np.ndarray:
    """``uint8`` codes ``round(255 v)`` of values in ``[0, 1]`` (others clipped), same shape."""
    v = np.clip(np.asarray(values, dtype=np.float32), 0.0, 1.0)
    return np.rint(v * 255.0).astype(np.uint8)


def uint8_to_unit(codes: np.ndarray) -> np.ndarray:
    """``float32`` values in ``[0, 1]`` of :func:`unit_to_uint8` codes, same shape."""
    return np.asarray(codes, dtype=np.uint8).astype(np.float32) / 255.0


def signed_to_int16(values: np.ndarray) -> np.ndarray:
    """``int16`` codes ``round(32767 v)`` of values in ``[-1, 1]`` (others clipped)."""
    v = np.clip(np.asarray(values, dtype=np.float64), -1.0, 1.0)
    return np.rint(v * 32767.0).astype("<i2")


def int16_to_signed(codes: np.ndarray) -> np.ndarray:
    """``float32`` values in ``[-1, 1]`` of :func:`signed_to_int16` codes, same shape."""
    return (np.asarray(codes, dtype=np.int16) / 32767.0).astype(np.float32)
