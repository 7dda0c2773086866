"""Reading a BVH file's text within the reader's budgets: its lines and hierarchy words.

:func:`open_bvh_text` opens only a regular file no bigger than ``MAX_FILE_BYTES`` without
NUL bytes in its first 4 KiB; :class:`BVHLines` reads it one line at a time, each at most
``MAX_LINE_CHARS`` long (a frame row is refused as soon as it holds more values than
channels); :class:`HierarchyWords` gives the words of the hierarchy, each at most
``MAX_TOKEN_CHARS`` long, up to the line holding ``MOTION`` alone. So the reader never holds
more than one line of text, whatever the file. The limits are read from
:mod:`emotive.io.bvh_limits` when used; every problem is a :class:`~emotive.errors.BVHError`.
"""

from __future__ import annotations

import io
import math
import os
import stat
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from emotive.errors import BVHError
from emotive.io import bvh_limits
from emotive.io.bvh_limits import quote


class BVHLines:
    """The lines of an open BVH file, one at a time, each read at most ``MAX_LINE_CHARS`` long.

    Line ends are LF, CRLF or CR. A longer line is refused after ``MAX_LINE_CHARS`` characters
    (a frame row with more values than channels sooner), so no line is ever held whole.

    Args:
        path: the file, for messages.
        fh: the file opened as text (Latin-1, universal newlines).
    """

    def __init__(self, path: str, fh: io.TextIOBase) -> None:
        self.path = path
        self._fh = fh
        self._chars = 0
        #: 1-based number of the line last read (0 before the first).
        self.number = 0

    def next(self, width: int | None = None) -> str | None:
        """The next line without its end, or ``None`` at the end of the file.

        Args:
            width: values a frame row holds, when the line is one; a longer line is refused
                as holding too many values when its first ``MAX_LINE_CHARS`` characters do.
        """
        try:
            line = self._fh.readline(bvh_limits.MAX_LINE_CHARS + 1)
        except OSError as exc:
            raise BVHError(self.path, None, f"cannot be read ({exc.strerror})") from None
        if not line:
            return None
        self.number += 1
        self._chars += len(line)
        if self._chars > bvh_limits.MAX_FILE_BYTES:
            raise BVHError(
                self.path, None, f"grew past {bvh_limits.MAX_FILE_BYTES:,} bytes while being read"
            )
        if line.endswith("\n"):
            return line[:-1]
        if len(line) <= bvh_limits.MAX_LINE_CHARS:
            return line
        if width is not None and len(line.split(maxsplit=width)) > width:
            raise _too_wide(self.path, self.number, width)
        raise BVHError(
            self.path, self.number,
            f"the line is longer than {bvh_limits.MAX_LINE_CHARS:,} characters, the most "
            "read: this is not a BVH file, or its lines are joined (a BVH file has one frame "
            "per line); break the line",
        )


def _too_wide(path: str, line: int, width: int) -> BVHError:
    """The error for frame row ``line`` holding more than ``width`` values."""
    return BVHError(
        path, line,
        f"a frame row holds more than the {width} values the hierarchy's channels declare: "
        "fix the row or the CHANNELS",
    )


def _header_text(line: str) -> str:
    """A hierarchy line read as Latin-1, as UTF-8 when its bytes are (joint names may be)."""
    try:
        return line.encode("latin-1").decode("utf-8")
    except UnicodeDecodeError:
        return line


