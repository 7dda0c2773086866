"""The hostile-clients campaign against ``emotive serve``: one watcher, 26 hostile clients.

The server runs as its own process (``emotive serve --port 0``), as users run it; the hostile
connections run in another process (``python serve_hostile.py flood URL SECONDS``, at
niceness 10: in the field they run on other machines), so that neither shares an interpreter
lock with the watcher, which adds five agents, reads frames and pings in a thread of the
calling process (:mod:`hostile_watch`). The hostile connections are of the kinds
:data:`KINDS` (twice each of 0-9, then the later ones):

* 0-2: ``add_agent`` on a built-in circle, as fast as the server reads;
* 3-5: ``add_agent`` on a drawn path of :data:`PATH_POINTS` points (the most a path may
  have) over about 400 m;
* 6: ``set_emotion`` with a schedule of :data:`KEYFRAMES` keyframes (about 680 KB);
* 7: text that is not JSON;
* 8: messages holding ``NaN``, ``Infinity`` and ``1e999``;
* 9: out-of-range values (a pace of 9, a target 10 km away, an unknown agent);
* 10 (:data:`BLEND`): ``set_emotion`` on its own agent with schedules of 256 blended
  keyframes (the most a schedule may have; 30 ms of preparation each), at the rate limit;
* 11 (:data:`CHURN`): an ``add_agent`` flood that removes each new agent as soon as it is
  answered and adds the next, at the rate limit (every agent a join: a warm-up of the network);
* 12 (:data:`DEAF`): connects and never reads;
* 13 (:data:`SLOW`): reads one message every :data:`SLOW_READ` seconds.

Every message but the non-JSON ones carries a ``ref``; the flood counts what it sent and
what came back. :func:`campaign` returns the watcher's frames per wall second, its ping round
trips, the server's RSS before and after, the server's own frame counts (``/api/stats``,
polled through the flood: when the slow readers were dropped), and the floods' counts. As a
script it prints them as JSON::

    python tests/serve/serve_hostile.py campaign --seconds 20 [-- SERVER ARGS]

Legend: none (no arrays).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import subprocess
import sys
import threading
import time
from typing import Any

import httpx
import websockets
from hostile_watch import (
    SETTLE_FRAMES,
    START_TIMEOUT,
    Watcher,
    frames_after,
    rss_mb,
    server_process,
    stats,
    ws_url,
)

#: Kinds of the later attackers (see the module docstring).
BLEND, CHURN, DEAF, SLOW = 10, 11, 12, 13
#: The kind of each hostile connection.
KINDS = [*range(10), *range(10), BLEND, BLEND, CHURN, CHURN, DEAF, SLOW]
#: Hostile connections.
CONNECTIONS = len(KINDS)
#: Points of a maximal drawn path.
PATH_POINTS = 10_000
#: Keyframes of the large schedule (the campaign of issue 38).
KEYFRAMES = 20_000
#: Keyframes of a blended schedule (the most a schedule may have).
BLEND_KEYFRAMES = 256
#: The blends its keyframes cycle through (weights, text, a valence/arousal point).
BLENDS: list[dict[str, Any]] = [{"emotion": {"happy": 0.5, "sad": 0.3, "angry": 0.2}},
                                {"emotion": "happy=0.4,neutral=0.6"},
                                {"valence": 0.3, "arousal": -0.2}]
#: Seconds between two messages of an attacker at the rate limit (the server's 100 a second).
RATE_PERIOD = 0.01
#: Seconds between two reads of the slow reader.
SLOW_READ = 0.5
#: Seconds between two polls of the server's counters during the flood.
POLL_EVERY = 0.5
#: Niceness of the floods' process (lower priority than the server and the watcher).
FLOOD_NICENESS = 10
#: Messages a hostile connection keeps unanswered at most (it floods, but reads its replies,
#: so that every message's reply can be checked), and for messages over 4 KB.
IN_FLIGHT = 200
IN_FLIGHT_LARGE = 8
#: Seconds the floods wait at the end for the replies still due: a hang guard.
DRAIN_TIMEOUT = 60.0
#: The line the floods print once all their connections are open.
READY = "flooding"


# ------------------------------------------------------------------------------ the floods

def _long_path() -> list[list[float]]:
    """A spiral of :data:`PATH_POINTS` points, about 420 m long, within 12 m of the origin."""
    out = []
    for k in range(PATH_POINTS):
        a = 0.006 * k
        r = 2.0 + 10.0 * k / PATH_POINTS
        out.append([round(r * math.cos(a), 4), round(r * math.sin(a), 4)])
    return out


def hostile_texts(kind: int, agent: int = 0) -> list[str]:
    """The messages hostile connection kind ``kind`` (0-10) cycles through, ``REF`` for its
    ref (``agent``: the agent a kind-10 connection added)."""
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
    if kind == BLEND:
        schedule = [{"t": round(0.05 * k, 2), **BLENDS[k % len(BLENDS)]}
                    for k in range(BLEND_KEYFRAMES)]
        return [json.dumps({"ref": "REF", "type": "set_emotion", "id": agent,
                            "schedule": schedule})]
    return ['{"type": "set_pace", "id": 0, "pace": 9, "ref": "REF"}',
            '{"type": "set_target", "id": 0, "target": [10000, 0], "ref": "REF"}',
            '{"type": "remove_agent", "id": 987654321, "ref": "REF"}',
            '{"type": "add_agent", "path": {"shape": "circle", "radius": 1e6}, "ref": "REF"}']


class Tally:
    """What one hostile connection sent and got back (its reader runs as a task).

    Attributes:
        counts: ``kind``, ``sent``, ``with_ref``, ``replies``, ``agents``, ``errors``,
            ``answered`` (replies that carried a ref it sent), ``closed`` (the close code),
            ``messages`` (some error texts), ``missing_refs`` (refs never answered).
        replies: every reply with a ref, by ref.
    """

    def __init__(self, kind: int) -> None:
        self.counts: dict[str, Any] = {"kind": kind, "sent": 0, "with_ref": 0, "replies": 0,
                                       "agents": 0, "errors": 0, "answered": 0,
                                       "closed": None, "messages": set()}
        self.refs: set[str] = set()
        self.replies: dict[str, dict[str, Any]] = {}
        self.changed = asyncio.Event()

    def sending(self, ref: str | None) -> None:
        """Count a message about to be sent (with ``ref``, or none)."""
        if ref is not None:
            self.refs.add(ref)

    def sent(self, ref: str | None) -> None:
        """Count a message sent."""
        self.counts["sent"] += 1
        self.counts["with_ref"] += ref is not None

    async def read(self, ws: Any) -> None:
        """Read every reply until the connection closes (frames are skipped)."""
        async for message in ws:
            if isinstance(message, bytes):
                continue
            reply = json.loads(message)
            c = self.counts
            c["replies"] += 1
            c["agents"] += reply.get("type") == "agent"
            c["errors"] += reply.get("type") == "error"
            if reply.get("type") == "error":
                c["messages"].add(reply["message"][:120])
            if reply.get("ref") in self.refs:
                self.refs.discard(reply["ref"])
                self.replies[reply["ref"]] = reply
                c["answered"] += 1
            self.changed.set()

    async def drain(self, reader: asyncio.Task) -> None:
        """Wait for the replies still due (a hang guard of DRAIN_TIMEOUT)."""
        deadline = time.monotonic() + DRAIN_TIMEOUT
        while True:
            self.changed.clear()
            left = deadline - time.monotonic()
            if self.counts["replies"] >= self.counts["sent"] or left <= 0 or reader.done():
                return
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self.changed.wait(), min(left, 1.0))

    def result(self, ws: Any) -> dict[str, Any]:
        """The counts, once the connection is done."""
        self.counts["closed"] = ws.close_code
        self.counts["missing_refs"] = len(self.refs)
        self.counts["messages"] = sorted(self.counts["messages"])[:8]
        return self.counts


async def _send(ws: Any, tally: Tally, text: str, ref: str | None, end: float) -> bool:
    """Send one message before ``end``; ``False``: the server no longer reads it in time."""
    tally.sending(ref)
    try:
        await asyncio.wait_for(ws.send(text), max(end - time.monotonic(), 0.01))
    except TimeoutError:
        tally.refs.discard(ref)
        return False
    tally.sent(ref)
    return True


async def _flood(ws: Any, tally: Tally, k: int, texts: list[str], seconds: float,
                 pace: float = 0.0) -> None:
    """Send ``texts`` in turn for ``seconds`` (``pace`` seconds apart at least), then
    collect the replies."""
    in_flight = IN_FLIGHT_LARGE if len(texts[0]) > 4096 else IN_FLIGHT
    reader = asyncio.create_task(tally.read(ws))
    end = time.monotonic() + seconds
    n = 0
    try:
        while time.monotonic() < end:
            text, ref = texts[n % len(texts)], None
            if "REF" in text:
                ref = f"c{k}m{n}"
                text = text.replace('"REF"', f'"{ref}"')
            if not await _send(ws, tally, text, ref, end):
                break
            n += 1
            if pace:
                await asyncio.sleep(pace)
            while (tally.counts["sent"] - tally.counts["replies"] >= in_flight
                   and not reader.done()):
                await asyncio.sleep(0.01)
        await tally.drain(reader)
    except websockets.ConnectionClosed:
        pass
    finally:
        reader.cancel()


async def _reply(tally: Tally, ref: str, reader: asyncio.Task) -> dict[str, Any] | None:
    """The reply carrying ``ref`` (``None``: the connection closed or DRAIN_TIMEOUT passed)."""
    deadline = time.monotonic() + DRAIN_TIMEOUT
    while ref not in tally.replies and not reader.done() and time.monotonic() < deadline:
        tally.changed.clear()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(tally.changed.wait(), 1.0)
    return tally.replies.get(ref)


async def _own_agent(ws: Any, tally: Tally, k: int) -> tuple[int, asyncio.Task]:
    """Add the connection's own agent (before its flood); its id (0 if refused)."""
    reader = asyncio.create_task(tally.read(ws))
    ref = f"c{k}own"
    await _send(ws, tally, json.dumps({"type": "add_agent", "ref": ref}), ref, math.inf)
    reply = await _reply(tally, ref, reader)
    return (reply["id"] if reply and reply.get("type") == "agent" else 0), reader


