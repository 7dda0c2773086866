"""Load on ``emotive serve``: 2,000 agents watched by 10 clients at 30 fps, a stalled client.

The server runs as its own process (``emotive serve --port 0``), as users run it, so that the
clients (websocket readers in this process, on one event loop) do not share its interpreter
lock; on the 2-core development machine they still share its cores. Each client counts the
frames and bytes it receives (the 32-byte header checked, not decoded further). Scenarios:

* crowd (the issue's load): 10 clients each adding 200 agents (a scene of 2,000) at 30 fps,
  with ``--workers 1`` (the scene stepped in the server's process), ``--workers 2`` (two
  step worker processes, ``--worker-kind processes``) and ``--workers 2 --worker-kind
  threads`` (two step threads, the default on the torch backend), frames in
  the compact layout (``EMF2``), and ``--workers 2 --worker-kind processes`` with the float32
  layout (``EMF1``),
  the configurations in turn, ``repeats`` rounds; ``--step-budget 10`` so that admission
  lets all 2,000 in whatever the step costs (the default budget, half a frame, admits only
  what the machine steps in time; the agents in the scene are printed in each row's name);
* shared: one scene of 200 agents (added by one client) watched by 10 clients;
* stalled: the shared scene while one of the 10 clients stops reading (its socket paused):
  the rate of the other nine, against the shared scene's rate;
* backend: the server's step time (p50) with 200 agents on ONNX Runtime against torch, when
  the ONNX backend is installed;
* split: the step alone (no server), 2,000 agents on one thread against two threads and two
  processes of 1,000 each, in agent-frames per second: whether a second core helps.

Per crowd run: frames received per client per second (the slowest client) against the
30 fps clock, frames on time (``1 - late_frames / frames`` of ``/api/stats`` over the measured
window) against the 99 % target, the p50 and p99 of the server's tick time against the
33.3 ms frame budget, MB/s received per client, and where the processor time goes per frame:
the server's simulation thread (commands, joining the workers' frames, encoding), its event
loop (sending to the clients), the step workers, and the clients (this process). Each
configuration runs ``repeats`` times; rows give the medians.

``python -m bench.bench_serve [--repeats 3] [--seconds 10] [--crowd-only | --split-only]``.
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import httpx
import torch
import websockets

from bench.common import comparison
from emotive.data.emotion import coerce_emotion
from emotive.paths import figure8
from emotive.serve.engines import load_engine
from emotive.serve.frames import HEADER, MAGIC, MAGIC_V2, frame_bytes

FPS = 30.0
#: Seconds the server may take to start.
START_TIMEOUT = 120.0
_URL = re.compile(r"app:\s+(http://\S+?)/")


@contextmanager
def server_process(*args: str) -> Iterator[tuple[str, int]]:
    """Run ``emotive serve --port 0 ARGS`` in a subprocess; yield its URL and pid; stop it."""
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
        url = next(m.group(1) for m in map(_URL.search, lines) if m)
        # The URL is printed before the step workers have started: wait until it answers.
        deadline = time.monotonic() + START_TIMEOUT
        while True:
            try:
                if httpx.get(f"{url}/api/health", timeout=START_TIMEOUT).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"emotive serve did not answer: {''.join(lines)[-2000:]}")
            time.sleep(0.2)
        yield url, proc.pid
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class Watcher:
    """One websocket client counting the frames and bytes it gets (and maybe adding agents).

    Args:
        url: the server's base URL.
        encoding: the frame layout to ask for (1 or 2).
    """

    def __init__(self, url: str, encoding: int = 2) -> None:
        self.url = url.replace("http://", "ws://", 1) + f"/ws?encoding={encoding}"
        self.frames = 0
        self.bytes = 0
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
                if isinstance(message, bytes) and message[:4] in (MAGIC, MAGIC_V2):
                    self.frames += 1
                    self.bytes += len(message)
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


def _ticks(path: Path) -> float:
    """Processor seconds (user + system) of the process or thread whose ``stat`` it is."""
    fields = path.read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def server_cpu(pid: int) -> dict[str, float]:
    """Processor seconds so far of the server's threads and its step workers (Linux ``/proc``).

    Keys: ``loop`` (the main thread: uvicorn's event loop, which sends the frames),
    ``simulation`` (the server's other threads: the simulation thread, and the preparer of
    control messages, idle while the load is measured), ``workers`` (the step worker
    processes). Empty where ``/proc`` is missing.
    """
    out = {"simulation": 0.0, "loop": 0.0, "workers": 0.0}
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            key = "loop" if task.name == str(pid) else "simulation"
            out[key] += _ticks(task / "stat")
        for proc in Path("/proc").iterdir():
            if proc.name.isdigit():
                try:
                    fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
                    if int(fields[1]) == pid:
                        out["workers"] += _ticks(proc / "stat")
                except OSError:
                    continue
    except OSError:
        return {}
    return out


async def _stats(url: str) -> dict[str, Any]:
    async with httpx.AsyncClient() as client:
        return (await client.get(f"{url}/api/stats", timeout=30)).json()


async def _measure(url: str, clients: int, agents: int, own: bool, seconds: float,
                   stall: bool = False, encoding: int = 2, pid: int = 0) -> dict[str, Any]:
    """Frames and MB per client per second, on-time share, tick times, processor time."""
    watchers = [Watcher(url, encoding) for _ in range(clients)]
    for k, w in enumerate(watchers):
        await w.start(add=agents if own or k == 0 else 0)
    total = agents * (clients if own else 1)
    deadline = time.monotonic() + 180
    while min(w.agents for w in watchers) < total and time.monotonic() < deadline:
        stats = await _stats(url)
        if stats["agents"] >= stats["capacity"] and stats["agents"] > 0 and all(
                w.agents >= stats["agents"] for w in watchers):
            break  # admission stopped short of the total: measure what it let in
        await asyncio.sleep(0.2)
    await asyncio.sleep(3.0)
    if stall:
        watchers[-1].stop_reading()
        await asyncio.sleep(2.0)
    fast = watchers[:-1] if stall else watchers
    before, counts, sizes = await _stats(url), [w.frames for w in fast], [w.bytes for w in fast]
    cpu0, own0, t0 = server_cpu(pid), time.process_time(), time.perf_counter()
    await asyncio.sleep(seconds)
    after, elapsed = await _stats(url), time.perf_counter() - t0
    cpu1, own1 = server_cpu(pid), time.process_time()
    rates = [(w.frames - c) / elapsed for w, c in zip(fast, counts, strict=True)]
    mbs = [(w.bytes - b) / elapsed / 1e6 for w, b in zip(fast, sizes, strict=True)]
    frames = max(after["frames"] - before["frames"], 1)
    late = after["late_frames"] - before["late_frames"]
    for w in watchers:
        await w.close()
    # Processor milliseconds per frame the server made.
    cpu = {k: round(1000.0 * (cpu1[k] - cpu0[k]) / frames, 2) for k in cpu1}
    cpu["clients"] = round(1000.0 * (own1 - own0) / frames, 2)
    return {"min_rate": min(rates), "mean_rate": sum(rates) / len(rates),
            "on_time": 100.0 * (1.0 - late / frames), "p99": after["step_ms"]["p99"],
            "p50": after["step_ms"]["p50"], "server_fps": frames / elapsed,
            "dropped": after["dropped_frames"] - before["dropped_frames"],
            "agents": after["agents"], "mb_per_client": statistics.median(mbs),
            "tick_ms": after.get("tick_ms", {}), "cpu_ms_per_frame": cpu}


def _scenario(clients: int, agents: int, own: bool, seconds: float, stall: bool = False,
              *args: str, encoding: int = 2) -> dict[str, Any]:
    limit = str(max(500, agents * clients))
    with server_process("--max-agents", limit, *args) as (url, pid):
        return asyncio.run(_measure(url, clients, agents, own, seconds, stall, encoding, pid))


def _rows(label: str, m: dict[str, float]) -> list[dict]:
    return [
        comparison(f"serve_{label}: frames/s, slowest client", "frames/s", m["min_rate"], FPS,
                   "the 30 fps clock"),
        comparison(f"serve_{label}: frames on time", "%", m["on_time"], 99.0, "target: 99 %"),
        comparison(f"serve_{label}: tick p99", "ms", m["p99"], 1000.0 / FPS,
                   "the 33.3 ms frame budget", higher_is_better=False),
    ]


#: The crowd configurations: (step workers, worker kind, frame layout).
CROWD = ((1, "-", 2), (2, "processes", 2), (2, "threads", 2), (2, "processes", 1))
#: ``--step-budget`` of the crowd runs: admission lets the whole crowd in, whatever the step
#: costs, so that every run carries the issue's load.
CROWD_BUDGET = 10

Config = tuple[int, str, int]


def crowd(configs: tuple[Config, ...] = CROWD, clients: int = 10, agents: int = 200,
          seconds: float = 10.0, repeats: int = 1) -> dict[Config, dict[str, Any]]:
    """The issue's load in each configuration: medians, and every run.

    ``repeats`` rounds of all the configurations in turn, so that a change in the machine's
    other load touches each alike.
    """
    runs: dict[Config, list[dict[str, Any]]] = {c: [] for c in configs}
    for _ in range(repeats):
        for config in configs:
            workers, kind, encoding = config
            args = ["--workers", str(workers), "--step-budget", str(CROWD_BUDGET)]
            args += ["--worker-kind", kind] if workers > 1 else []
            m = _scenario(clients, agents, True, seconds, False, *args, encoding=encoding)
            print(f"  crowd workers={workers} {kind} EMF{encoding}: {m}", flush=True)
            runs[config].append(m)
    results = {}
    for config, done in runs.items():
        out: dict[str, Any] = {k: statistics.median(r[k] for r in done) for k in (
            "min_rate", "mean_rate", "on_time", "p50", "p99", "server_fps", "agents",
            "mb_per_client")}
        for key in ("cpu_ms_per_frame", "tick_ms"):
            out[key] = {k: statistics.median(r[key].get(k, 0.0) for r in done)
                        for k in done[0][key]}
        out["runs"] = done
        results[config] = out
    return results


def _crowd_name(m: dict[str, Any], clients: int, agents: int, config: Config) -> str:
    workers, kind, encoding = config
    how = f"workers={workers}" + (f" {kind}" if workers > 1 else "")
    return (f"serve_crowd[{m['agents']:.0f} agents ({clients}x{agents}), {clients} clients, "
            f"30 fps, {how}, EMF{encoding}]")


def crowd_rows(results: dict[Config, dict[str, Any]], clients: int, agents: int
               ) -> list[dict]:
    """Rows of the crowd runs (each row names its load) and the side-by-side ratios."""
    rows = []
    for config, m in results.items():
        name = _crowd_name(m, clients, agents, config)
        v1 = frame_bytes(1, int(m["agents"]), 22, 27, 19) * m["mean_rate"] / 1e6
        rows += [
            comparison(f"{name}: frames on time", "%", m["on_time"], 99.0, "target: 99 %"),
            comparison(f"{name}: frames/s, slowest client", "frames/s", m["min_rate"], FPS,
                       "the 30 fps clock"),
            comparison(f"{name}: tick p50", "ms", m["p50"], 1000.0 / FPS,
                       "the 33.3 ms frame budget", higher_is_better=False),
            comparison(f"{name}: tick p99", "ms", m["p99"], 1000.0 / FPS,
                       "the 33.3 ms frame budget", higher_is_better=False),
            comparison(f"{name}: MB/s per client", "MB/s", m["mb_per_client"], v1,
                       "EMF1 frames at the same rate", higher_is_better=False),
        ]
    one = results.get((1, "-", 2))
    for kind in ("processes", "threads"):
        two = results.get((2, kind, 2))
        if one and two:
            rows.append(comparison(
                f"serve_crowd[{clients}x{agents}]: frames/s slowest client, workers=2 {kind} "
                "vs 1", "frames/s", two["min_rate"], one["min_rate"], "workers=1"))
    b = clients * agents
    rows.append(comparison(f"serve_frame_bytes[{b} agents]: EMF2 vs EMF1", "bytes",
                           frame_bytes(2, b, 22, 0, 19), frame_bytes(1, b, 22, 27, 19),
                           "EMF1 frame", higher_is_better=False))
    return rows


def onnx_available() -> bool:
    """Whether the ONNX backend's module and runtime are installed."""
    return all(importlib.util.find_spec(name) is not None
               for name in ("onnxruntime", "emotive.models.gait.onnx_runtime"))


def _crowd_engine(agents: int) -> Any:
    """The server's gait engine with ``agents`` agents on figure-8s, stepped a few times."""
    torch.set_num_threads(1)
    engine = load_engine()
    neutral = coerce_emotion("neutral", engine.labels, engine.points_over)
    for k in range(0, agents, 100):
        n = min(100, agents - k)
        engine.add_agents([figure8()] * n, [neutral] * n, [0.37 * i for i in range(n)],
                          [1.0] * n)
    for _ in range(5):
        engine.step()
    return engine


def _steps(engine: Any, steps: int) -> None:
    for _ in range(steps):
        engine.step()


def _step_child(agents: int, steps: int) -> None:
    """A child of :func:`split`: build an engine, say ready, step on a line of stdin."""
    engine = _crowd_engine(agents)
    print("ready", flush=True)
    sys.stdin.readline()
    start = time.perf_counter()
    _steps(engine, steps)
    print(json.dumps(time.perf_counter() - start), flush=True)


def split(agents: int = 2000, steps: int = 60) -> dict[str, float]:
    """Agent-frames per second of one step split three ways (the alternatives of the design).

    ``thread``: one engine steps all ``agents`` on one thread (``--workers 1``); ``threads``:
    two engines of half each, in two threads of one process (the interpreter lock shared);
    ``processes``: two processes of half each, started together (``--workers 2``'s step,
    without the server).
    """
    out = {}
    engine = _crowd_engine(agents)
    start = time.perf_counter()
    _steps(engine, steps)
    out["thread"] = agents * steps / (time.perf_counter() - start)
    del engine
    engines = [_crowd_engine(agents // 2) for _ in range(2)]
    threads = [threading.Thread(target=_steps, args=(e, steps)) for e in engines]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    out["threads"] = agents * steps / (time.perf_counter() - start)
    del engines
    children = [subprocess.Popen([sys.executable, "-m", "bench.bench_serve", "--step-child",
                                  str(agents // 2), str(steps)], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE, text=True) for _ in range(2)]
    for child in children:
        if child.stdout.readline().strip() != "ready":
            raise RuntimeError("a step child did not start")
    start = time.perf_counter()
    for child in children:
        child.stdin.write("go\n")
        child.stdin.flush()
    for child in children:
        json.loads(child.stdout.readline())
    out["processes"] = agents * steps / (time.perf_counter() - start)
    for child in children:
        child.wait()
    return out


def split_rows(agents: int = 2000, steps: int = 60, repeats: int = 1) -> list[dict]:
    """Rows of :func:`split`: two threads and two processes against one thread (medians)."""
    runs = [split(agents, steps) for _ in range(repeats)]
    for r in runs:
        print(f"  split[{agents} agents]: {r}", flush=True)
    m = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
    return [comparison(f"serve_split[{agents} agents, {how}]: agent-frames/s", "frames/s",
                       m[how], m["thread"], "one thread") for how in ("threads", "processes")]


def run(clients: int = 10, agents: int = 200, seconds: float = 10.0, repeats: int = 1,
        crowd_only: bool = False) -> list[dict]:
    """The load rows (see the module docstring); prints each scenario's numbers as it goes."""
    results = crowd(CROWD, clients, agents, seconds, repeats)
    for (w, kind, e), m in results.items():
        print(f"  crowd median workers={w} {kind} EMF{e}: "
              f"{ {k: v for k, v in m.items() if k != 'runs'} }", flush=True)
    rows = crowd_rows(results, clients, agents) + split_rows(clients * agents,
                                                              repeats=repeats)
    if crowd_only:
        return rows
    shared = _scenario(clients, agents, False, seconds)
    print(f"  shared: {shared}", flush=True)
    stalled = _scenario(clients, agents, False, seconds, True)
    print(f"  stalled: {stalled}", flush=True)
    rows += _rows(f"shared[{agents} agents, {clients} clients]", shared)
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
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3, help="runs of each crowd setup")
    parser.add_argument("--seconds", type=float, default=10.0, help="measured seconds")
    parser.add_argument("--crowd-only", action="store_true",
                        help="the crowd and split rows only")
    parser.add_argument("--split-only", action="store_true", help="the split rows only")
    parser.add_argument("--step-child", nargs=2, type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.step_child:
        _step_child(*args.step_child)
        return
    if args.split_only:
        for row in split_rows(repeats=args.repeats):
            print(row)
        return
    start = time.perf_counter()
    for row in run(seconds=args.seconds, repeats=args.repeats, crowd_only=args.crowd_only):
        print(row)
    print(f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
