"""Per-client outboxes on the event loop: frames fanned out without waiting for anyone.

Each connected client has an :class:`Outbox` holding at most ``buffered_frames`` frames (the
newest; an older one is dropped and counted, per client and in total) and its pending
replies, and the frame layout it asked for (:data:`~emotive.serve.frames.ENCODINGS`). The
simulation thread never touches an outbox: it encodes each frame once per layout in
:meth:`Hub.encodings` and :class:`LoopSink` hands the bytes to the event loop with
``call_soon_threadsafe``, where :meth:`Hub.publish` appends the same bytes object to every
outbox of that layout and returns.

A client that reads slowly is dropped by its unread backlog, counted in frames: the frames
made since the newest one it has read. What it has read is known from the bytes the server
handed to its socket and those still waiting there, unread (the transport's buffer and, on
Linux, the kernel's send queue: :func:`unread_bytes`); a frame whose last byte left that
queue was read. The backlog counts only while something waits unread (or a send waits for
room in the socket): a client that has read everything sent to it is up to date, so frames
the server itself was slow to send (a slow tick, a busy event loop) never count against it.
Once its backlog exceeds ``max_backlog_frames`` frames it is marked stalled, and its session
closes it with 1008. Replies are not dropped: a client holding ``max_replies`` unread replies
has no more of its messages read (:meth:`Outbox.room`) until it reads some.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
from collections import deque
from collections.abc import Callable
from typing import Any

from emotive.serve.frames import DEFAULT_ENCODING
from emotive.serve.settings import ServeSettings

try:  # Unix: a socket's send queue can be read with an ioctl
    import fcntl
    import termios
except ImportError:  # Windows: the transport's own buffer only
    fcntl = termios = None

#: The ioctl that reads a TCP socket's unsent and unacknowledged bytes (Linux ``SIOCOUTQ``).
SEND_QUEUE = getattr(termios, "TIOCOUTQ", None)


def unread_bytes(transport: Any) -> int:
    """Bytes handed to ``transport`` that its peer has not taken yet.

    The transport's own buffer, and where the system tells (Linux: ``SIOCOUTQ``) the bytes in
    the socket's send queue: not yet sent, or sent and not acknowledged. Bytes in the peer's
    receive buffer count as taken.
    """
    waiting = transport.get_write_buffer_size()
    sock = transport.get_extra_info("socket")
    if SEND_QUEUE is None or sock is None:
        return waiting
    with contextlib.suppress(OSError, ValueError):
        out = fcntl.ioctl(sock.fileno(), SEND_QUEUE, b"\0\0\0\0")
        waiting += struct.unpack("i", out)[0]
    return waiting


def ws_frame_bytes(payload: int) -> int:
    """Bytes of a websocket message of ``payload`` bytes from the server (unmasked header)."""
    return payload + (2 if payload < 126 else 4 if payload < 65536 else 10)


class Outbox:
    """What waits to be sent to one client: its replies first, then the newest frames.

    Args:
        client: the connection number.
        frames: frames kept at most.
        max_replies: replies kept before the client's messages stop being read.
        max_backlog: frames of unread backlog (see the module docstring) before it counts
            as stalled.
        encoding: the frame layout it gets (1 or 2).
        unread: bytes handed to its socket that it has not taken yet (:func:`unread_bytes`);
            ``None``: unknown (then only a send that waits for room counts).
    """

    def __init__(self, client: int, frames: int, max_replies: int, max_backlog: int,
                 encoding: int = DEFAULT_ENCODING,
                 unread: Callable[[], int] | None = None) -> None:
        self.client = client
        self.encoding = int(encoding)
        self.frames: deque[tuple[int, bytes]] = deque()
        self.replies: deque[dict[str, Any]] = deque()
        self.max_frames = int(frames)
        self.max_replies = int(max_replies)
        self.max_backlog = int(max_backlog)
        self.unread = unread
        self.dropped = 0
        #: Frames given to it so far (the newest one's number), and the newest it has read.
        self.published = 0
        self.taken = 0
        #: Its unread backlog in frames when the last frame came.
        self.behind = 0
        self.stalled = asyncio.Event()
        self._ready = asyncio.Event()
        self._drained = asyncio.Event()
        self._sending = False
        self._current = 0
        self._written = 0
        #: ``(bytes written up to its end, number)`` of frames handed to the socket, unread.
        self._inflight: deque[tuple[int, int]] = deque()

    def _unread(self) -> bool:
        """Bring :attr:`taken` up to date; whether something sent to it waits unread."""
        unread = self.unread() if self.unread is not None else 0
        if unread <= 0 and not self._sending:
            # It has read everything sent to it: what waits here is the server's delay.
            self._inflight.clear()
            self.taken = self.published
            return False
        read = self._written - unread
        while self._inflight and self._inflight[0][0] <= read:
            self.taken = max(self.taken, self._inflight.popleft()[1])
        return True

    def put_frame(self, data: bytes) -> int:
        """Queue a frame, dropping the oldest beyond the bound; returns the frames dropped.

        Marks the client stalled once its unread backlog exceeds ``max_backlog`` frames.
        """
        waiting = self._unread()
        self.published += 1
        self.behind = self.published - self.taken if waiting else 0
        if self.behind > self.max_backlog:
            self.stalled.set()
        dropped = 0
        if len(self.frames) >= self.max_frames:
            self.frames.popleft()
            dropped = 1
            self.dropped += 1
        self.frames.append((self.published, data))
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

    def sending(self) -> None:
        """Mark the start of a send of what :meth:`next` returned last."""
        self._sending = True

    def sent(self, payload: int) -> None:
        """Mark the end of that send: ``payload`` bytes went to the socket."""
        self._sending = False
        self._written += ws_frame_bytes(payload)
        if self._current:
            self._inflight.append((self._written, self._current))

    async def next(self) -> dict[str, Any] | bytes:
        """The next thing to send: a reply if any is waiting, else the oldest kept frame."""
        while not (self.replies or self.frames):
            self._ready.clear()
            await self._ready.wait()
        if self.replies:
            reply = self.replies.popleft()
            self._drained.set()
            self._current = 0
            return reply
        self._current, data = self.frames.popleft()
        return data


class Hub:
    """Every connected client's outbox, on the event loop.

    Args:
        settings: ``buffered_frames``, ``max_replies`` and ``max_backlog_frames``.

    Attributes:
        dropped_frames: frames dropped for clients that read slower than the scene.
        slow_clients: clients closed for their unread backlog.
    """

    def __init__(self, settings: ServeSettings) -> None:
        self.settings = settings
        self.outboxes: dict[int, Outbox] = {}
        self.dropped_frames = 0
        self.slow_clients = 0
        self._next = 0
        self._encodings: frozenset[int] = frozenset()

    def open(self, encoding: int = DEFAULT_ENCODING,
             unread: Callable[[], int] | None = None) -> Outbox:
        """A new client's outbox for frames in layout ``encoding`` (``unread``: see Outbox)."""
        s = self.settings
        box = Outbox(self._next, s.buffered_frames, s.max_replies, s.max_backlog_frames,
                     encoding, unread)
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