async def _churn(ws: Any, tally: Tally, k: int, seconds: float) -> None:
    """Add an agent, remove it once answered, add the next: every agent a join."""
    reader = asyncio.create_task(tally.read(ws))
    end = time.monotonic() + seconds
    n = 0
    try:
        while time.monotonic() < end:
            ref = f"c{k}a{n}"
            if not await _send(ws, tally, json.dumps({"type": "add_agent", "ref": ref}), ref,
                               end):
                break
            reply = await _reply(tally, ref, reader)
            if reply is not None and reply.get("type") == "agent":
                gone = f"c{k}r{n}"
                await _send(ws, tally, json.dumps({"type": "remove_agent", "id": reply["id"],
                                                   "ref": gone}), gone, end)
            n += 1
            await asyncio.sleep(RATE_PERIOD)
        await tally.drain(reader)
    except websockets.ConnectionClosed:
        pass
    finally:
        reader.cancel()


async def _slow(ws: Any, tally: Tally, seconds: float, period: float | None) -> None:
    """Read one message every ``period`` seconds (``None``: none) for ``seconds``."""
    end = time.monotonic() + seconds
    reads = 0
    with contextlib.suppress(websockets.ConnectionClosed):
        while time.monotonic() < end:
            if period is None:
                await asyncio.sleep(min(POLL_EVERY, max(end - time.monotonic(), 0.0)))
                continue
            await asyncio.wait_for(ws.recv(), DRAIN_TIMEOUT)
            reads += 1
            await asyncio.sleep(period)
    # Read what is left, to learn how the server closed the connection (if it did).
    ws.transport.resume_reading()
    deadline = time.monotonic() + DRAIN_TIMEOUT
    with contextlib.suppress(websockets.ConnectionClosed, TimeoutError):
        while time.monotonic() < deadline:
            await asyncio.wait_for(ws.recv(), max(deadline - time.monotonic(), 0.01))
    tally.counts["reads"] = reads


