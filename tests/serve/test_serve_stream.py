"""A client adding 100 agents gets the whole scene in order on the scene clock, and it moves.

Scene time is frame number / fps whatever the machine's speed. How many frames a second the
server makes and sends in wall time is measured by ``make bench`` (``bench/bench_serve.py``).
"""

from __future__ import annotations

import asyncio

import httpx
import numpy as np

from emotive.serve.testing import running_server
from serve_client import WsClient

AGENTS = 100
#: Scene seconds watched.
SECONDS = 3.0


def test_hundred_agents_stream_in_order_at_thirty_frames_per_scene_second():
    with running_server() as url:
        fps = httpx.get(f"{url}/api/skeleton").json()["fps"]

        async def watch():
            async with WsClient(url) as client:
                ids = await client.add_agents(AGENTS, path="figure8", emotion="happy")
                await client.frames_after(3)
                return ids, await client.scene_after(SECONDS)

        ids, frames = asyncio.run(watch())
        stats = httpx.get(f"{url}/api/stats").json()
    assert fps == 30.0
    assert len(set(ids)) == AGENTS
    numbers = [f.number for f in frames]
    assert (np.diff(numbers) > 0).all(), numbers
    for frame in frames:
        assert frame.time == frame.number / fps
        assert sorted(frame.ids.tolist()) == sorted(ids)
        assert np.isfinite(frame.world).all() and np.isfinite(frame.rotations).all()
    first, last = frames[0], frames[-1]
    seconds = last.time - first.time
    assert seconds >= SECONDS - 1e-6
    assert np.array_equal(first.ids, last.ids)
    walked = np.linalg.norm(last.root[:, [0, 2]] - first.root[:, [0, 2]], axis=1)
    assert np.median(walked) > 0.5, (
        f"agents walked {np.median(walked):.2f} m in {seconds:.1f} scene s")
    assert np.abs(first.world - last.world).max() > 0.1
    # The server's counters agree with what the client saw.
    assert stats["agents"] == AGENTS and stats["frames"] > last.number
    assert 0 <= stats["late_frames"] <= stats["frames"] and stats["fps"] >= 0
    assert 0 < stats["step_ms"]["p50"] <= stats["step_ms"]["p99"]
