"""Helpers of the server tests: a websocket client that collects frames and replies.

:class:`WsClient` reads in the background (so the server never sees it stall unless a test
asks it to stop reading), decodes every frame with :func:`emotive.serve.frames.decode_frame`
(in the layout it asked for, the server's default unless told; the world positions of compact
frames computed from the rig of ``/api/skeleton``) and matches replies to requests by ``ref``.

Waits are on what the server makes: frames (counted, or by their scene time, frame number /
fps) and its frame counter (``/api/stats``). Scene time runs behind wall time on a busy
machine (the server skips ticks it cannot make in time), so a budget in scene time or frames
holds whatever the machine's speed; wall time only bounds a hang.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import time
from typing import Any

import httpx
import websockets

from emotive.serve.frames import Frame, decode_frame
from emotive.serve.rig import FrameRig

#: Wall seconds a test waits for any one reply: a hang guard.
REPLY_TIMEOUT = 120.0
#: Wall seconds without a new frame (or a new frame count of the server) that count as a hang.
STALL_SECONDS = 120.0
#: Wall seconds any one wait on the server may take in all: a hang guard, not a budget.
HANG_SECONDS = 300.0
#: Wall seconds between two polls of ``/api/stats``.
POLL_SECONDS = 0.1


def ws_url(base: str, token: str | None = None, encoding: int | None = None) -> str:
    """The websocket URL of a server's base URL (with its token and frame layout, if any)."""
    url = base.replace("http://", "ws://", 1) + "/ws"
    query = [f"token={token}"] * (token is not None) + [f"encoding={encoding}"] * (
        encoding is not None)
    return url + ("?" + "&".join(query) if query else "")


async def frame_rig(base: str, token: str | None = None) -> FrameRig | None:
    """The rig of a server's frames (``/api/skeleton``), or ``None`` when it does not answer."""
    headers = {} if token is None else {"Authorization": f"Bearer {token}"}
    async with httpx.AsyncClient(timeout=REPLY_TIMEOUT) as http:
        reply = await http.get(f"{base}/api/skeleton", headers=headers)
    return FrameRig.from_info(reply.json()) if reply.status_code == 200 else None


class WsClient:
    """A websocket client of the server (``async with WsClient(url) as c: ...``).

    Attributes:
        frames: ``(arrival time, frame)`` of every frame received, in order.
        replies: every JSON message received, in order.
    """

    def __init__(self, base: str, token: str | None = None, read: bool = True,
                 encoding: int | None = None) -> None:
        self.base = base
        self.token = token
        self.url = ws_url(base, token, encoding)
        self.read = read
        self.rig: FrameRig | None = None
        self.frames: list[tuple[float, Frame]] = []
        self.replies: list[dict[str, Any]] = []
        self._refs = itertools.count()
        self._changed = asyncio.Event()
        self.ws: Any = None
        self._task: asyncio.Task | None = None

    async def __aenter__(self) -> WsClient:
        self.rig = await frame_rig(self.base, self.token)
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
                    self.frames.append((time.perf_counter(), decode_frame(message, self.rig)))
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

    async def frames_after(self, count: int) -> list[Frame]:
        """Wait for ``count`` more frames and return them (a hang: no frame for a long time)."""
        start = len(self.frames)
        await self._frames_until(lambda: len(self.frames) >= start + count,
                                 lambda: f"{len(self.frames) - start} of {count} frames came")
        return [f for _, f in self.frames[start:start + count]]

    async def scene_after(self, seconds: float) -> list[Frame]:
        """Wait until the frames' scene time is ``seconds`` past the latest frame's.

        Returns the frames from that latest one (or the first to come) on.
        """
        if not self.frames:
            await self.frames_after(1)
        start = len(self.frames) - 1
        t0 = self.frames[start][1].time
        # Frame times are number / fps: allow for the rounding of that division.
        await self._frames_until(lambda: self.frames[-1][1].time >= t0 + seconds - 1e-6,
                                 lambda: f"{self.frames[-1][1].time - t0:.2f} of {seconds} "
                                         "scene s came")
        return [f for _, f in self.frames[start:]]

    async def _frames_until(self, done: Any, told: Any) -> None:
        """Wait until ``done()``; fail if the connection closes or frames stop coming."""
        while not done():
            if self.ws.close_code is not None:
                raise ConnectionError(f"the connection closed ({self.ws.close_code}): {told()}")
            seen = len(self.frames)
            try:
                await self.wait_for(lambda s=seen: done() or len(self.frames) > s
                                    or self.ws.close_code is not None, STALL_SECONDS)
            except TimeoutError:
                raise TimeoutError(f"no progress: no frame for {STALL_SECONDS:.0f} s; "
                                   f"{told()}") from None

    async def add_agents(self, count: int, **fields: Any) -> list[int]:
        """Add ``count`` agents (one message each); returns their ids."""
        replies = await self.requests([{"type": "add_agent", **fields}] * count)
        assert all(r["type"] == "agent" for r in replies), replies
        return [r["id"] for r in replies]


async def server_stats(base: str) -> dict[str, Any]:
    """``GET /api/stats`` of a server without a token (off the event loop's thread)."""
    async with httpx.AsyncClient(timeout=REPLY_TIMEOUT) as http:
        reply = await http.get(f"{base}/api/stats")
    reply.raise_for_status()
    return reply.json()


async def until_server(base: str, check: Any, what: Any, frames: int | None = None) -> Any:
    """Poll ``check(stats)`` (``/api/stats``) until it returns something truthy.

    Fails (AssertionError naming ``what``, a string or a callable giving one) once the server
    made ``frames`` frames since the first poll (a budget in scene time: ``frames / fps``
    scene seconds) without it. With ``frames=None`` there is no budget (for what the server
    does on its own wall clock, such as dropping a stalled client). Either way it fails when
    the server's frame counter does not move for ``STALL_SECONDS``, or after
    ``HANG_SECONDS`` in all.
    """
    told = what if callable(what) else lambda: what
    first = await server_stats(base)
    start = moved = time.monotonic()
    last = first["frames"]
    while True:
        stats = await server_stats(base)
        result = check(stats)
        if result:
            return result
        made = stats["frames"] - first["frames"]
        now = time.monotonic()
        assert frames is None or made < frames, f"{told()}: after {made} frames of the server"
        if stats["frames"] != last:
            last, moved = stats["frames"], now
        assert now - moved < STALL_SECONDS, (
            f"no progress: the server made no frame for {STALL_SECONDS:.0f} s; {told()}")
        assert now - start < HANG_SECONDS, (
            f"no progress within {HANG_SECONDS:.0f} s ({made} frames made); {told()}")
        await asyncio.sleep(POLL_SECONDS)
