"""A client that stops reading loses frames (counted) without slowing anyone, then is dropped.

It is dropped by its unread backlog in frames (``max_backlog_frames``), not by a timeout: the
server counts the frames made since the newest one it read, while data sent to it waits.
"""

from __future__ import annotations

import asyncio

import httpx
import websockets

from emotive.serve.testing import running_server
from serve_client import REPLY_TIMEOUT, WsClient, server_stats, until_server, ws_url

#: Scene seconds the reading client is watched while the other stalls.
SECONDS = 3.0
#: Frames of unread backlog after which the server drops a client.
BACKLOG = 30
#: Frames the scene may make before the stalled client is dropped: its backlog, and the
#: frames its socket's buffers take first (the client's receive buffer, 128 KB by default on
#: Linux: 8 frames of 100 agents), with room to spare.
DROP_FRAMES = 4 * BACKLOG


def test_a_stalled_client_does_not_slow_another_and_is_dropped_by_its_backlog():
    with running_server(max_backlog_frames=BACKLOG) as url:
        fps = httpx.get(f"{url}/api/skeleton").json()["fps"]

        async def run():
            async with WsClient(url) as fast:
                await fast.add_agents(100, path="circle")
                stalled = await websockets.connect(ws_url(url), max_size=None,
                                                   open_timeout=REPLY_TIMEOUT)
                stalled.transport.pause_reading()
                await fast.frames_after(5)
                before = await server_stats(url)
                # The server drops the stalled client by its backlog, counted in frames: within
                # DROP_FRAMES of the scene (the frames its socket's buffers hold come first).
                after = await until_server(url, lambda s: s["clients"] == 1 and s,
                                           "the stalled client was not disconnected",
                                           frames=DROP_FRAMES)
                # The scene makes SECONDS of frames (the server's frame counter).
                now = await until_server(
                    url, lambda s: s if s["frames"] >= before["frames"] + SECONDS * fps
                    else None, "the scene did not go on")
                window = range(before["frames"], now["frames"])
                # The reading client gets the last of them (or a later one), then is counted.
                await fast.wait_for(lambda: fast.frames[-1][1].number >= window[-1])
                got = sum(f.number in window for _, f in fast.frames)
                more = await fast.frames_after(10)
                stalled.transport.abort()
                return got, len(window), before, after, more

        got, made, before, after, more = asyncio.run(run())
    # The reading client gets every frame the scene made while the other stalled.
    assert got >= made - 3, f"the reading client got {got} of {made} frames"
    assert made >= 30
    assert before["clients"] == 2
    assert after["clients"] == 1 and after["slow_clients"] == 1
    assert len(more) == 10
