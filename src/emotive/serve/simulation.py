"""The simulation thread: it alone owns the engine, and steps it on a fixed clock.

Tick ``k`` is due at ``t0 + k / fps``. At each tick the thread applies the commands that
arrived since the last one (consecutive ``add_agent`` commands in one batched call, so a
hundred new agents cost one warm-up of the network), steps the engine, encodes the frame
once (:func:`~emotive.serve.frames.encode_frame`), hands the bytes to the :class:`Sink`
(which fans them out to the clients without waiting for any) and feeds the running
recordings. A frame finished after the next tick was due counts as late; when the thread
falls more than a frame behind it skips the missed ticks instead of bursting to catch up, so
scene time (frame number / fps) then runs behind wall time.

Control messages reach the thread through a thread-safe queue (:meth:`Simulation.submit`)
and are answered through :class:`concurrent.futures.Future` objects; the engine is never
touched by two threads.

Legend: ``B`` agents, ``J`` joints, ``C`` emotion labels.
"""

from __future__ import annotations

import gc
import logging
import math
import queue
import threading
import time
from collections import deque
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


class Simulation:
    """The scene's thread: engine, clock, commands, stats and recordings.

    Args:
        engine: the engine it alone steps.
        settings: the server's settings (``max_agents``, the recording limits).
        sink: receiver of frames and notices (:class:`Sink`).
        clock: the time source, seconds.
    """

    def __init__(self, engine: Engine, settings: ServeSettings, sink: Sink,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.engine = engine
        self.settings = settings
        self.sink = sink
        self.fps = engine.fps
        self._clock = clock
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
                _, _, future = self._queue.get_nowait()
            except queue.Empty:
                break
            future.set_exception(MessageError("the server is shutting down"))

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
            frame = self.engine.step()
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

    def _apply_pending(self) -> None:
        batch: list[tuple[Command, int, Future]] = []
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item[0].kind == "add_agent":
                batch.append(item)
                continue
            self._add(batch)
            batch = []
            self._apply(*item)
        self._add(batch)

    def _apply(self, command: Command, client: int, future: Future) -> None:
        try:
            reply = self._reply(command, client)
        except Exception as exc:  # every failure becomes this message's error reply
            future.set_exception(exc)
        else:
            future.set_result(reply)

    def _add(self, batch: list[tuple[Command, int, Future]]) -> None:
        """Add a run of ``add_agent`` commands, batched, within ``max_agents``."""
        room = self.settings.max_agents - len(self.engine)
        for _, _, future in batch[max(room, 0):]:
            future.set_exception(MessageError(
                f"the scene holds {len(self.engine)} agents, the server's limit (--max-agents "
                f"{self.settings.max_agents}): remove agents first"))
        batch = batch[:max(room, 0)]
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
        for agent, spec, (_, _, future) in zip(ids, specs, batch, strict=True):
            self._agents[agent] = _Agent(spec.path, spec.schedule, now, spec.pace)
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
        return {"agents": len(self._agents), "fps": float(fps), "frames": frames,
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