async def _floods(url: str, seconds: float) -> list[dict[str, Any]]:
    texts = {kind: hostile_texts(kind) for kind in range(10)}
    connected = asyncio.Event()
    ready: list[int] = []

    async def one(k: int) -> dict[str, Any]:
        kind = KINDS[k]
        tally = Tally(kind)
        # The slow readers read nothing ahead (the library reads up to max_queue messages).
        async with websockets.connect(ws_url(url), max_size=None, open_timeout=START_TIMEOUT,
                                      close_timeout=5, ping_interval=None,
                                      max_queue=1 if kind in (DEAF, SLOW) else 16) as ws:
            if kind == DEAF:
                ws.transport.pause_reading()
            if kind == BLEND:
                agent, reader = await _own_agent(ws, tally, k)
                reader.cancel()
            ready.append(k)
            if len(ready) == CONNECTIONS:
                print(READY, flush=True)
                connected.set()
            await connected.wait()
            if kind == BLEND:
                await _flood(ws, tally, k, hostile_texts(BLEND, agent), seconds, RATE_PERIOD)
            elif kind == CHURN:
                await _churn(ws, tally, k, seconds)
            elif kind in (DEAF, SLOW):
                await _slow(ws, tally, seconds, None if kind == DEAF else SLOW_READ)
            else:
                await _flood(ws, tally, k, texts[kind], seconds)
            return tally.result(ws)

    return list(await asyncio.gather(*(one(k) for k in range(CONNECTIONS))))


