"""A client adding 100 agents gets the whole scene at the clock's rate, and it moves."""

from __future__ import annotations

import asyncio
import time

import httpx
import numpy as np

from emotive.serve.testing import running_server
from serve_client import WsClient

AGENTS = 100
SECONDS = 3.0


def test_hundred_agents_stream_at_thirty_frames_per_second():
    with running_server() as url:

        async def watch():
            async with WsClient(url) as client:
                ids = await client.add_agents(AGENTS, path="figure8", emotion="happy")
                await client.frames_after(3)
                start = len(client.frames)
                t0 = time.perf_counter()
                await asyncio.sleep(SECONDS)
                frames = [f for _, f in client.frames[start:]]
                return ids, frames, time.perf_counter() - t0

        ids, frames, seconds = asyncio.run(watch())
        stats = httpx.get(f"{url}/api/stats").json()
    assert len(set(ids)) == AGENTS
    assert len(frames) / seconds >= 28, f"{len(frames) / seconds:.1f} frames/s"
    numbers = [f.number for f in frames]
    assert numbers == sorted(numbers) and len(set(numbers)) == len(numbers)
    for frame in frames:
        assert sorted(frame.ids.tolist()) == sorted(ids)
        assert np.isfinite(frame.world).all() and np.isfinite(frame.rotations).all()
    first, last = frames[0], frames[-1]
    assert np.array_equal(first.ids, last.ids)
    walked = np.linalg.norm(last.root[:, [0, 2]] - first.root[:, [0, 2]], axis=1)
    assert np.median(walked) > 0.5, f"agents walked {np.median(walked):.2f} m in {seconds:.1f} s"
    assert np.abs(first.world - last.world).max() > 0.1
    assert stats["agents"] == AGENTS and stats["frames"] > 0
    assert stats["fps"] > 20 and stats["step_ms"]["p99"] > 0
