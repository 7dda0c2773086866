"""The simulation thread: it alone owns the engine, and steps it on a fixed clock.

Tick ``k`` is due at ``t0 + k / fps``; its frame is made as soon as the frame before it is
handed out, and handed out when due, so that a tick that takes longer than a period now and
then uses the time the others left. For each frame the thread applies the commands that
arrived since the last one, all prepared off this thread
(:mod:`~emotive.serve.preparation`), in fair turns and within a share of the frame, and
joins new agents in the time the tick has to spare (:mod:`~emotive.serve.commands`). It then
steps the engine (its own, or the step worker processes of
:class:`~emotive.serve.workers.ShardedEngine`), encodes the frame once in each layout some
client asked for (:func:`~emotive.serve.frames.encode_frame`), hands the bytes to the
:class:`Sink` (which fans them out to the clients without waiting for any) and feeds the
running recordings. A frame handed out after the next tick was due counts as late; when the
thread falls more than a frame behind it skips the missed ticks instead of bursting to catch
up, so scene time (frame number / fps, :meth:`Simulation.scene_time`) then runs behind wall
time. While it waits for a frame's due time, other threads may use the interpreter: the
preparer of control messages waits for those moments (:meth:`Simulation.wait_spare`), so
that its work, which holds the interpreter lock, does not lengthen a tick.

Control messages reach the thread through a thread-safe queue (:meth:`Simulation.submit`)
and are answered through :class:`concurrent.futures.Future` objects; the engine is never
touched by two threads. A step worker that is lost takes its agents along: they leave the
scene and every client gets an ``error`` message saying which.

Admission: an agent joins only if its client has fewer than ``max_agents_per_client`` in
the scene and the scene fewer than :meth:`Simulation.capacity`: ``max_agents``, or fewer
where the measured step time says that more would not be stepped within :data:`STEP_BUDGET`
of a frame (:mod:`~emotive.serve.capacity`; the processor time of the thread that steps: this
one, or each step worker, whose limits add up).

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
from typing import Any, Protocol

import numpy as np

from emotive.errors import EmotiveError
from emotive.models.gait.generate import GaitFrame
from emotive.serve.capacity import StepCosts
from emotive.serve.commands import (
    JOIN_BURST,
    JOIN_PER_TICK,
    JOIN_SHARE,
    NO_VA,
    SceneAgent,
    SceneCommands,
)
from emotive.serve.engines import Engine
from emotive.serve.errors import MessageError
from emotive.serve.frames import Frame, encode_frame
from emotive.serve.limits import WorkBudget
from emotive.serve.messages import Command
from emotive.serve.recording import Recorder
from emotive.serve.settings import ServeSettings
from emotive.serve.turns import JoinCosts, Pending, Turns

log = logging.getLogger("emotive.serve")

__all__ = ["JOIN_PER_TICK", "STEP_BUDGET", "Simulation", "Sink", "error_text"]

#: Steps whose times give the p50/p99 of ``/api/stats``.
STEP_WINDOW = 300
#: Share of the frame period the engine's step may take with every agent the scene admits,
#: unless ``--step-budget`` says otherwise.
STEP_BUDGET = ServeSettings.step_budget
#: Weight of a new tick in the estimate of a tick's own time (step and encoding).
TICK_WEIGHT = 0.1
#: Seconds a thread waiting in :meth:`Simulation.wait_spare` checks again at the latest.
SPARE_POLL = 0.1


class Sink(Protocol):
    """Where the simulation thread sends what it makes; every call must return at once."""

    def encodings(self) -> frozenset[int]:
        """The frame layouts (versions) some client asked for now."""

    def frame(self, data: dict[int, bytes]) -> None:
        """One frame for every client, encoded in each layout of :meth:`encodings`."""

    def notice(self, client: int | None, message: dict[str, Any]) -> None:
        """A message for one client (e.g. its recording reached its limit); ``None``: all."""


class Simulation(SceneCommands):
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
        self.frames = 0
        self._clock = clock
        self._cpu = cpu_clock
        self._queue: queue.SimpleQueue[tuple[Command, int, Future, WorkBudget | None]] = (
            queue.SimpleQueue())
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._agents: dict[int, SceneAgent] = {}
        self._last = engine.step()
        self._va = np.zeros((0, 2))
        #: Counts changes of the agents' emotions (the valence/arousal rows are kept until).
        self._emotions = 0
        self._va_key: tuple | None = None
        self._va_base = np.zeros((0, 2))
        self._va_moving: list[tuple[int, SceneAgent]] = []
        self.recorder = Recorder(settings.recording_seconds * self.fps,
                                 settings.recording_megabytes * 1e6, settings.kept_recordings)
        self._lock = threading.Lock()
        self._steps: deque[float] = deque(maxlen=STEP_WINDOW)
        self._turns = Turns()
        self._join_costs = JoinCosts()
        self._join_budget = WorkBudget(JOIN_SHARE, JOIN_BURST, self.scene_time)
        #: What a tick's own step and encoding took lately, seconds (upward at once).
        self._tick_guess = 0.5 / self.fps
        #: Clock time the thread's present wait for a due time ends (0: it is ticking), and
        #: the waits so far.
        self._idle = threading.Condition()
        self._idle_until = 0.0
        self._idles = 0
        self._owned: dict[int, int] = {}
        self._costs: dict[int, StepCosts] = {}
        self._capacity = settings.max_agents
        self._done: deque[float] = deque()
        self._phases: deque[tuple[float, float, float, float]] = deque(maxlen=STEP_WINDOW)
        self.late_frames = 0
        self.lost_agents = 0

    # ----------------------------------------------------------------------------- thread

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread = threading.Thread(target=self._run, name="emotive-simulation",
                                        daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread and wait for it; pending commands fail."""
        self._stop.set()
        with self._idle:
            self._idle.notify_all()
        if self._thread is not None:
            self._thread.join(timeout)
        while True:
            try:
                self._turns.put(Pending(*self._queue.get_nowait()))
            except queue.Empty:
                break
        for item in self._turns:
            if not item.future.done():
                item.future.set_exception(MessageError("the server is shutting down"))
        self._turns.clear()

    def submit(self, command: Command, client: int = -1,
               budget: WorkBudget | None = None) -> Future:
        """Queue a command for the next tick; its future gets the reply message.

        Args:
            command: the prepared command.
            client: the connection it came from (-1: the HTTP API or the server).
            budget: the client's work budget: charged what the command costs this thread,
                and while it is overdrawn the client's commands wait (``None``: neither).
        """
        future: Future = Future()
        if self._stop.is_set():
            future.set_exception(MessageError("the server is shutting down"))
        else:
            self._queue.put((command, client, future, budget))
        return future

    def scene_time(self) -> float:
        """Seconds of scene time so far: frames made / fps (any thread)."""
        return self.frames / self.fps

    def wait_spare(self, seconds: float, patience: float) -> None:
        """Block until the simulation thread waits for a frame's due time (another thread).

        For a thread whose work holds the interpreter lock (the preparer): done while the
        simulation thread waits, it does not lengthen a tick. Returns when a wait with
        ``seconds`` left is under way, else when the next wait begins (the most time there
        is), or after ``patience`` seconds without one (a busy machine, late ticks), or once
        the simulation thread stops.
        """
        deadline = self._clock() + patience
        with self._idle:
            first = self._idles
            while not self._stop.is_set():
                now = self._clock()
                left = self._idle_until - now if self._idle_until else -1.0
                if left >= seconds or (left > 0.0 and self._idles != first) or now >= deadline:
                    return
                self._idle.wait(max(min(SPARE_POLL, deadline - now), 0.001))

    def _wait_due(self, now: float, seconds: float) -> bool:
        """Wait ``seconds`` for a frame's due time (others may work); ``True``: stopped."""
        with self._idle:
            self._idle_until = now + seconds
            self._idles += 1
            self._idle.notify_all()
        stopped = self._stop.wait(seconds)
        with self._idle:
            self._idle_until = 0.0
        return stopped

    def _run(self) -> None:
        # The model, the rig and the app are loaded: keep them out of the cyclic collector's
        # full passes, whose pauses otherwise land inside ticks.
        gc.freeze()
        period = 1.0 / self.fps
        t0 = self._clock()
        k = 0
        while not self._stop.is_set():
            # Frame k is made as soon as frame k - 1 is out, and handed out when due: a tick
            # that takes longer than a period now and then uses the time the others left.
            start = self._clock()
            data: dict[int, bytes] | None = None
            ticked = start
            try:
                self._apply_pending(t0 + k * period)
                ticked = self._clock()
                data = self._tick(ticked - start)
            except Exception:
                # Nothing may end the stream: log it and go on with the next tick.
                log.exception("simulation tick failed")
            made = self._clock()
            own = made - ticked
            self._tick_guess = max(own, self._tick_guess + TICK_WEIGHT * (own - self._tick_guess))
            wait = t0 + k * period - made
            if wait > 0 and self._wait_due(made, wait):
                break
            if data:
                self.sink.frame(data)
            end = self._clock()
            with self._lock:
                self._steps.append(made - start)
                self._done.append(end)
                while self._done and self._done[0] < end - 1.0:
                    self._done.popleft()
                self.frames += 1
                self.late_frames += end > t0 + (k + 1) * period
            k += 1
            if end > t0 + (k + 1) * period:
                k = math.floor((end - t0) / period)

    def _tick(self, commands: float = 0.0) -> dict[int, bytes] | None:
        """Step and encode one frame (``commands``: seconds the commands took).

        Returns the frame's bytes in each layout some client asked for, for :meth:`_run` to
        hand out when it is due (``None``: nobody asked).
        """
        started = self._clock()
        cpu = 0.0
        wanted = self.sink.encodings()
        try:
            agents = len(self.engine)
            start = self._cpu()
            if getattr(self.engine, "partial_frames", False):
                # Float rotations and positions only for version-1 clients and recordings.
                frame = self.engine.step(full=1 in wanted or self.recorder.running)
            else:
                frame = self.engine.step()
            cpu = self._measure_step(agents, self._cpu() - start)
        except Exception:
            # A model failure must not end the stream: log it and serve the last frame again.
            log.exception("the engine failed to step; the scene holds its last frame")
            frame = self._last
        self._check_lost()
        self._take_crowd()
        for agent, path in getattr(self.engine, "take_paths", list)():
            if agent in self._agents:
                self._agents[agent].path = path
        self._last = frame
        data = None
        stepped = self._clock()
        number = self.frames
        va = self._valence_arousal(frame, number / self.fps)
        if wanted:
            movers = getattr(frame, "mover_positions", None)
            if movers is None:
                movers = frame.positions[:, self.engine.mover]
            scene = Frame(number, number / self.fps, np.asarray(frame.agents, dtype=np.int32),
                          va, frame.emotion, movers, frame.rotations, frame.world)
            codes = getattr(frame, "rotation_codes", None)
            data = {v: encode_frame(scene, v, codes if v == 2 else None) for v in sorted(wanted)}
        with self._lock:
            self._phases.append((commands, stepped - started, self._clock() - stepped, cpu))
        if self.recorder.running:
            for rec in self.recorder.capture(np.asarray(frame.agents, dtype=np.int32),
                                             frame.rotations, frame.positions):
                self.sink.notice(rec.owner, {
                    "type": "error", "message": (
                        f"recording {rec.rid} reached its limit of {rec.frames} frames; it "
                        "keeps those: send stop_recording to finish it")})
        return data

    def _measure_step(self, agents: int, seconds: float) -> float:
        """The step's processor time into the admission limit: the workers' own, if any.

        Returns the processor seconds of the slowest stepping engine.
        """
        costs = getattr(self.engine, "costs", None)
        if costs is None:
            self._measured(agents, seconds)
            return seconds
        for shard, (count, cpu) in costs.items():
            self._measured(count, cpu, shard)
        return max((cpu for _, cpu in costs.values()), default=0.0)

    def _check_lost(self) -> None:
        """Forget the agents of step workers lost since the last check, and tell everyone."""
        take = getattr(self.engine, "take_lost", None)
        for lost in (take() if take is not None else ()):
            self._costs.pop(lost.index, None)
            self._update_capacity()
            for agent in lost.agents:
                info = self._agents.pop(agent, None)
                if info is not None:
                    self._owned[info.owner] = self._owned.get(info.owner, 1) - 1
            self.lost_agents += len(lost.agents)
            self._emotions += 1
            shown = ", ".join(map(str, lost.agents[:20])) + (
                ", ..." if len(lost.agents) > 20 else "")
            self.sink.notice(None, {"type": "error", "message": (
                f"{lost.reason}; its {len(lost.agents)} agents left the scene ({shown}): add "
                "them again (the other workers go on), or restart the server")})

    def _valence_arousal(self, frame: GaitFrame, now: float) -> np.ndarray:
        """``(B, 2)`` each agent's valence and arousal at scene time ``now``.

        Agents of one emotion keep theirs: their rows are gathered again only when the
        frame's agents or an emotion changed (:attr:`_emotions`); schedules are interpolated
        each frame.
        """
        key = (self._emotions, frame.agents)
        if key != self._va_key:
            infos = [self._agents.get(agent) for agent in frame.agents]
            fixed = [None if info is None else info.constant_va for info in infos]
            self._va_base = np.array([NO_VA if f is None else f for f in fixed],
                                     dtype=np.float64).reshape(-1, 2)
            self._va_moving = [(k, info) for k, info in enumerate(infos)
                               if info is not None and fixed[k] is None]
            self._va_key = key
        va = self._va_base.copy()
        for k, info in self._va_moving:
            pts, times = info.schedule.points, info.schedule.times
            t = now - info.since
            va[k] = (np.interp(t, times, pts[:, 0]), np.interp(t, times, pts[:, 1]))
        self._va = va
        return va

    # ----------------------------------------------------------------------------- stats

    def stats(self) -> dict[str, Any]:
        """The scene's counters and times, as ``GET /api/stats`` reports them.

        ``frames``, ``late_frames``, ``fps`` (last second), ``step_ms`` p50/p99 (the whole
        tick), ``tick_ms`` (the p50 of its parts: commands, step and encoding in wall time,
        and ``step_cpu``, the processor time of the step, of the slowest worker), ``workers``
        (engines stepping: 1 in-process, else the live step workers) and ``lost_agents``.
        """
        with self._lock:
            steps = np.array(self._steps) * 1000.0
            phases = np.array(self._phases).reshape(-1, 4) * 1000.0
            fps = len(self._done)
            frames, late = self.frames, self.late_frames
        p50, p99 = (np.percentile(steps, [50, 99]) if len(steps) else (0.0, 0.0))
        parts = np.median(phases, axis=0) if len(phases) else np.zeros(4)
        return {"agents": len(self._agents), "capacity": self._capacity,
                "fps": float(fps), "frames": frames,
                "late_frames": late, "step_ms": {"p50": round(float(p50), 3),
                                                 "p99": round(float(p99), 3)},
                "tick_ms": {name: round(float(v), 3) for name, v in
                            zip(("commands", "step", "encode", "step_cpu"), parts,
                                strict=True)},
                "workers": len(getattr(self.engine, "live", lambda: [None])()),
                "lost_agents": self.lost_agents}


def error_text(exc: BaseException) -> str:
    """The ``error`` reply's message for an exception raised while handling a message."""
    if isinstance(exc, EmotiveError | ValueError):
        return " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, KeyError):
        return str(exc.args[0]) if exc.args else "unknown key"
    log.error("internal error handling a message", exc_info=exc)
    return f"internal error ({type(exc).__name__}); the message was not applied"
