"""The hostile-clients campaign against ``emotive serve``: one watcher, twenty floods.

The server runs as its own process (``emotive serve --port 0``), as users run it; the twenty
hostile connections run in another process (``python serve_hostile.py flood URL SECONDS``,
at niceness 10: in the field they run on other machines), so that neither shares an
interpreter lock with the watcher, which adds five agents, reads frames and pings in a thread
of the calling process. The hostile connections, by number ``k``:

* ``k % 10`` 0-2: ``add_agent`` on a built-in circle, as fast as the server reads;
* 3-5: ``add_agent`` on a drawn path of :data:`PATH_POINTS` points (the most a path may
  have) over about 400 m;
* 6: ``set_emotion`` with a schedule of :data:`KEYFRAMES` keyframes (about 680 KB);
* 7: text that is not JSON;
* 8: messages holding ``NaN``, ``Infinity`` and ``1e999``;
* 9: out-of-range values (a pace of 9, a target 10 km away, an unknown agent).

Every message but the non-JSON ones carries a ``ref``; the flood counts what it sent and
what came back. :func:`campaign` returns the watcher's frames per wall second, its ping round
trips, the server's RSS before and after, the server's own frame counts (``/api/stats``),
and the floods' counts. As a script it prints them as JSON::

    python tests/serve/serve_hostile.py campaign --seconds 20 [-- SERVER ARGS]

Legend: none (no arrays).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
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

#: Hostile connections.
CONNECTIONS = 20
#: Points of a maximal drawn path.
PATH_POINTS = 10_000
#: Keyframes of the large schedule (the campaign of issue 38).
KEYFRAMES = 20_000
#: Niceness of the floods' process (lower priority than the server and the watcher).
FLOOD_NICENESS = 10
#: Seconds the server may take to start, and the floods to connect: hang guards.
START_TIMEOUT = 180.0
#: Messages a hostile connection keeps unanswered at most (it floods, but reads its replies,
#: so that every message's reply can be checked), and for messages over 4 KB.
IN_FLIGHT = 200
IN_FLIGHT_LARGE = 8
#: Agents the watcher adds before the quiet watch (so that the engine is warm).
WATCHED_AGENTS = 5
#: Seconds between the watcher's pings.
PING_EVERY = 0.2
#: Seconds the floods wait at the end for the replies still due: a hang guard.
DRAIN_TIMEOUT = 60.0
#: The line the floods print once all their connections are open.
READY = "flooding"
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


def _ws(url: str) -> str:
    return url.replace("http://", "ws://", 1) + "/ws"


# ------------------------------------------------------------------------------ the floods

def _long_path() -> list[list[float]]:
    """A spiral of :data:`PATH_POINTS` points, about 420 m long, within 12 m of the origin."""
    out = []
    for k in range(PATH_POINTS):
        a = 0.006 * k
        r = 2.0 + 10.0 * k / PATH_POINTS
        out.append([round(r * math.cos(a), 4), round(r * math.sin(a), 4)])
    return out


def hostile_texts(kind: int) -> list[str]:
    """The messages hostile connection kind ``kind`` (0-9) cycles through, ``REF`` for its ref."""
    if kind <= 2:
        return ['{"type": "add_agent", "path": "circle", "ref": "REF"}']
    if kind <= 5:
        return [json.dumps({"type": "add_agent", "path": _long_path(), "ref": "REF"})]
    if kind == 6:
        schedule = [{"t": round(0.01 * k, 2), "emotion": "sad"} for k in range(KEYFRAMES)]
        # ``ref`` first: the server reads it from the head of a message too large to read.
        return [json.dumps({"ref": "REF", "type": "set_emotion", "id": 0,
                            "schedule": schedule})]
    if kind == 7:
        return ["not json at all", '{"type": "add_agent", "pa', "\x00\x01\x02", "[[[[1]"]
    if kind == 8:
        return ['{"type": "add_agent", "pace": NaN, "ref": "REF"}',
                '{"type": "set_pace", "id": 0, "pace": Infinity, "ref": "REF"}',
                '{"type": "add_agent", "path": [[0, 0], [-Infinity, 1]], "ref": "REF"}',
                '{"type": "set_target", "id": 0, "target": [1e999, 0], "ref": "REF"}']
    return ['{"type": "set_pace", "id": 0, "pace": 9, "ref": "REF"}',
            '{"type": "set_target", "id": 0, "target": [10000, 0], "ref": "REF"}',
            '{"type": "remove_agent", "id": 987654321, "ref": "REF"}',
            '{"type": "add_agent", "path": {"shape": "circle", "radius": 1e6}, "ref": "REF"}']


async def _flood(ws: Any, k: int, texts: list[str], seconds: float) -> dict[str, Any]:
    """One hostile connection: send its messages for ``seconds``, then collect the replies."""
    in_flight = IN_FLIGHT_LARGE if len(texts[0]) > 4096 else IN_FLIGHT
    counts: dict[str, Any] = {"kind": k % 10, "sent": 0, "with_ref": 0, "replies": 0,
                              "agents": 0, "errors": 0, "answered": 0, "closed": None,
                              "messages": set()}
    refs: set[str] = set()
    async def read() -> None:
        async for message in ws:
            if isinstance(message, bytes):
                continue
            reply = json.loads(message)
            counts["replies"] += 1
            counts["agents"] += reply.get("type") == "agent"
            counts["errors"] += reply.get("type") == "error"
            if reply.get("type") == "error":
                counts["messages"].add(reply["message"][:120])
            if reply.get("ref") in refs:
                refs.discard(reply["ref"])
                counts["answered"] += 1

    reader = asyncio.create_task(read())
    end = time.monotonic() + seconds
    n = 0
    try:
        while time.monotonic() < end:
            text, ref = texts[n % len(texts)], None
            if "REF" in text:
                ref = f"c{k}m{n}"
                refs.add(ref)
                text = text.replace('"REF"', f'"{ref}"')
            try:
                await asyncio.wait_for(ws.send(text), max(end - time.monotonic(), 0.01))
            except TimeoutError:
                refs.discard(ref)
                break
            counts["sent"] += 1
            counts["with_ref"] += ref is not None
            n += 1
            while (counts["sent"] - counts["replies"] >= in_flight
                   and not reader.done()):
                await asyncio.sleep(0.01)
        deadline = time.monotonic() + DRAIN_TIMEOUT
        while counts["replies"] < counts["sent"] and time.monotonic() < deadline:
            if reader.done():
                break
            await asyncio.sleep(0.05)
    except websockets.ConnectionClosed:
        pass
    finally:
        counts["closed"] = ws.close_code
        reader.cancel()
    counts["missing_refs"] = len(refs)
    counts["messages"] = sorted(counts["messages"])[:8]
    return counts


async def _floods(url: str, seconds: float) -> list[dict[str, Any]]:
    texts = [hostile_texts(k) for k in range(10)]
    connected = asyncio.Event()
    ready: list[int] = []

    async def one(k: int) -> dict[str, Any]:
        async with websockets.connect(_ws(url), max_size=None, open_timeout=START_TIMEOUT,
                                      close_timeout=5, ping_interval=None) as ws:
            ready.append(k)
            if len(ready) == CONNECTIONS:
                print(READY, flush=True)
                connected.set()
            await connected.wait()
            return await _flood(ws, k, texts[k % 10], seconds)

    return list(await asyncio.gather(*(one(k) for k in range(CONNECTIONS))))


def run_floods(url: str, seconds: float) -> subprocess.Popen:
    """Start the floods in a child process; its stdout ends with their counts as JSON."""
    return subprocess.Popen([sys.executable, __file__, "flood", url, str(seconds)],
                            stdout=subprocess.PIPE, text=True)


# ------------------------------------------------------------------------------ the watcher

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
        async with websockets.connect(_ws(self.url), max_size=None,
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


#: Frames the watcher waits for before a measurement (half a second of the stream).
SETTLE_FRAMES = 15


def _frames_after(watcher: Watcher, count: int) -> None:
    """Wait until the watcher has ``count`` more frames (a hang guard of START_TIMEOUT)."""
    target = len(watcher.numbers) + count
    deadline = time.monotonic() + START_TIMEOUT
    while len(watcher.numbers) < target and watcher.error is None:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the watcher got no {count} frames in {START_TIMEOUT} s")
        time.sleep(0.01)


def _stats(url: str) -> dict[str, Any]:
    return httpx.get(f"{url}/api/stats", timeout=60).json()


def campaign(seconds: float = 20.0, quiet: float = 3.0, server_args: tuple[str, ...] = ()
             ) -> dict[str, Any]:
    """Run the campaign: a quiet watch, the floods for ``seconds``, and the aftermath.

    Returns:
        ``quiet_fps`` (the server's own frames per second before the flood, /api/stats),
        ``flood_frames`` (the server's frames made during the flood and the drain after),
        ``per_second`` (the watcher's frames in each wall second of the flood),
        ``worst_second``, ``made_per_second`` (frames the server numbered in each of those
        seconds, from the frame numbers the watcher got), ``frames_numbered`` and
        ``flood_fps`` (the server's frames over the flood, and per second), ``ping_max_s``,
        ``closed`` (the watcher's close code or ``None``), ``rss_before_mb``,
        ``rss_after_mb``, ``floods`` (each connection's counts) and ``stats_after``.
    """
    with server_process(*server_args) as (url, proc):
        watcher = Watcher(url)
        watcher.start()
        watcher.connected.wait(START_TIMEOUT)
        if watcher.error is not None:
            raise watcher.error
        _frames_after(watcher, SETTLE_FRAMES)
        s0, t0 = _stats(url), time.perf_counter()
        time.sleep(quiet)
        s1, t1 = _stats(url), time.perf_counter()
        rss_before = rss_mb(proc.pid)
        floods = run_floods(url, seconds)
        if floods.stdout.readline().strip() != READY:
            raise RuntimeError("the floods did not connect")
        start = time.perf_counter()
        out, _ = floods.communicate(timeout=START_TIMEOUT + seconds + DRAIN_TIMEOUT + 60)
        end = time.perf_counter()
        s2 = _stats(url)
        _frames_after(watcher, SETTLE_FRAMES)
        rss_after = rss_mb(proc.pid)
        watcher.stop()
    counts = json.loads(out.strip().splitlines()[-1])
    flood_end = start + seconds
    bins, made = watcher.per_second(start, min(flood_end, end))
    numbers = [n for t, n in zip(watcher.arrivals, watcher.numbers, strict=True)
               if start <= t < flood_end]
    pings = [rtt for t, rtt in watcher.pings if start <= t < end]
    return {
        "quiet_fps": (s1["frames"] - s0["frames"]) / (t1 - t0),
        "flood_frames": s2["frames"] - s1["frames"],
        "per_second": bins, "worst_second": min(bins) if bins else 0,
        "made_per_second": made,
        "frames_numbered": (max(numbers) - min(numbers) + 1) if numbers else 0,
        "flood_fps": ((max(numbers) - min(numbers) + 1) / seconds) if numbers else 0.0,
        "ping_max_s": max(pings) if pings else None,
        "closed": watcher.closed, "watch_error": repr(watcher.error) if watcher.error else None,
        "rss_before_mb": rss_before, "rss_after_mb": rss_after,
        "floods": counts, "stats_after": s2,
    }


def main(argv: list[str] | None = None) -> None:
    """``campaign [--seconds S] [-- SERVER ARGS]`` or ``flood URL SECONDS`` (the child)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("campaign")
    c.add_argument("--seconds", type=float, default=20.0)
    c.add_argument("server_args", nargs="*")
    f = sub.add_parser("flood")
    f.add_argument("url")
    f.add_argument("seconds", type=float)
    args = parser.parse_args(argv)
    if args.command == "flood":
        # In the field hostile clients run on other machines: here they take only the
        # processor time that the server and the watcher leave.
        os.nice(FLOOD_NICENESS)
        print(json.dumps(asyncio.run(_floods(args.url, args.seconds))), flush=True)
        return
    result = campaign(args.seconds, server_args=tuple(args.server_args))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
