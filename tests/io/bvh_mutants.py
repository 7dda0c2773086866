"""A deterministic fuzz corpus of hostile BVH files, made from the project's own writer.

:func:`base_text` writes a small synthetic walk (the shared rig of ``tests/rigs.py``) with
:func:`emotive.io.bvh.write_bvh`; :func:`mutants` derives over 2,000 files from it: byte
flips, token deletions and duplications, huge, tiny, NaN and infinite numbers (``Frame
Time`` 1e-310, 1e-9, 1e6, 1e308 among them), deep nesting, truncation, channel counts,
unbalanced braces, binary junk, CRLF, CR and a BOM, and the budgets of the reader (a line
or a frame row over 1 MiB, a word over 256 characters, a ``Frames:`` of 5,000 digits, more
values than the reader takes, figures of 1.7 cm and 170 m). Nothing is committed: the corpus
is rebuilt from a fixed seed on every run.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.io.bvh import write_bvh
from emotive.transforms.np_rotations import euler_to_quaternion
from rigs import RIG

#: Numbers a hostile file may hold where a plausible one is expected.
HOSTILE_NUMBERS = (
    "1e-310", "1e-9", "1e6", "1e308", "-1e308", "1e300", "1e-308", "nan", "NaN", "inf",
    "-inf", "Infinity", "1e999", "-1e999", "0", "-0", "0x10", "1_000", "+5", "--1", "1e",
    ".", "9" * 400, "1" * 5000, "2e1000", "4.9e-324", "1000.0001", "-999.9999", "7,5",
)
#: Frame times that must be refused or read as a plausible rate.
FRAME_TIMES = (
    "1e-310", "1e-9", "1e6", "1e308", "0", "-0.0333", "nan", "inf", "0.001", "1", "0.0009",
    "1.01", "0.0333333", "", "abc", "1e-3", "4.9e-324",
)
#: ``Frames:`` values, declared against the 5 rows that follow.
FRAME_COUNTS = ("0", "-1", "4", "6", "1000000", "1000001", "10000000", "10" * 40, "4.5",
                "5e0", "", "five", "1" * 4000, "1" * 5000, "333334")
N_FRAMES = 5


def base_motion(frames: int = N_FRAMES) -> Motion:
    """A short walk on the shared synthetic rig (metres, centimetres in the file)."""
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    sk = Skeleton(
        tuple(r[0] for r in RIG), np.array([r[1] for r in RIG]),
        np.array([r[2] for r in RIG], dtype=float),
        end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends],
    )
    euler = np.random.default_rng(26).uniform(-0.5, 0.5, (frames, len(RIG), 3))
    positions = np.broadcast_to(sk.offsets, (frames, len(RIG), 3)).copy()
    positions[:, 0, 2] = np.arange(frames) / 30.0
    return Motion(sk, euler_to_quaternion(euler, "ZXY"), positions, 30.0,
                  metadata={"file_unit": "cm"})


def base_text() -> str:
    """The BVH text of :func:`base_motion` as :func:`write_bvh` writes it."""
    with tempfile.TemporaryDirectory() as tmp:
        return write_bvh(base_motion(), Path(tmp) / "base.bvh").read_text()


def deep_chain(joints: int) -> str:
    """A hierarchy of ``joints`` joints, each the only child of the one before."""
    head = []
    for j in range(joints):
        kind = "ROOT" if j == 0 else "JOINT"
        head.append(f"{kind} J{j}\n{{\nOFFSET 0 0.5 0\nCHANNELS 3 Zrotation Xrotation Yrotation")
    body = "\n".join(head) + "\nEnd Site\n{\nOFFSET 0 1 0\n}\n" + "}\n" * joints
    return f"HIERARCHY\n{body}MOTION\nFrames: 1\nFrame Time: 0.0333333\n" + "0 " * 3 * joints


def _number_spans(text: str) -> list[tuple[int, int]]:
    return [m.span() for m in re.finditer(r"-?\d+(\.\d+)?(e[-+]?\d+)?", text)]


def _token_spans(text: str) -> list[tuple[int, int]]:
    return [m.span() for m in re.finditer(r"\S+", text)]


def _swap(text: str, span: tuple[int, int], new: str) -> str:
    return text[: span[0]] + new + text[span[1]:]


def _random_mutants(text: str, rng: np.random.Generator) -> Iterator[tuple[str, bytes]]:
    raw = text.encode()
    tokens, numbers = _token_spans(text), _number_spans(text)
    for n in range(500):
        buf = bytearray(raw)
        for _ in range(int(rng.integers(1, 4))):
            buf[int(rng.integers(len(buf)))] = int(rng.integers(256))
        yield f"byte_flip_{n}", bytes(buf)
    for n in range(300):
        span = tokens[int(rng.integers(len(tokens)))]
        yield f"token_delete_{n}", _swap(text, span, "").encode()
    for n in range(300):
        span = tokens[int(rng.integers(len(tokens)))]
        word = text[span[0]:span[1]]
        yield f"token_duplicate_{n}", _swap(text, span, f"{word} {word}").encode()
    for n in range(450):
        span = numbers[int(rng.integers(len(numbers)))]
        value = HOSTILE_NUMBERS[int(rng.integers(len(HOSTILE_NUMBERS)))]
        yield f"number_{n}", _swap(text, span, value).encode()
    for n in range(200):
        yield f"truncate_{n}", raw[: int(rng.integers(len(raw)))]
    for n in range(100):
        buf = bytearray(raw)
        at = int(rng.integers(len(buf)))
        buf[at:at] = rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8).tobytes()
        yield f"binary_junk_{n}", bytes(buf)


def _structural_mutants(text: str, rng: np.random.Generator) -> Iterator[tuple[str, bytes]]:
    chans = [m.span(1) for m in re.finditer(r"CHANNELS (\d+)", text)]
    for n in range(100):
        count = ("0", "1", "2", "4", "5", "7", "9", "1000", "-3", "6", "3")[n % 11]
        span = chans[int(rng.integers(len(chans)))]
        yield f"channel_count_{n}", _swap(text, span, count).encode()
    braces = [m.span() for m in re.finditer(r"[{}]", text)]
    for n in range(100):
        span = braces[int(rng.integers(len(braces)))]
        new = ("", "{", "}", "{ {", "} }")[n % 5]
        yield f"braces_{n}", _swap(text, span, new).encode()
    lines = text.splitlines(keepends=True)
    for n in range(100):
        at = int(rng.integers(len(lines)))
        cut = lines[:at] + lines[at + 1:] if n % 2 else lines[:at] + [lines[at]] * 2 + lines[at:]
        yield f"line_{'drop' if n % 2 else 'repeat'}_{n}", "".join(cut).encode()


def _targeted_mutants(text: str) -> Iterator[tuple[str, bytes]]:
    frame_time = re.search(r"Frame Time: (\S+)", text).span(1)
    for n, value in enumerate(FRAME_TIMES):
        yield f"frame_time_{n}_{value[:8]}", _swap(text, frame_time, value).encode()
    frames = re.search(r"Frames: (\S+)", text).span(1)
    for n, value in enumerate(FRAME_COUNTS):
        yield f"frames_{n}", _swap(text, frames, value).encode()
    for joints in (1, 2, 990, 1000, 1024, 1025, 5000):
        yield f"deep_{joints}", deep_chain(joints).encode()
    offsets = [m.span(1) for m in re.finditer(r"OFFSET (\S+)", text)]
    for n, scale in enumerate(("1e3", "1e4", "1e5", "1e6", "1e306", "1e-3", "1e-6")):
        body = text
        for span in reversed(offsets):
            body = _swap(body, span, f"{float(body[span[0]:span[1]] or 0) * float(scale):.9g}")
        yield f"offset_scale_{n}", body.encode()
    yield "crlf", text.replace("\n", "\r\n").encode()
    yield "cr_only", text.replace("\n", "\r").encode()
    yield "bom", b"\xef\xbb\xbf" + text.encode()
    yield "utf16", text.encode("utf-16")
    yield "tabs", text.replace(" ", "\t").encode()
    yield "empty", b""
    yield "only_whitespace", b" \n\t\r\n" * 100
    yield "nul_bytes", b"\x00" * 4096
    yield "header_only", text.split("MOTION")[0].encode()
    yield "no_newline_at_end", text.rstrip("\n").encode()
    yield "one_long_line", text.replace("\n", " ").encode()
    yield "latin1_name", text.replace("Hips", "H\xefps").encode("latin-1")
    yield "huge_row", (text.rstrip("\n") + " 0" * 100_000 + "\n").encode()
    yield "row_over_a_mebibyte", (text.rstrip("\n") + " 0" * 600_000 + "\n").encode()
    yield "blank_row_over_a_mebibyte", (text + " " * (1 << 21) + "\n").encode()
    yield "one_token_over_a_mebibyte", b"x" * (1 << 21)
    yield "long_joint_name", text.replace("Hips", "H" * 300).encode()
    yield "long_joint_name_in_bounds", text.replace("Hips", "H" * 256).encode()
    yield "long_non_numeric_value", _swap(text, _number_spans(text)[-1], "x" * 5000).encode()
    yield "second_offset", text.replace("OFFSET 0 95 0", "OFFSET 0 95 0\nOFFSET 0 95 0").encode()


def mutants(seed: int = 26) -> list[tuple[str, bytes]]:
    """Every mutant as ``(name, bytes)``, the same list for the same seed."""
    text = base_text()
    rng = np.random.default_rng(seed)
    out = [("base", text.encode())]
    out += list(_random_mutants(text, rng))
    out += list(_structural_mutants(text, rng))
    out += list(_targeted_mutants(text))
    return out
