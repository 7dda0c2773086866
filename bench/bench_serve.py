"""Load on ``emotive serve``: 10 clients x 200 agents at 30 fps, a stalled client, backends.

The server runs as its own process (``emotive serve --port 0``), as users run it, so that the
clients (websocket readers in this process, on one event loop) do not share its interpreter
lock; on the 2-core development machine they still share its cores. Each client counts the
frames it receives (their 32-byte header checked, not decoded further). Scenarios:

* shared: one scene of 200 agents (added by one client) watched by 10 clients;
* own: 10 clients each adding 200 agents (a scene of 2,000);
* stalled: the shared scene while one of the 10 clients stops reading (its socket paused):
  the rate of the other nine, against the shared scene's rate;
* backend: the server's step time (p50) with 200 agents on ONNX Runtime against torch, when
  the ONNX backend is installed.

Rows per scenario: frames received per client per second (the slowest client) against the
30 fps clock, frames on time (``1 - late_frames / frames`` of ``/api/stats`` over the measured
window) against the 99 % target, and the p99 of the server's tick time against the 33.3 ms
frame budget.
"""

from __future__ import annotations

import asyncio
import importlib.util
import json
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import httpx
import websockets

from bench.common import comparison, print_rows
from emotive.serve.frames import HEADER, MAGIC

FPS = 30.0
#: Seconds the server may take to start.
START_TIMEOUT = 120.0
_URL = re.compile(r"app:\s+(http://\S+?)/")


@contextmanager
def server_process(*args: str) -> Iterator[str]:
    """Run ``emotive serve --port 0 ARGS`` in a subprocess; yield its base URL; stop it."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "from emotive.cli import main; main()", "serve", "--port", "0",
         *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    found = threading.Event()

    def drain() -> None:
        for line in proc.stdout:
            lines.append(line)
            if _URL.search(line):
                found.set()

    threading.Thread(target=drain, daemon=True).start()
    try:
        if not found.wait(START_TIMEOUT):
            raise RuntimeError(f"emotive serve did not start: {''.join(lines)[-2000:]}")
        yield next(m.group(1) for m in map(_URL.search, lines) if m)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class Watcher:
    """One websocket client counting the frames it gets (and optionally adding agents)."""

    def __init__(self, url: str) -> None:
        self.url = url.replace("http://", "ws://", 1) + "/ws"
        self.frames = 0
        self.agents = 0
        self.ws: Any = None
        self._task: asyncio.Task | None = None

    async def start(self, add: int = 0) -> None:
        """Connect, start counting, and send ``add`` ``add_agent`` messages."""
        self.ws = await websockets.connect(self.url, max_size=None)
        self._task = asyncio.create_task(self._read())
        for k in range(add):
            await self.ws.send(json.dumps({"type": "add_agent", "path": "figure8",
                                           "start": 0.37 * k}))

    async def _read(self) -> None:
        try:
            async for message in self.ws:
                if isinstance(message, bytes):
                    if message[:4] == MAGIC:
                        self.frames += 1
                        self.agents = HEADER.unpack_from(message)[3]
        except websockets.ConnectionClosed:
            pass

    def stop_reading(self) -> None:
        """Stop reading: the server sees a client whose socket does not drain."""
        if self._task is not None:
            self._task.cancel()
        self.ws.transport.pause_reading()

    async def close(self) -> None:
        """Drop the connection abruptly."""
        if self._task is not None:
            self._task.cancel()
        self.ws.transport.abort()


async def _stats(url: str) -> dict[str, Any]:
    async with httpx.AsyncClient() as client:
        return (await client.get(f"{url}/api/stats", timeout=30)).json()


async def _measure(url: str, clients: int, agents: int, own: bool, seconds: float,
                   stall: bool = False) -> dict[str, float]:
    """Frames per client per second, on-time share and p99 tick time over ``seconds``."""
    watchers = [Watcher(url) for _ in range(clients)]
    for k, w in enumerate(watchers):
        await w.start(add=agents if own or k == 0 else 0)
    total = agents * (clients if own else 1)
    deadline = time.monotonic() + 120
    while min(w.agents for w in watchers) < total and time.monotonic() < deadline:
        await asyncio.sleep(0.2)
    await asyncio.sleep(3.0)
    if stall:
        watchers[-1].stop_reading()
        await asyncio.sleep(2.0)
    fast = watchers[:-1] if stall else watchers
    before, counts, t0 = await _stats(url), [w.frames for w in fast], time.perf_counter()
    await asyncio.sleep(seconds)
    after, elapsed = await _stats(url), time.perf_counter() - t0
    rates = [(w.frames - c) / elapsed for w, c in zip(fast, counts, strict=True)]
    frames = max(after["frames"] - before["frames"], 1)
    late = after["late_frames"] - before["late_frames"]
    for w in watchers:
        await w.close()
    return {"min_rate": min(rates), "mean_rate": sum(rates) / len(rates),
            "on_time": 100.0 * (1.0 - late / frames), "p99": after["step_ms"]["p99"],
            "p50": after["step_ms"]["p50"], "server_fps": frames / elapsed,
            "dropped": after["dropped_frames"] - before["dropped_frames"],
            "agents": after["agents"]}


def _scenario(clients: int, agents: int, own: bool, seconds: float, stall: bool = False,
              *args: str) -> dict[str, float]:
    limit = str(max(500, agents * clients))
    with server_process("--max-agents", limit, *args) as url:
        return asyncio.run(_measure(url, clients, agents, own, seconds, stall))


def _rows(label: str, m: dict[str, float]) -> list[dict]:
    return [
        comparison(f"serve_{label}: frames/s, slowest client", "frames/s", m["min_rate"], FPS,
                   "the 30 fps clock"),
        comparison(f"serve_{label}: frames on time", "%", m["on_time"], 99.0, "target: 99 %"),
        comparison(f"serve_{label}: tick p99", "ms", m["p99"], 1000.0 / FPS,
                   "the 33.3 ms frame budget", higher_is_better=False),
    ]


def onnx_available() -> bool:
    """Whether the ONNX backend's module and runtime are installed."""
    return all(importlib.util.find_spec(name) is not None
               for name in ("onnxruntime", "emotive.models.gait.onnx_runtime"))


def run(clients: int = 10, agents: int = 200, seconds: float = 10.0) -> list[dict]:
    """The load rows (see the module docstring); prints each scenario's numbers as it goes."""
    shared = _scenario(clients, agents, False, seconds)
    print(f"  shared: {shared}", flush=True)
    own = _scenario(clients, agents, True, seconds)
    print(f"  own: {own}", flush=True)
    stalled = _scenario(clients, agents, False, seconds, True)
    print(f"  stalled: {stalled}", flush=True)
    rows = (_rows(f"shared[{agents} agents, {clients} clients]", shared)
            + _rows(f"own[{clients}x{agents} agents]", own))
    rows.append(comparison(f"serve_stalled[{agents} agents, {clients - 1} reading clients]",
                           "frames/s", stalled["min_rate"], shared["min_rate"],
                           "the same scene without a stalled client"))
    if onnx_available():
        onnx = _scenario(1, agents, True, seconds, False, "--backend", "onnx")
        print(f"  onnx: {onnx}", flush=True)
        torch_one = _scenario(1, agents, True, seconds)
        print(f"  torch: {torch_one}", flush=True)
        rows.append(comparison(f"serve_backend[{agents} agents, tick p50]", "ms", onnx["p50"],
                               torch_one["p50"], "torch backend", higher_is_better=False))
    return rows


def main() -> None:
    """Print the benchmark rows and the total time."""
    print_rows(run)


if __name__ == "__main__":
    main()
