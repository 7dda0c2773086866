"""The simulation thread: it alone owns the engine, and steps it on a fixed clock.

Tick ``k`` is due at ``t0 + k / fps``. At each tick the thread applies the commands that
arrived since the last one, all prepared off this thread
(:mod:`~emotive.serve.preparation`); new agents join in one batched call (so a hundred new
agents cost one warm-up of the network) of at most :data:`JOIN_PER_TICK`, the others (and
the later commands of their clients, which stay in order) at the next ticks. It then steps
the engine, encodes the frame
once (:func:`~emotive.serve.frames.encode_frame`), hands the bytes to the :class:`Sink`
(which fans them out to the clients without waiting for any) and feeds the running
recordings. A frame finished after the next tick was due counts as late; when the thread
falls more than a frame behind it skips the missed ticks instead of bursting to catch up, so
scene time (frame number / fps) then runs behind wall time.

Control messages reach the thread through a thread-safe queue (:meth:`Simulation.submit`)
and are answered through :class:`concurrent.futures.Future` objects; the engine is never
touched by two threads.

Admission: an agent joins only if its client has fewer than ``max_agents_per_client`` in
the scene and the scene fewer than :meth:`Simulation.capacity`: ``max_agents``, or fewer
where the measured step time (processor time of this thread, which the engine steps in)
says that more would not be stepped within :data:`STEP_BUDGET` of a frame. The step's
median time at each of the last
:data:`COUNTS_FITTED` agent counts is fitted by a line (a fixed cost plus a cost per agent)
once those counts span :data:`MEASURED_AGENTS`; the limit is where the line crosses the
budget, and the present count when the step already takes longer.

Legend: ``B`` agents, ``J`` joints, ``C`` emotion labels.
"""

from __future__ import annotations

import gc
import logging
import math
import queue
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from emotive.data.emotion import EmotionSchedule
from emotive.errors import EmotiveError
from emotive.models.gait.generate import GaitFrame
from emotive.paths import GroundPath
from emotive.serve.engines import Engine
from emotive.serve.errors import MessageError
from emotive.serve.frames import Frame, encode_frame
from emotive.serve.messages import AddAgent, Command
from emotive.serve.recording import Recorder
from emotive.serve.settings import ServeSettings

log = logging.getLogger("emotive.serve")

#: Steps whose times give the p50/p99 of ``/api/stats``.
STEP_WINDOW = 300
#: Most points of a path reported in an agent's state.
STATE_PATH_POINTS = 200
#: Most agents joining at one tick (100 joining took 15 ms on a 2-core machine).
JOIN_PER_TICK = 32
#: Share of the frame period the engine's step may take with every agent the scene admits.
STEP_BUDGET = 0.5
#: Agent counts whose step times are fitted (the most recent ones).
COUNTS_FITTED = 8
#: The fitted counts must span at least this many agents.
MEASURED_AGENTS = 16
#: Recent steps kept per agent count.
COST_WINDOW = 15


class Sink(Protocol):
    """Where the simulation thread sends what it makes; both calls must return at once."""

    def frame(self, data: bytes) -> None:
        """One encoded frame for every client."""

    def notice(self, client: int, message: dict[str, Any]) -> None:
        """A message for one client (e.g. its recording reached its limit)."""


@dataclass
class _Agent:
    """What the server knows of an agent beside the engine."""

    path: GroundPath
    schedule: EmotionSchedule
    since: float
    pace: float
    owner: int = -1


