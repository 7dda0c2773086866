"""One websocket connection: control messages in, replies and frames out.

Two tasks per connection: the receiver checks each text message (rate, size, depth, JSON,
fields: :mod:`~emotive.serve.limits`, :mod:`~emotive.serve.messages`), answers ``ping`` at
once and queues everything else for the simulation thread, whose reply is put in the
client's :class:`~emotive.serve.hub.Outbox` when it comes; the sender drains the outbox
(replies first, then the newest frames). The receiver never waits for a reply, so a burst of
``add_agent`` messages lands in one tick. Any exception while handling one message becomes
that message's ``error`` reply; the connection ends when the client leaves, or when its
outbox stalls (it stopped reading), with close code 1008.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from concurrent.futures import Future
from typing import Any

from starlette.websockets import WebSocket, WebSocketDisconnect

from emotive.serve.errors import MessageError
from emotive.serve.hub import Hub, Outbox
from emotive.serve.limits import TokenBucket, parse_message
from emotive.serve.messages import Command, to_command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation, error_text

#: Close code of a client dropped for not reading (policy violation).
STALLED_CLOSE = 1008
_NO_REF = object()


def _with_ref(reply: dict[str, Any], ref: Any) -> dict[str, Any]:
    if ref is not _NO_REF:
        reply["ref"] = ref
    return reply


def error_reply(message: str, ref: Any = _NO_REF) -> dict[str, Any]:
    """``{"type": "error", "message": ..., "ref": ...}`` (``ref`` only when the message had it)."""
    return _with_ref({"type": "error", "message": message}, ref)


class Session:
    """One client's connection.

    Args:
        ws: the accepted websocket.
        sim: the scene.
        hub: the clients.
        settings: the limits.
    """

    def __init__(self, ws: WebSocket, sim: Simulation, hub: Hub, settings: ServeSettings
                 ) -> None:
        self.ws = ws
        self.sim = sim
        self.hub = hub
        self.settings = settings
        self.bucket = TokenBucket(settings.rate, settings.burst)
        self.box: Outbox = hub.open()

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
            self.sim.submit(Command("client_left"), self.box.client)
        if self.box.stalled.is_set():
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self.ws.close(STALLED_CLOSE, "client stopped reading"),
                                       1.0)

    async def _send(self) -> None:
        with contextlib.suppress(WebSocketDisconnect, RuntimeError, OSError):
            while True:
                item = await self.box.next()
                if isinstance(item, bytes):
                    await self.ws.send_bytes(item)
                else:
                    await self.ws.send_text(json.dumps(item))

    async def _receive(self) -> None:
        while True:
            message = await self.ws.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            if text is None:
                self.box.put_reply(error_reply(
                    "binary messages are frames, sent by the server only: send control "
                    "messages as JSON text"))
                continue
            self.handle(text)

    def handle(self, text: str) -> None:
        """Answer one text message (at once, or when the simulation has applied it)."""
        if not self.bucket.take():
            s = self.settings
            self.box.put_reply(error_reply(
                f"too many messages: the limit is {s.rate:g} per second (bursts of {s.burst}); "
                "this one was not applied"))
            return
        ref: Any = _NO_REF
        try:
            message = parse_message(text, self.settings.max_message_bytes,
                                    self.settings.max_depth)
            ref = message.get("ref", _NO_REF)
            if message["type"] == "ping":
                unknown = set(message) - {"type", "ref", "t"}
                if unknown:
                    raise MessageError(f"ping has no field {', '.join(sorted(unknown))}; its "
                                       "fields: t")
                self.box.put_reply(_with_ref({"type": "pong", "t": message.get("t"),
                                              "server_time": time.time()}, ref))
                return
            future = self.sim.submit(to_command(message, self.sim.engine.labels,
                                               self.sim.engine.points_over),
                                     self.box.client)
        except Exception as exc:  # every failure becomes this message's error reply
            self.box.put_reply(error_reply(error_text(exc), ref))
            return
        asyncio.wrap_future(future).add_done_callback(
            lambda done, ref=ref: self._answer(done, ref))

    def _answer(self, done: asyncio.Future | Future, ref: Any) -> None:
        if done.cancelled():
            return
        exc = done.exception()
        reply = error_reply(error_text(exc)) if exc is not None else dict(done.result())
        self.box.put_reply(_with_ref(reply, ref))
