"""One websocket connection: control messages in, replies and frames out.

Two tasks per connection. The receiver checks each text message's rate and size: a message
over the rate is answered with an error, as many a second as the rate allows in bursts of a
quarter of ``burst``, and past that the receiver waits before it reads on; all the sessions
together read at most ``server_rate`` messages a second. A small message (at most
:data:`SMALL_MESSAGE` bytes) it parses at once, answering ``ping`` there; every other message
goes to the client's lane of the :class:`~emotive.serve.preparation.Preparer`, which prepares
it in its worker thread and hands the command to the simulation thread, whose reply is put
in the client's :class:`~emotive.serve.hub.Outbox` when it comes. The sender drains the
outbox (replies first, then the newest frames). The receiver never waits for a reply, but it
reads no more of the client's messages while the client's lane is full or its unread replies
reach ``max_replies``: a flood then waits in the client's own socket. While the client's work
budget (seconds of the server's work per second of scene time) is overdrawn, every message
but ``ping`` is refused as it is read. Any exception while handling one message becomes that
message's ``error`` reply, with the message's ``ref`` whenever it could be read; the
connection ends when the client leaves, or when its unread backlog stalls it
(:mod:`~emotive.serve.hub`): then with close code 1008, and the connection is cut
:data:`CLOSE_TIMEOUT` later (a client that reads nothing would not take the close).
"""

from __future__ import annotations

import asyncio
import contextlib
import json

from starlette.websockets import WebSocket, WebSocketDisconnect

from emotive.serve.errors import NO_REF, MessageError
from emotive.serve.frames import DEFAULT_ENCODING
from emotive.serve.hub import Hub, Outbox, unread_bytes
from emotive.serve.limits import TokenBucket, check_size, head_ref, parse_message, ref_of
from emotive.serve.messages import Command
from emotive.serve.preparation import Preparer, error_reply, pong, with_ref, work_refusal
from emotive.serve.server import TRANSPORT_EXTENSION
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation, error_text

#: Close code of a client dropped for not reading (policy violation).
STALLED_CLOSE = 1008
#: Messages of at most this many bytes are parsed on the event loop (microseconds each);
#: the ``ref`` of a refused message is read only up to this size.
SMALL_MESSAGE = 4096
#: Seconds the close of a stalled client may take before its connection is cut.
CLOSE_TIMEOUT = 1.0


class Session:
    """One client's connection.

    Args:
        ws: the accepted websocket.
        sim: the scene.
        hub: the clients.
        preparer: the lanes and the worker.
        settings: the limits.
        reads: the server's messages read per second, shared by every session
            (``server_rate``; ``None``: a bucket of this session's own).
        encoding: the frame layout the client asked for (1 or 2).
    """

    def __init__(self, ws: WebSocket, sim: Simulation, hub: Hub, preparer: Preparer,
                 settings: ServeSettings, reads: TokenBucket | None = None,
                 encoding: int = DEFAULT_ENCODING) -> None:
        self.ws = ws
        self.sim = sim
        self.hub = hub
        self.preparer = preparer
        self.settings = settings
        self.bucket = TokenBucket(settings.rate, settings.burst)
        self.refusals = TokenBucket(settings.rate, max(1, settings.burst // 4))
        self.reads = reads or TokenBucket(settings.server_rate, int(settings.server_rate))
        self.transport = ws.scope.get("extensions", {}).get(TRANSPORT_EXTENSION)
        transport = self.transport
        self.box: Outbox = hub.open(
            encoding, None if transport is None else lambda: unread_bytes(transport))
        self.lane = preparer.open(self.box)

    async def run(self) -> None:
        """Serve the connection until the client leaves or stalls."""
        tasks = [asyncio.create_task(self._receive()), asyncio.create_task(self._send()),
                 asyncio.create_task(self.box.stalled.wait())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            self.hub.close(self.box)
            self.preparer.close(self.lane)
            self.sim.submit(Command("client_left"), self.box.client)
        if self.box.stalled.is_set():
            self.hub.slow_clients += 1
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self.ws.close(STALLED_CLOSE, "client stopped reading"),
                                       CLOSE_TIMEOUT)
            if self.transport is not None:
                # A client that reads nothing never takes the close either (and the socket
                # would stay open while data waits for it): cut the connection soon after.
                asyncio.get_running_loop().call_later(CLOSE_TIMEOUT, self.transport.abort)

    async def _send(self) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            while True:
                item = await self.box.next()
                self.box.sending()
                if isinstance(item, bytes):
                    await self.ws.send_bytes(item)
                    self.box.sent(len(item))
                else:
                    text = json.dumps(item)  # ASCII: one byte a character
                    await self.ws.send_text(text)
                    self.box.sent(len(text))

    async def _receive(self) -> None:
        while True:
            await self.box.room()
            # Messages over the rate are answered, as many again as the rate; past that
            # the client's messages wait in its socket.
            if self.refusals.delay() > 0.0:
                await asyncio.sleep(self.bucket.delay())
            while not self.reads.take():
                await asyncio.sleep(self.reads.delay())
            message = await self.ws.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            if text is None:
                self.box.put_reply(error_reply(
                    "binary messages are frames, sent by the server only: send control "
                    "messages as JSON text"))
                continue
            await self.handle(text)
            # uvicorn hands over every message of one read at once: let the other clients
            # (and this one's sender) run between two of them.
            await asyncio.sleep(0)

    def _small_ref(self, text: str) -> object:
        return ref_of(text) if len(text) <= SMALL_MESSAGE else head_ref(text)

    async def handle(self, text: str) -> None:
        """Answer one text message at once, or queue it for preparation."""
        s = self.settings
        if not self.bucket.take():
            self.refusals.take()
            self.box.put_reply(error_reply(
                f"too many messages: the limit is {s.rate:g} per second (bursts of {s.burst}); "
                "this one was not applied", self._small_ref(text)))
            return
        ref = NO_REF
        try:
            size = check_size(text, s.max_message_bytes)
            if size > SMALL_MESSAGE:
                if not self.lane.budget.allowed():
                    raise MessageError(work_refusal(s), head_ref(text))
                await self.preparer.put(self.lane, text, size)
                return
            message = parse_message(text, s.max_message_bytes, s.max_depth, s.max_values)
            ref = message.get("ref", NO_REF)
            if message["type"] == "ping":
                self.box.put_reply(with_ref(pong(message), ref))
                return
            if not self.lane.budget.allowed():
                raise MessageError(work_refusal(s))
            if message["type"] == "add_agent":
                self.preparer.check_quota(self.lane)
        except MessageError as exc:
            if exc.ref is not NO_REF:
                ref = exc.ref
            self.box.put_reply(error_reply(error_text(exc),
                                           head_ref(text) if ref is NO_REF else ref))
            return
        await self.preparer.put(self.lane, message, size)