class Simulation:
    """The scene's thread: engine, clock, commands, stats and recordings.

    Args:
        engine: the engine it alone steps.
        settings: the server's settings (``max_agents``, the recording limits).
        sink: receiver of frames and notices (:class:`Sink`).
        clock: the time source, seconds.
        cpu_clock: this thread's processor time, seconds (the step times the admission
            limit is derived from: other programs on the machine do not inflate them).
    """

    def __init__(self, engine: Engine, settings: ServeSettings, sink: Sink,
                 clock: Callable[[], float] = time.perf_counter,
                 cpu_clock: Callable[[], float] = time.thread_time) -> None:
        self.engine = engine
        self.settings = settings
        self.sink = sink
        self.fps = engine.fps
        self._clock = clock
        self._cpu = cpu_clock
        self._queue: queue.SimpleQueue[tuple[Command, int, Future]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._agents: dict[int, _Agent] = {}
        self._last = engine.step()
        self._va = np.zeros((0, 2))
        self.recorder = Recorder(settings.recording_seconds * self.fps,
                                 settings.recording_megabytes * 1e6, settings.kept_recordings)
        self._lock = threading.Lock()
        self._steps: deque[float] = deque(maxlen=STEP_WINDOW)
        self._pending: deque[tuple[Command, int, Future]] = deque()
        self._owned: dict[int, int] = {}
        self._times: OrderedDict[int, deque[float]] = OrderedDict()
        self._capacity = settings.max_agents
        self._done: deque[float] = deque()
        self.frames = 0
        self.late_frames = 0

    # ----------------------------------------------------------------------------- thread

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread = threading.Thread(target=self._run, name="emotive-simulation",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread and wait for it; pending commands fail."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
        while True:
            try:
                self._pending.append(self._queue.get_nowait())
            except queue.Empty:
                break
        for _, _, future in self._pending:
            if not future.done():
                future.set_exception(MessageError("the server is shutting down"))
        self._pending.clear()

    def submit(self, command: Command, client: int = -1) -> Future:
        """Queue a command for the next tick; its future gets the reply message."""
        future: Future = Future()
        if self._stop.is_set():
            future.set_exception(MessageError("the server is shutting down"))
        else:
            self._queue.put((command, client, future))
        return future

    def _run(self) -> None:
        # The model, the rig and the app are loaded: keep them out of the cyclic collector's
        # full passes, whose pauses otherwise land inside ticks.
        gc.freeze()
        period = 1.0 / self.fps
        t0 = self._clock()
        k = 0
        while not self._stop.is_set():
            wait = t0 + k * period - self._clock()
            if wait > 0 and self._stop.wait(wait):
                break
            start = self._clock()
            try:
                self._apply_pending()
                self._tick()
            except Exception:
                # Nothing may end the stream: log it and go on with the next tick.
                log.exception("simulation tick failed")
            end = self._clock()
            with self._lock:
                self._steps.append(end - start)
                self._done.append(end)
                while self._done and self._done[0] < end - 1.0:
                    self._done.popleft()
                self.frames += 1
                self.late_frames += end > t0 + (k + 1) * period
            k += 1
            if end > t0 + (k + 1) * period:
                k = math.floor((end - t0) / period)

    def _tick(self) -> None:
        try:
            agents = len(self.engine)
            start = self._cpu()
            frame = self.engine.step()
            self._measured(agents, self._cpu() - start)
        except Exception:
            # A model failure must not end the stream: log it and serve the last frame again.
            log.exception("the engine failed to step; the scene holds its last frame")
            frame = self._last
        self._last = frame
        number = self.frames
        va = self._valence_arousal(frame, number / self.fps)
        mover = self.engine.mover
        data = encode_frame(Frame(number, number / self.fps, np.asarray(frame.agents),
                                  va, frame.emotion, frame.positions[:, mover],
                                  frame.rotations, frame.world))
        self.sink.frame(data)
        if self.recorder.running:
            for rec in self.recorder.capture(np.asarray(frame.agents, dtype=np.int32),
                                             frame.rotations, frame.positions):
                self.sink.notice(rec.owner, {
                    "type": "error", "message": (
                        f"recording {rec.rid} reached its limit of {rec.frames} frames; it "
                        "keeps those: send stop_recording to finish it")})

    def _valence_arousal(self, frame: GaitFrame, now: float) -> np.ndarray:
        """``(B, 2)`` each agent's valence and arousal at scene time ``now``."""
        va = np.zeros((len(frame.agents), 2))
        for k, agent in enumerate(frame.agents):
            info = self._agents.get(agent)
            if info is None:
                continue
            pts, times = info.schedule.points, info.schedule.times
            if len(times) == 1:
                va[k] = pts[0]
            else:
                t = now - info.since
                va[k] = (np.interp(t, times, pts[:, 0]), np.interp(t, times, pts[:, 1]))
        self._va = va
        return va

    # ----------------------------------------------------------------------------- commands

    def owned(self, client: int) -> int:
        """Agents client ``client`` has in the scene (any thread: a read of one number)."""
        return self._owned.get(client, 0)

    def capacity(self) -> int:
        """Agents the scene admits now: ``max_agents``, or fewer by the measured step time."""
        return self._capacity

    def _measured(self, agents: int, seconds: float) -> None:
        """Take one step's time into the admission limit (see the module docstring)."""
        if agents == 0:
            return
        times = self._times.setdefault(agents, deque(maxlen=COST_WINDOW))
        times.append(seconds)
        self._times.move_to_end(agents)
        while len(self._times) > COUNTS_FITTED:
            self._times.popitem(last=False)
        counts = np.array(list(self._times), dtype=np.float64)
        medians = np.array([np.median(t) for t in self._times.values()])
        budget = STEP_BUDGET / self.fps
        limit = self.settings.max_agents
        if np.median(times) > budget:
            limit = agents
        elif len(counts) >= 2 and np.ptp(counts) >= MEASURED_AGENTS:
            slope, fixed = np.polyfit(counts, medians, 1)
            if slope > 0.0:
                limit = min(limit, max(int((budget - fixed) / slope), agents))
        self._capacity = limit

    def _apply_pending(self) -> None:
        while True:
            try:
                self._pending.append(self._queue.get_nowait())
            except queue.Empty:
                break
        batch: list[tuple[Command, int, Future]] = []
        joined = 0
        waiting: set[int] = set()
        later: deque[tuple[Command, int, Future]] = deque()
        for item in self._pending:
            command, client, _ = item
            if client in waiting:
                later.append(item)
            elif command.kind == "add_agent":
                if joined < JOIN_PER_TICK:
                    batch.append(item)
                    joined += 1
                else:
                    waiting.add(client)
                    later.append(item)
            else:
                self._add(batch)
                batch = []
                self._apply(*item)
        self._add(batch)
        self._pending = later

    def _apply(self, command: Command, client: int, future: Future) -> None:
        try:
            reply = self._reply(command, client)
        except Exception as exc:  # every failure becomes this message's error reply
            future.set_exception(exc)
        else:
            future.set_result(reply)

    def _refusal(self, client: int, taken: dict[int, int], count: int) -> MessageError | None:
        """Why one more agent of ``client`` may not join a scene of ``count``, or ``None``."""
        s = self.settings
        if client >= 0 and self.owned(client) + taken.get(client, 0) >= s.max_agents_per_client:
            return MessageError(
                f"you have {self.owned(client)} agents in the scene, the limit per client "
                f"(--max-agents-per-client {s.max_agents_per_client}): remove some first")
        if count < self._capacity:
            return None
        if self._capacity >= s.max_agents:
            return MessageError(f"the scene holds {count} agents, the server's limit "
                                f"(--max-agents {s.max_agents}): remove agents first")
        return MessageError(
            f"the scene holds {count} agents, the most this machine steps within "
            f"{100 * STEP_BUDGET:.0f} % of a {1000 / self.fps:.1f} ms frame by its measured "
            f"step time (limit now {self._capacity}, below --max-agents {s.max_agents}): "
            "remove agents first, or try again when the machine is less busy")

    def _add(self, batch: list[tuple[Command, int, Future]]) -> None:
        """Add a run of ``add_agent`` commands, batched, within the quotas and the capacity."""
        taken: dict[int, int] = {}
        admitted = []
        for item in batch:
            refusal = self._refusal(item[1], taken, len(self.engine) + len(admitted))
            if refusal is not None:
                item[2].set_exception(refusal)
                continue
            taken[item[1]] = taken.get(item[1], 0) + 1
            admitted.append(item)
        batch = admitted
        if not batch:
            return
        specs: list[AddAgent] = [c.value for c, _, _ in batch]
        try:
            ids = self.engine.add_agents([s.path for s in specs], [s.schedule for s in specs],
                                         [s.start for s in specs], [s.pace for s in specs])
        except Exception as exc:  # every failure becomes this message's error reply
            if len(batch) == 1:
                batch[0][2].set_exception(exc)
                return
            # One bad entry spoils a batch: add one at a time, each with its own reply.
            for item in batch:
                self._add([item])
            return
        now = self.frames / self.fps
        for agent, spec, (_, client, future) in zip(ids, specs, batch, strict=True):
            self._agents[agent] = _Agent(spec.path, spec.schedule, now, spec.pace, client)
            self._owned[client] = self._owned.get(client, 0) + 1
            future.set_result({"type": "agent", "id": agent})

    def _known(self, agent: int | None) -> int:
        if agent not in self._agents:
            raise MessageError(f"no agent with id {agent}: it was never added or was removed "
                               '(send {"type": "state"} for the live ones)')
        return int(agent)

    def _reply(self, command: Command, client: int) -> dict[str, Any]:
        kind, value = command.kind, command.value
        if kind == "state":
            return {"type": "state", "agents": self.agent_states()}
        if kind == "start_recording":
            rec = self.recorder.start(client)
            return {"type": "recording", "id": rec.rid, "state": "started"}
        if kind == "client_left":
            self.recorder.release(client)
            return {"type": "ok"}
        if kind == "stop_recording":
            rec = self.recorder.stop(client, value)
            return {"type": "recording", "id": rec.rid, "state": "stopped",
                    "frames": rec.frames, "agents": rec.agents}
        agent = self._known(command.agent)
        info = self._agents[agent]
        if kind == "remove_agent":
            self.engine.remove_agent(agent)
            del self._agents[agent]
            self._owned[info.owner] = self._owned.get(info.owner, 1) - 1
        elif kind == "set_emotion":
            self.engine.set_emotion(agent, value)
            info.schedule, info.since = value, self.frames / self.fps
        elif kind == "set_path":
            self.engine.set_path(agent, value)
            info.path = value
        elif kind == "set_target":
            info.path = self.engine.set_target(agent, value)
        elif kind == "set_pace":
            self.engine.set_pace(agent, value)
            info.pace = value
        else:
            raise MessageError(f"unknown command {kind!r}")
        return {"type": "ok"}

    def agent_states(self) -> list[dict[str, Any]]:
        """Every live agent's state, as ``GET /api/agents`` reports it (simulation thread)."""
        frame = self._last
        rows = {a: k for k, a in enumerate(frame.agents)}
        labels = self.engine.labels
        out = []
        for agent, info in self._agents.items():
            k = rows.get(agent)
            weights = (frame.emotion[k] if k is not None else info.schedule.at(0.0))
            va = self._va[k] if k is not None and k < len(self._va) else info.schedule.points[0]
            pts = info.path.points
            step = max(1, math.ceil(len(pts) / STATE_PATH_POINTS))
            path = np.vstack((pts[::step], pts[-1:])) if (len(pts) - 1) % step else pts[::step]
            out.append({
                "id": agent,
                "emotion": {n: round(float(w), 4) for n, w in zip(labels, weights, strict=True)
                            if w > 1e-4},
                "valence": round(float(va[0]), 4), "arousal": round(float(va[1]), 4),
                "pace": info.pace, "path": np.round(path, 3).tolist(),
            })
        return out

    # ----------------------------------------------------------------------------- stats

    def stats(self) -> dict[str, Any]:
        """``frames``, ``late_frames``, ``fps`` (last second) and ``step_ms`` p50/p99."""
        with self._lock:
            steps = np.array(self._steps) * 1000.0
            fps = len(self._done)
            frames, late = self.frames, self.late_frames
        p50, p99 = (np.percentile(steps, [50, 99]) if len(steps) else (0.0, 0.0))
        return {"agents": len(self._agents), "capacity": self._capacity,
                "fps": float(fps), "frames": frames,
                "late_frames": late, "step_ms": {"p50": round(float(p50), 3),
                                                 "p99": round(float(p99), 3)}}


def error_text(exc: BaseException) -> str:
    """The ``error`` reply's message for an exception raised while handling a message."""
    if isinstance(exc, EmotiveError | ValueError):
        return " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, KeyError):
        return str(exc.args[0]) if exc.args else "unknown key"
    log.error("internal error handling a message", exc_info=exc)
    return f"internal error ({type(exc).__name__}); the message was not applied"
