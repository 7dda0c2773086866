"""Helpers of the server tests: a websocket client that collects frames and replies.

:class:`WsClient` reads in the background (so the server never sees it stall unless a test
asks it to stop reading), decodes every frame with :func:`emotive.serve.frames.decode_frame`
and matches replies to requests by ``ref``.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import time
from typing import Any

import websockets

from emotive.serve.frames import Frame, decode_frame

#: Seconds a test waits for any one reply.
REPLY_TIMEOUT = 15.0


def ws_url(base: str, token: str | None = None) -> str:
    """The websocket URL of a server's base URL."""
    url = base.replace("http://", "ws://", 1) + "/ws"
    return url if token is None else f"{url}?token={token}"


class WsClient:
    """A websocket client of the server (``async with WsClient(url) as c: ...``).

    Attributes:
        frames: ``(arrival time, frame)`` of every frame received, in order.
        replies: every JSON message received, in order.
    """

    def __init__(self, base: str, token: str | None = None, read: bool = True) -> None:
        self.url = ws_url(base, token)
        self.read = read
        self.frames: list[tuple[float, Frame]] = []
        self.replies: list[dict[str, Any]] = []
        self._refs = itertools.count()
        self._changed = asyncio.Event()
        self.ws: Any = None
        self._task: asyncio.Task | None = None

    async def __aenter__(self) -> WsClient:
        self.ws = await websockets.connect(self.url, max_size=None, open_timeout=REPLY_TIMEOUT)
        if self.read:
            self._task = asyncio.create_task(self._reader())
        return self

    async def __aexit__(self, *exc: object) -> None:
        if self._task is not None:
            self._task.cancel()
        await self.ws.close()

    async def _reader(self) -> None:
        try:
            async for message in self.ws:
                if isinstance(message, bytes):
                    self.frames.append((time.perf_counter(), decode_frame(message)))
                else:
                    self.replies.append(json.loads(message))
                self._changed.set()
        except websockets.ConnectionClosed:
            self._changed.set()

    async def send(self, message: dict[str, Any] | str) -> None:
        """Send a message (a dict is sent as JSON)."""
        await self.ws.send(message if isinstance(message, str) else json.dumps(message))

    async def wait_for(self, predicate: Any, timeout: float = REPLY_TIMEOUT) -> None:
        """Wait until ``predicate()`` holds."""
        deadline = time.monotonic() + timeout
        while not predicate():
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"condition not met within {timeout} s; last replies: "
                                   f"{self.replies[-3:]}")
            self._changed.clear()
            try:
                await asyncio.wait_for(self._changed.wait(), left)
            except TimeoutError:
                pass

    def reply(self, ref: Any) -> dict[str, Any] | None:
        """The reply carrying ``ref``, if it came."""
        return next((r for r in self.replies if r.get("ref") == ref), None)

    async def request(self, message: dict[str, Any]) -> dict[str, Any]:
        """Send a message with a fresh ``ref`` and return its reply."""
        ref = f"r{next(self._refs)}"
        await self.send({**message, "ref": ref})
        await self.wait_for(lambda: self.reply(ref) is not None)
        return self.reply(ref)

    async def requests(self, messages: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Send many messages at once, then return their replies in order."""
        refs = [f"r{next(self._refs)}" for _ in messages]
        for ref, message in zip(refs, messages, strict=True):
            await self.send({**message, "ref": ref})
        await self.wait_for(lambda: all(self.reply(r) is not None for r in refs))
        return [self.reply(r) for r in refs]

    async def frames_after(self, count: int, timeout: float = REPLY_TIMEOUT) -> list[Frame]:
        """Wait for ``count`` more frames and return them."""
        start = len(self.frames)
        await self.wait_for(lambda: len(self.frames) >= start + count, timeout)
        return [f for _, f in self.frames[start:start + count]]

    async def add_agents(self, count: int, **fields: Any) -> list[int]:
        """Add ``count`` agents (one message each); returns their ids."""
        replies = await self.requests([{"type": "add_agent", **fields}] * count)
        assert all(r["type"] == "agent" for r in replies), replies
        return [r["id"] for r in replies]
