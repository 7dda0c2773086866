"""Outboxes: a client is dropped by its own unread backlog, never for the server's delay."""

from __future__ import annotations

import asyncio
import socket
import sys
import time

import pytest

from emotive.serve.hub import Outbox, unread_bytes, ws_frame_bytes

BACKLOG = 10


class Socket:
    """A client's socket: bytes the server wrote, and those the client has read."""

    def __init__(self) -> None:
        self.written = 0
        self.read = 0

    def unread(self) -> int:
        return self.written - self.read

    def read_all(self) -> None:
        self.read = self.written


def _box(sock: Socket | None) -> Outbox:
    return Outbox(0, frames=2, max_replies=3, max_backlog=BACKLOG,
                  unread=None if sock is None else sock.unread)


def _send_one(box: Outbox, sock: Socket) -> None:
    """What the session's sender does with the next item: it goes to the socket."""
    item = asyncio.run(box.next())
    box.sending()
    size = len(item) if isinstance(item, bytes) else len(str(item))
    box.sent(size)
    sock.written += ws_frame_bytes(size)


def test_a_client_that_reads_nothing_is_stalled_after_its_backlog_of_frames():
    sock = Socket()
    box = _box(sock)
    for _ in range(BACKLOG):
        box.put_frame(b"f" * 100)
        _send_one(box, sock)
    assert not box.stalled.is_set() and box.behind == BACKLOG
    box.put_frame(b"f" * 100)
    assert box.stalled.is_set() and box.behind == BACKLOG + 1


def test_frames_the_server_was_slow_to_send_never_count():
    # Nothing waits unread: frames pile up (and are dropped) only because the sender did not
    # run, the server's own delay.
    sock = Socket()
    box = _box(sock)
    for _ in range(1000):
        box.put_frame(b"f")
    assert not box.stalled.is_set() and box.behind == 0 and box.dropped == 998


def test_a_client_that_keeps_up_is_never_stalled_though_it_reads_late():
    sock = Socket()
    box = _box(sock)
    for k in range(500):
        box.put_frame(b"f" * 300)
        _send_one(box, sock)
        if k % 5 == 4:  # it reads every fifth frame period, all that came
            sock.read_all()
    assert not box.stalled.is_set() and box.behind <= 5


def test_a_client_that_reads_half_the_frames_falls_behind_and_is_stalled():
    sock = Socket()
    box = _box(sock)
    size = ws_frame_bytes(300)
    for k in range(100):
        box.put_frame(b"f" * 300)
        _send_one(box, sock)
        if k % 2:
            sock.read += size  # one frame every two frame periods
        if box.stalled.is_set():
            break
    assert box.stalled.is_set() and k <= 2 * BACKLOG + 2, k


def test_what_it_read_is_counted_by_bytes_replies_included():
    sock = Socket()
    box = _box(sock)
    box.put_reply({"type": "ok"})
    _send_one(box, sock)
    for _ in range(3):
        box.put_frame(b"f" * 100)
        _send_one(box, sock)
    # It read the reply and the first two frames, not the third.
    sock.read = sock.written - ws_frame_bytes(100)
    box.put_frame(b"f" * 100)
    assert box.taken == 2 and box.behind == 2


def test_without_a_view_of_the_socket_a_send_that_waits_for_room_counts():
    box = _box(None)
    box.put_frame(b"f")
    asyncio.run(box.next())
    box.sending()  # the socket is full: this send does not end
    for _ in range(BACKLOG - 1):
        box.put_frame(b"f")
    assert not box.stalled.is_set() and box.behind == BACKLOG
    box.put_frame(b"f")
    assert box.stalled.is_set()
    # A send that ends (the client read) makes it up to date again.
    other = _box(None)
    for _ in range(3 * BACKLOG):
        other.put_frame(b"f")
        asyncio.run(other.next())
        other.sending()
        other.sent(1)
    assert not other.stalled.is_set() and other.behind == 0


def test_replies_are_kept_and_the_room_opens_when_one_is_read():
    box = _box(Socket())

    async def run() -> list[bool]:
        for k in range(5):
            box.put_reply({"type": "ok", "ref": k})
        waited = asyncio.ensure_future(box.room())
        await asyncio.sleep(0)
        before = waited.done()
        got = [await box.next() for _ in range(3)]
        await asyncio.wait_for(waited, 5.0)
        return [before, box.has_room(), [g["ref"] for g in got] == [0, 1, 2]]

    assert asyncio.run(run()) == [False, True, True]
    assert len(box.replies) == 2 and not box.stalled.is_set()


class _Transport:
    """The two calls :func:`unread_bytes` makes of an asyncio transport."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock

    def get_write_buffer_size(self) -> int:
        return 0

    def get_extra_info(self, name: str) -> socket.socket | None:
        return self.sock if name == "socket" else None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SIOCOUTQ is Linux's")
def test_bytes_a_peer_does_not_read_are_seen_in_the_send_queue():
    with socket.create_server(("127.0.0.1", 0)) as server:
        peer = socket.socket()
        peer.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        peer.connect(server.getsockname())
        sender, _ = server.accept()
        with peer, sender:
            sender.setblocking(False)
            sent = 0
            try:
                while sent < 8_000_000:
                    sent += sender.send(b"x" * 65536)
            except BlockingIOError:
                pass
            # The peer's small buffer took a little; the rest waits in the sender's queue.
            waiting = unread_bytes(_Transport(sender))
            assert 0 < waiting <= sent
            got = 0
            peer.settimeout(60)
            while got < sent:
                got += len(peer.recv(1 << 20))
            # Once its acknowledgements are in (on loopback at once; a hang guard of a minute).
            deadline = time.monotonic() + 60.0
            while unread_bytes(_Transport(sender)) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert unread_bytes(_Transport(sender)) == 0
