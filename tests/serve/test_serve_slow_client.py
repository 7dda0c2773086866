"""A client that stops reading loses frames (counted) without slowing anyone, then is dropped."""

from __future__ import annotations

import asyncio
import time

import httpx
import websockets

from emotive.serve.testing import running_server
from serve_client import WsClient, ws_url


def test_a_stalled_client_does_not_slow_another():
    with running_server(stall_seconds=2.0) as url:

        async def run():
            async with WsClient(url) as fast:
                await fast.add_agents(100, path="circle")
                stalled = await websockets.connect(ws_url(url), max_size=None)
                stalled.transport.pause_reading()
                await fast.frames_after(5)
                before = httpx.get(f"{url}/api/stats").json()
                start = len(fast.frames)
                await asyncio.sleep(3.0)
                stats = httpx.get(f"{url}/api/stats").json()
                got, made = len(fast.frames) - start, stats["frames"] - before["frames"]
                deadline = time.monotonic() + 20
                while (httpx.get(f"{url}/api/stats").json()["clients"] > 1
                       and time.monotonic() < deadline):
                    await asyncio.sleep(0.2)
                after = httpx.get(f"{url}/api/stats").json()
                more = await fast.frames_after(10)
                stalled.transport.abort()
                return got, made, before, after, more

        got, made, before, after, more = asyncio.run(run())
    # The reading client gets every frame the scene made while the other stalled.
    assert got >= made - 3, f"the reading client got {got} of {made} frames"
    assert made >= 30
    assert before["clients"] == 2 and after["dropped_frames"] > 0
    assert after["clients"] == 1, "the stalled client was not disconnected"
    assert len(more) == 10