def run_floods(url: str, seconds: float) -> subprocess.Popen:
    """Start the floods in a child process; its stdout ends with their counts as JSON."""
    return subprocess.Popen([sys.executable, __file__, "flood", url, str(seconds)],
                            stdout=subprocess.PIPE, text=True)


def campaign(seconds: float = 20.0, quiet: float = 3.0, server_args: tuple[str, ...] = ()
             ) -> dict[str, Any]:
    """Run the campaign: a quiet watch, the floods for ``seconds``, and the aftermath.

    Returns:
        ``quiet_fps`` and ``quiet_after_fps`` (the server's own frames per second just
        before the flood and once its connections are closed, /api/stats),
        ``flood_frames`` (the server's frames made during the flood and the drain after),
        ``per_second`` (the watcher's frames in each wall second of the flood),
        ``worst_second``, ``made_per_second`` (frames the server numbered in each of those
        seconds, from the frame numbers the watcher got), ``frames_numbered`` and
        ``flood_fps`` (the server's frames over the flood, and per second), ``ping_max_s``,
        ``closed`` (the watcher's close code or ``None``), ``rss_before_mb``,
        ``rss_peak_mb`` (the most during the flood, polled), ``rss_after_mb``, ``floods``
        (each connection's counts), ``stats_after``, ``slow_clients`` (the clients the
        server closed for their backlog) and ``slow_closed_after`` (the frames the server
        made from the flood's start until it had closed both slow readers, polled;
        ``None``: it had not).
    """
    with server_process(*server_args) as (url, proc):
        watcher = Watcher(url)
        watcher.start()
        watcher.connected.wait(START_TIMEOUT)
        if watcher.error is not None:
            raise watcher.error
        frames_after(watcher, SETTLE_FRAMES)
        # The quiet rate over the frames of ``quiet`` seconds at 30 a second, as the watcher
        # receives them (a window of frames, not of the wall clock).
        s0, t0 = stats(url), time.perf_counter()
        frames_after(watcher, round(quiet * 30))
        s1, t1 = stats(url), time.perf_counter()
        rss_before = rss_mb(proc.pid)
        floods = run_floods(url, seconds)
        if floods.stdout.readline().strip() != READY:
            raise RuntimeError("the floods did not connect")
        start = time.perf_counter()
        polls: list[tuple[dict[str, Any], float]] = []
        halt = threading.Event()

        def poll() -> None:
            while not halt.wait(POLL_EVERY):
                with contextlib.suppress(httpx.HTTPError, OSError, RuntimeError):
                    polls.append((stats(url), rss_mb(proc.pid)))

        poller = threading.Thread(target=poll, name="hostile-poll", daemon=True)
        poller.start()
        try:
            out, _ = floods.communicate(timeout=START_TIMEOUT + seconds + DRAIN_TIMEOUT + 60)
        finally:
            halt.set()
            poller.join(60)
        end = time.perf_counter()
        s2 = stats(url)
        frames_after(watcher, SETTLE_FRAMES)
        s3, t3 = stats(url), time.perf_counter()
        frames_after(watcher, round(quiet * 30))
        s4, t4 = stats(url), time.perf_counter()
        rss_after = rss_mb(proc.pid)
        watcher.stop()
    counts = json.loads(out.strip().splitlines()[-1])
    slow_readers = KINDS.count(DEAF) + KINDS.count(SLOW)
    flood_end = start + seconds
    bins, made = watcher.per_second(start, min(flood_end, end))
    numbers = [n for t, n in zip(watcher.arrivals, watcher.numbers, strict=True)
               if start <= t < flood_end]
    pings = [rtt for t, rtt in watcher.pings if start <= t < end]
    return {
        "quiet_fps": (s1["frames"] - s0["frames"]) / (t1 - t0),
        "quiet_after_fps": (s4["frames"] - s3["frames"]) / (t4 - t3),
        "flood_frames": s2["frames"] - s1["frames"],
        "per_second": bins, "worst_second": min(bins) if bins else 0,
        "made_per_second": made,
        "frames_numbered": (max(numbers) - min(numbers) + 1) if numbers else 0,
        "flood_fps": ((max(numbers) - min(numbers) + 1) / seconds) if numbers else 0.0,
        "ping_max_s": max(pings) if pings else None,
        "closed": watcher.closed, "watch_error": repr(watcher.error) if watcher.error else None,
        "rss_before_mb": rss_before, "rss_after_mb": rss_after,
        "rss_peak_mb": max([rss_after, *(r for _, r in polls)]),
        "floods": counts, "stats_after": s2, "slow_clients": s2.get("slow_clients", 0),
        "slow_closed_after": next((p["frames"] - s1["frames"] for p, _ in polls
                                   if p.get("slow_clients", 0) >= slow_readers), None),
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
