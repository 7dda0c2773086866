"""Per-client outboxes on the event loop: frames fanned out without waiting for anyone.

Each connected client has an :class:`Outbox` holding at most ``buffered_frames`` frames (the
newest; an older one is dropped and counted, per client and in total) and its pending
replies, and the frame layout it asked for (:data:`~emotive.serve.frames.ENCODINGS`). The
simulation thread never touches an outbox: it encodes each frame once per layout in
:meth:`Hub.encodings` and :class:`LoopSink` hands the bytes to the event loop with
``call_soon_threadsafe``, where :meth:`Hub.publish` appends the same bytes object to every
outbox of that layout and returns.

A client is blamed only for its own backlog: it is marked stalled (and its session closes it
with 1008) when its socket has accepted nothing (the session's sender waits inside one send)
for ``stall_seconds`` counted only while frames reached the outbox on time, each within
:data:`ON_TIME_PERIODS` frame periods of the last. Time in which the server itself fell
behind (a slow tick, a busy event loop) never counts against a client. Replies are not
dropped: a client holding ``max_replies`` unread replies has no more of its messages read
(:meth:`Outbox.room`) until it reads some.
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from emotive.serve.frames import DEFAULT_ENCODING
from emotive.serve.settings import ServeSettings

#: A frame that reaches an outbox within this many frame periods of the last counts as on
#: time; a longer gap is the server's own delay and never counts against a client.
ON_TIME_PERIODS = 4.0


class Outbox:
    """What waits to be sent to one client: its replies first, then the newest frames.

    Args:
        client: the connection number.
        frames: frames kept at most.
        max_replies: replies kept before the client's messages stop being read.
        stall_seconds: seconds of its own backlog (see the module docstring) before it
            counts as stalled.
        period: the scene's frame period, seconds.
        clock: the time source, seconds.
        encoding: the frame layout it gets (1 or 2).
    """

    def __init__(self, client: int, frames: int, max_replies: int, stall_seconds: float,
                 period: float = 1.0 / 30.0, clock: Callable[[], float] = time.monotonic,
                 encoding: int = DEFAULT_ENCODING) -> None:
        self.client = client
        self.encoding = int(encoding)
        self.frames: deque[bytes] = deque()
        self.replies: deque[dict[str, Any]] = deque()
        self.max_frames = int(frames)
        self.max_replies = int(max_replies)
        self.stall_seconds = float(stall_seconds)
        self.on_time_gap = ON_TIME_PERIODS * float(period)
        self.dropped = 0
        self.stalled = asyncio.Event()
        self._ready = asyncio.Event()
        self._drained = asyncio.Event()
        self._clock = clock
        self._sending = False
        self._blocked = 0.0
        self._last_frame: float | None = None

    def put_frame(self, data: bytes) -> int:
        """Queue a frame, dropping the oldest beyond the bound; returns the frames dropped."""
        now = self._clock()
        if self._sending and self._last_frame is not None:
            gap = now - self._last_frame
            if gap <= self.on_time_gap:
                self._blocked += gap
                if self._blocked > self.stall_seconds:
                    self.stalled.set()
        self._last_frame = now
        dropped = 0
        if len(self.frames) >= self.max_frames:
            self.frames.popleft()
            dropped = 1
            self.dropped += 1
        self.frames.append(data)
        self._ready.set()
        return dropped

    def put_reply(self, message: dict[str, Any]) -> None:
        """Queue a reply (JSON-ready); none is ever dropped (see :meth:`room`)."""
        self.replies.append(message)
        self._ready.set()

    def has_room(self) -> bool:
        """Whether fewer than ``max_replies`` replies wait."""
        return len(self.replies) < self.max_replies

    async def room(self) -> None:
        """Wait until fewer than ``max_replies`` replies wait (the client reads them)."""
        while not self.has_room():
            self._drained.clear()
            await self._drained.wait()

    def sending(self, active: bool) -> None:
        """Mark the start (``True``) or the end of a send; an ended send clears the backlog."""
        self._sending = active
        if not active:
            self._blocked = 0.0

    async def next(self) -> dict[str, Any] | bytes:
        """The next thing to send: a reply if any is waiting, else the oldest kept frame."""
        while not (self.replies or self.frames):
            self._ready.clear()
            await self._ready.wait()
        if self.replies:
            reply = self.replies.popleft()
            self._drained.set()
            return reply
        return self.frames.popleft()


class Hub:
    """Every connected client's outbox, on the event loop.

    Args:
        settings: ``buffered_frames``, ``max_replies`` and ``stall_seconds``.
        period: the scene's frame period, seconds.
    """

    def __init__(self, settings: ServeSettings, period: float = 1.0 / 30.0) -> None:
        self.settings = settings
        self.period = float(period)
        self.outboxes: dict[int, Outbox] = {}
        self.dropped_frames = 0
        self._next = 0
        self._encodings: frozenset[int] = frozenset()

    def open(self, encoding: int = DEFAULT_ENCODING) -> Outbox:
        """A new client's outbox, for frames in layout ``encoding``."""
        s = self.settings
        box = Outbox(self._next, s.buffered_frames, s.max_replies, s.stall_seconds,
                     self.period, encoding=encoding)
        self._next += 1
        self.outboxes[box.client] = box
        self._encodings = frozenset(b.encoding for b in self.outboxes.values())
        return box

    def close(self, box: Outbox) -> None:
        """Forget a client."""
        self.outboxes.pop(box.client, None)
        self._encodings = frozenset(b.encoding for b in self.outboxes.values())

    def encodings(self) -> frozenset[int]:
        """The layouts the connected clients get (any thread: one read of a frozen set)."""
        return self._encodings

    def publish(self, frames: dict[int, bytes]) -> None:
        """Give one frame to every client, in its layout (event loop only).

        A client whose layout is missing (it connected after the frame was encoded) skips
        that frame.
        """
        for box in list(self.outboxes.values()):
            data = frames.get(box.encoding)
            if data is not None:
                self.dropped_frames += box.put_frame(data)

    def notice(self, client: int | None, message: dict[str, Any]) -> None:
        """Give a client a message, if still connected (``None``: all); event loop only."""
        boxes = (list(self.outboxes.values()) if client is None
                 else [b for b in (self.outboxes.get(client),) if b is not None])
        for box in boxes:
            box.put_reply(dict(message))


class LoopSink:
    """The simulation thread's :class:`~emotive.serve.simulation.Sink`: hands over to the loop.

    Args:
        hub: the clients.
        loop: the event loop the hub lives on.
    """

    def __init__(self, hub: Hub, loop: asyncio.AbstractEventLoop) -> None:
        self.hub = hub
        self.loop = loop

    def _call(self, fn: Callable[..., None], *args: Any) -> None:
        try:
            self.loop.call_soon_threadsafe(fn, *args)
        except RuntimeError:
            # The loop closed while the server stops; nobody is left to receive it.
            pass

    def encodings(self) -> frozenset[int]:
        """The layouts the connected clients get."""
        return self.hub.encodings()

    def frame(self, data: dict[int, bytes]) -> None:
        """Hand a frame (its bytes in each layout) to every client without waiting."""
        self._call(self.hub.publish, data)

    def notice(self, client: int | None, message: dict[str, Any]) -> None:
        """Hand a message to one client (``None``: every client) without waiting."""
        self._call(self.hub.notice, client, message)
