"""Limits on control messages: size, nesting depth, values, finite numbers, rate and work.

Every check runs before a message is interpreted and raises
:class:`~emotive.serve.errors.MessageError`, whose text becomes the ``error`` reply. The
nesting depth is measured by a scan of the brackets outside strings before ``json.loads``
sees the text, so ten thousand nested brackets never reach Python's recursion limit, and the
values by a count of its commas, so that no message holds the interpreter for longer than a
fraction of a frame while it is parsed (``json.loads`` is one call that other threads cannot
interrupt). A message refused for ``NaN``, ``Infinity`` or a number beyond float range is
read once more, leniently, to recover its ``ref`` (:func:`ref_of`). :class:`TokenBucket`
bounds messages per second, :class:`WorkBudget` the seconds of a client's work per second
of scene time.
"""

from __future__ import annotations

import json
import math
import re
import threading
import time
from typing import Any

import numpy as np

from emotive.serve.errors import NO_REF, MessageError

#: A JSON string literal (its escapes included), blanked out before the depth scan.
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_OPEN = np.frombuffer(b"[{", dtype=np.uint8)
_CLOSE = np.frombuffer(b"]}", dtype=np.uint8)


def nesting_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` outside string literals in ``text``."""
    if text.count("[") + text.count("{") == 0:
        return 0
    raw = np.frombuffer(_STRING.sub('""', text).encode("utf-8", "replace"), dtype=np.uint8)
    steps = np.isin(raw, _OPEN).astype(np.int64) - np.isin(raw, _CLOSE).astype(np.int64)
    return int(np.cumsum(steps).max(initial=0))


def _refuse_constant(name: str) -> float:
    raise MessageError(f"control messages must hold finite numbers; found {name}: send a "
                       "number, not NaN or Infinity")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise MessageError(f"control messages must hold finite numbers; {text} is out of "
                           "range")
    return value


def check_size(text: str, max_bytes: int) -> int:
    """The UTF-8 size of a message, bytes (exact from ``max_bytes / 4`` characters up).

    Raises:
        MessageError: larger than ``max_bytes``.
    """
    size = len(text.encode("utf-8", "replace")) if len(text) * 4 > max_bytes else len(text)
    if size > max_bytes:
        raise MessageError(f"message of {size} bytes is larger than the limit of {max_bytes} "
                           "bytes: send smaller messages (e.g. fewer path points)")
    return size


def ref_of(text: str) -> Any:
    """The ``ref`` of a message, read leniently (NaN and Infinity as ``None``).

    :data:`~emotive.serve.errors.NO_REF` when the text is not a JSON object even so.
    """
    try:
        value = json.loads(text, parse_constant=lambda _: None)
    except (ValueError, RecursionError):
        return NO_REF
    return value.get("ref", NO_REF) if isinstance(value, dict) else NO_REF


#: Characters at the start of a message searched by :func:`head_ref`.
HEAD_CHARS = 256
_DECODER = json.JSONDecoder(parse_constant=_refuse_constant, parse_float=_finite_float)


def head_ref(text: str, limit: int = HEAD_CHARS) -> Any:
    """The ``ref`` of a message too large or too broken to parse, from its first characters.

    Scans at most ``limit`` characters, strings skipped whole, for the key ``"ref"`` of the
    outermost object and reads the value after it, which must end within them and hold only
    finite numbers. Clients that put ``ref`` first get it back on every refusal.

    Returns:
        The value, or :data:`~emotive.serve.errors.NO_REF` when the head holds none.
    """
    head = text[:limit]
    depth, i = 0, 0
    while i < len(head):
        char = head[i]
        if char == '"':
            end = i + 1
            while end < len(head) and head[end] != '"':
                end += 2 if head[end] == "\\" else 1
            if end >= len(head):
                return NO_REF
            colon = len(head) - len(head[end + 1:].lstrip())
            if depth == 1 and head[i:end + 1] == '"ref"' and head[colon:colon + 1] == ":":
                return _value_at(head, colon + 1)
            i = end + 1
            continue
        if char in "{[":
            depth += 1
        elif char in "}]":
            depth -= 1
        i += 1
    return NO_REF


def _value_at(head: str, start: int) -> Any:
    """The JSON value at ``head[start:]`` (after blanks), whole within ``head``, or NO_REF."""
    start = len(head) - len(head[start:].lstrip())
    try:
        value, _ = _DECODER.raw_decode(head, start)
    except (ValueError, RecursionError, MessageError):
        return NO_REF
    return value


def parse_message(text: str, max_bytes: int, max_depth: int,
                  max_values: int | None = None) -> dict[str, Any]:
    """The JSON object of one control message, checked.

    Args:
        text: the websocket text message.
        max_bytes: its largest size in UTF-8 bytes.
        max_depth: its deepest bracket nesting.
        max_values: most values (commas + 1) it may hold (``None``: no bound).

    Raises:
        MessageError: too large, nested too deep, holding too many values, not JSON,
            holding NaN, Infinity or a number beyond float range (then with the message's
            ``ref``), or not an object with a string ``type``.
    """
    check_size(text, max_bytes)
    values = text.count(",") + 1
    if max_values is not None and values > max_values:
        raise MessageError(f"message holds about {values} values; the limit is {max_values} "
                           "(a path of at most 10,000 points): send fewer points or keyframes",
                           head_ref(text))
    depth = nesting_depth(text)
    if depth > max_depth:
        raise MessageError(f"message nested {depth} levels deep; the limit is {max_depth}",
                           head_ref(text))
    try:
        value = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except MessageError as exc:
        raise MessageError(str(exc), ref_of(text)) from None
    except json.JSONDecodeError as exc:
        raise MessageError(f"message is not JSON ({exc.msg} at character {exc.pos}): send one "
                           'JSON object such as {"type": "ping"}', head_ref(text)) from None
    except RecursionError:
        raise MessageError(f"message nested too deep; the limit is {max_depth}") from None
    if not isinstance(value, dict):
        raise MessageError(f"a control message is a JSON object, got {type(value).__name__}: "
                           'send e.g. {"type": "ping"}')
    if not isinstance(value.get("type"), str):
        raise MessageError('a control message needs a "type" string, e.g. {"type": "ping"}')
    return value


class TokenBucket:
    """Messages allowed per second, with bursts: ``rate`` tokens a second, ``burst`` at most.

    Args:
        rate: tokens added per second.
        burst: the bucket's size (and its content at the start).
        clock: the time source, seconds (monotonic).
    """

    def __init__(self, rate: float, burst: int, clock: Any = time.monotonic) -> None:
        self.rate = float(rate)
        self.burst = float(burst)
        self._clock = clock
        self._tokens = float(burst)
        self._last = clock()

    def _refill(self) -> None:
        now = self._clock()
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate)
        self._last = now

    def delay(self) -> float:
        """Seconds until a token is there (0: one is there now)."""
        self._refill()
        return max(1.0 - self._tokens, 0.0) / self.rate

    def take(self) -> bool:
        """Take one token if there is one; ``False`` means the message is over the rate."""
        self._refill()
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False


class WorkBudget:
    """Seconds of the server's work one client may cost per second of scene time.

    A bucket of seconds: it refills at ``rate`` per second of ``clock`` (the scene's own
    time, frame number / fps, in the server, so that a scene slowed by a busy machine gives
    each client less work in the same wall second, never more of the scene's time) up to
    ``burst``. Work is charged after it ran (its cost is known only then: preparation off the
    scene's thread, commands and joins on it), so the bucket may go below zero; while it is,
    the client's messages are refused and its commands wait. Any thread may charge or ask.

    Args:
        rate: seconds of work per second of ``clock``.
        burst: the most seconds it may hold (and its content at the start).
        clock: the time source, seconds (e.g. the scene's time).
    """

    def __init__(self, rate: float, burst: float, clock: Any = time.monotonic) -> None:
        self.rate = float(rate)
        self.burst = float(burst)
        self._clock = clock
        self._left = float(burst)
        self._last = clock()
        self._lock = threading.Lock()

    def _refill(self) -> None:
        now = self._clock()
        self._left = min(self.burst, self._left + (now - self._last) * self.rate)
        self._last = now

    def allowed(self, seconds: float = 0.0) -> bool:
        """Whether more work may be done now.

        The bucket must hold more than zero, and ``seconds`` at least (for work expected to
        cost that much).
        """
        with self._lock:
            self._refill()
            return self._left > 0.0 and self._left >= seconds

    def charge(self, seconds: float) -> None:
        """Take the cost of some work, seconds."""
        with self._lock:
            self._refill()
            self._left -= max(float(seconds), 0.0)
