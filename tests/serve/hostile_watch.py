"""The watcher and the server of the hostile campaign (``serve_hostile.py``).

:func:`server_process` runs ``emotive serve --port 0`` as its own process, as users run it;
:class:`Watcher` is the well-behaved client, in a thread of the calling process: it adds a
few agents, reads every frame (noting its number and when it came) and pings.

Legend: none (no arrays).
"""

from __future__ import annotations

import asyncio
import json
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import websockets

#: Seconds the server may take to start, and a watch to get its frames: hang guards.
START_TIMEOUT = 180.0
#: Agents the watcher adds before the quiet watch (so that the engine is warm).
WATCHED_AGENTS = 5
#: Seconds between the watcher's pings.
PING_EVERY = 0.2
#: Frames the watcher waits for before a measurement (half a second of the stream).
SETTLE_FRAMES = 15
_URL = re.compile(r"app:\s+(http://\S+?)/")


def rss_mb(pid: int) -> float:
    """Resident memory of process ``pid``, MB (``/proc``; Linux)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise RuntimeError(f"no VmRSS for process {pid}")


@contextmanager
def server_process(*args: str) -> Iterator[tuple[str, subprocess.Popen]]:
    """Run ``emotive serve --port 0 ARGS``; yield its base URL and process; stop it."""
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
        deadline = time.monotonic() + START_TIMEOUT
        while not found.wait(0.2):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"emotive serve did not start: {''.join(lines)[-2000:]}")
        yield next(m.group(1) for m in map(_URL.search, lines) if m), proc
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def ws_url(url: str) -> str:
    return url.replace("http://", "ws://", 1) + "/ws"


class Watcher(threading.Thread):
    """A well-behaved client in its own thread: adds a few agents, counts frames, pings.

    Attributes:
        arrivals: ``perf_counter`` time of every frame received.
        numbers: the frame number of every frame received.
        pings: ``(sent, round trip)`` seconds of every pong.
        closed: the close code, if the server closed the connection.
    """

    def __init__(self, url: str) -> None:
        super().__init__(name="hostile-watcher", daemon=True)
        self.url = url
        self.arrivals: list[float] = []
        self.numbers: list[int] = []
        self.pings: list[tuple[float, float]] = []
        self.closed: int | None = None
        self.error: BaseException | None = None
        self._halt = threading.Event()
        self.connected = threading.Event()

    def run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as exc:  # reported by the caller
            self.error = exc
        finally:
            self.connected.set()

    def stop(self) -> None:
        """End the watch and join the thread."""
        self._halt.set()
        self.join(60)

    async def _main(self) -> None:
        async with websockets.connect(ws_url(self.url), max_size=None,
                                      open_timeout=START_TIMEOUT) as ws:
            for k in range(WATCHED_AGENTS):
                await ws.send(json.dumps({"type": "add_agent", "path": "figure8",
                                          "start": 1.3 * k}))
            self.connected.set()
            sent: dict[str, float] = {}

            async def ping() -> None:
                n = 0
                while not self._halt.is_set():
                    ref = f"p{n}"
                    sent[ref] = time.perf_counter()
                    await ws.send(json.dumps({"type": "ping", "t": n, "ref": ref}))
                    n += 1
                    await asyncio.sleep(PING_EVERY)

            pinger = asyncio.create_task(ping())
            try:
                while not self._halt.is_set():
                    try:
                        message = await asyncio.wait_for(ws.recv(), 0.5)
                    except TimeoutError:
                        continue
                    now = time.perf_counter()
                    if isinstance(message, bytes):
                        self.arrivals.append(now)
                        self.numbers.append(int.from_bytes(message[4:8], "little"))
                    else:
                        reply = json.loads(message)
                        if reply.get("type") == "pong" and reply.get("ref") in sent:
                            t = sent.pop(reply["ref"])
                            self.pings.append((t, now - t))
            except websockets.ConnectionClosed as exc:
                self.closed = exc.rcvd.code if exc.rcvd is not None else 1006
            finally:
                pinger.cancel()

    def per_second(self, start: float, end: float) -> tuple[list[int], list[int]]:
        """Per whole wall second from ``start`` to ``end``: the frames received, and the
        frames the server made (the span of the frame numbers received in it)."""
        got = [0] * int(end - start)
        spans: list[list[int]] = [[] for _ in got]
        for t, number in zip(self.arrivals, self.numbers, strict=True):
            k = int(t - start)
            if 0 <= k < len(got) and t >= start:
                got[k] += 1
                spans[k].append(number)
        made = [max(n) - min(n) + 1 if n else 0 for n in spans]
        return got, made


def frames_after(watcher: Watcher, count: int) -> None:
    """Wait until the watcher has ``count`` more frames (a hang guard of START_TIMEOUT)."""
    target = len(watcher.numbers) + count
    deadline = time.monotonic() + START_TIMEOUT
    while len(watcher.numbers) < target and watcher.error is None:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the watcher got no {count} frames in {START_TIMEOUT} s")
        time.sleep(0.01)


def stats(url: str) -> dict[str, Any]:
    """The server's ``/api/stats``."""
    return httpx.get(f"{url}/api/stats", timeout=60).json()
