"""Limits on control messages: size, nesting depth, finite numbers and rate.

Every check runs before a message is interpreted and raises
:class:`~emotive.serve.errors.MessageError`, whose text becomes the ``error`` reply. The
nesting depth is measured by a scan of the brackets outside strings before ``json.loads``
sees the text, so ten thousand nested brackets never reach Python's recursion limit.
"""

from __future__ import annotations

import json
import math
import re
import time
from typing import Any

import numpy as np

from emotive.serve.errors import MessageError

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


def parse_message(text: str, max_bytes: int, max_depth: int) -> dict[str, Any]:
    """The JSON object of one control message, checked.

    Args:
        text: the websocket text message.
        max_bytes: its largest size in UTF-8 bytes.
        max_depth: its deepest bracket nesting.

    Raises:
        MessageError: too large, nested too deep, not JSON, holding NaN, Infinity or a number
            beyond float range, or not an object with a string ``type``.
    """
    size = len(text.encode("utf-8", "replace")) if len(text) * 4 > max_bytes else len(text)
    if size > max_bytes:
        raise MessageError(f"message of {size} bytes is larger than the limit of {max_bytes} "
                           "bytes: send smaller messages (e.g. fewer path points)")
    depth = nesting_depth(text)
    if depth > max_depth:
        raise MessageError(f"message nested {depth} levels deep; the limit is {max_depth}")
    try:
        value = json.loads(text, parse_constant=_refuse_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise MessageError(f"message is not JSON ({exc.msg} at character {exc.pos}): send one "
                           'JSON object such as {"type": "ping"}') from None
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

    def take(self) -> bool:
        """Take one token if there is one; ``False`` means the message is over the rate."""
        now = self._clock()
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate)
        self._last = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        return False