class HierarchyWords:
    """Whitespace words of the hierarchy with their 1-based line numbers, read lazily.

    The words end with the first line that holds ``MOTION`` alone (its number is
    ``motion_line``); the frame data after it is read from the same :class:`BVHLines`.

    Args:
        lines: the file's lines, not yet read.
    """

    def __init__(self, lines: BVHLines) -> None:
        self.path = lines.path
        self._lines = lines
        self._queue: deque[tuple[str, int]] = deque()
        #: Line of the word last returned by :meth:`next`.
        self.last_line = 1
        self._read_line = 1  # line of the last word queued
        self.motion_line: int | None = None

    def _fill(self) -> bool:
        """Queue the words of the next lines until there is one; ``False`` at the end."""
        while not self._queue and self.motion_line is None:
            line = self._lines.next()
            if line is None:
                return False
            number = self._lines.number
            if number == 1 and line.startswith("\xef\xbb\xbf"):  # UTF-8 byte order mark
                line = line[3:]
            for tok in _header_text(line).split():
                if len(tok) > bvh_limits.MAX_TOKEN_CHARS:
                    raise BVHError(
                        self.path, number,
                        f"a word of {len(tok):,} characters, {quote(tok)}: hierarchy words are "
                        f"at most {bvh_limits.MAX_TOKEN_CHARS} characters; shorten it",
                    )
                self._queue.append((tok, number))
                self._read_line = number
            if line.strip() == "MOTION":
                self.motion_line = number
        return bool(self._queue)

    @property
    def line(self) -> int:
        """Line of the next word, or of the last one at the end."""
        return self._queue[0][1] if self._fill() else self._read_line

    def error(self, problem: str) -> BVHError:
        """The error at the next word's line."""
        return BVHError(self.path, self.line, problem)

    def error_at_last(self, problem: str) -> BVHError:
        """The error at the line of the word just read."""
        return BVHError(self.path, self.last_line, problem)

    def next(self, what: str) -> str:
        """The next word; ``what`` names what is expected for the truncated-file error."""
        if not self._fill():
            raise self.error(f"file ends early while reading {what}: the file looks truncated")
        tok, self.last_line = self._queue.popleft()
        return tok

    def expect(self, word: str) -> None:
        """Read the next word, which must be ``word``."""
        tok = self.next(f"'{word}'")
        if tok != word:
            raise self.error_at_last(f"expected '{word}' but found {quote(tok)}")

    def number(self, what: str) -> float:
        """The next word as a finite number; ``what`` names it in the error."""
        tok = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise self.error_at_last(f"{what} must be a number, found {quote(tok)}") from None
        if not math.isfinite(value):
            raise self.error_at_last(f"{what} must be finite, found {quote(tok)}")
        return value

    def peek(self) -> str | None:
        """The next word without reading it, ``None`` at the end of the hierarchy."""
        return self._queue[0][0] if self._fill() else None


@contextmanager
def open_bvh_text(path: Path) -> Iterator[io.TextIOBase]:
    """A regular file opened as text; anything else is refused before it is opened."""
    try:
        info = os.stat(path)
    except FileNotFoundError:
        raise BVHError(path, None, "no such file: check the path") from None
    except OSError as exc:
        raise BVHError(path, None, f"cannot be read ({exc.strerror})") from None
    if stat.S_ISDIR(info.st_mode):
        raise BVHError(path, None, "is a directory, not a BVH file: pass the path of a .bvh file")
    try:
        # Non-blocking, then checked again on the open file: a FIFO swapped in after the
        # stat above must not block the read.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise BVHError(path, None, f"cannot be read ({exc.strerror})") from None
    with os.fdopen(fd, "rb") as raw:
        info = os.fstat(raw.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise BVHError(
                path, None,
                "is not a regular file (a pipe, socket or device): save the BVH to a file first",
            )
        if info.st_size > bvh_limits.MAX_FILE_BYTES:
            raise BVHError(
                path, None,
                f"is {info.st_size:,} bytes: at most {bvh_limits.MAX_FILE_BYTES:,} are read; "
                "split the clip",
            )
        try:
            head = raw.read(4096)
            raw.seek(0)
        except OSError as exc:
            raise BVHError(path, None, f"cannot be read ({exc.strerror})") from None
        if b"\x00" in head:
            raise BVHError(path, None, "is a binary file, not a BVH text file")
        # Latin-1 maps every byte to one character: numbers read as they are, names are
        # decoded as UTF-8 where they are (:func:`_header_text`).
        text = io.TextIOWrapper(raw, encoding="latin-1", newline=None)
        try:
            yield text
        finally:
            text.detach()
