"""The simulation thread: it alone owns the engine, and steps it on a fixed clock.

Tick ``k`` is due at ``t0 + k / fps``; its frame is made as soon as the frame before it is
handed out, and handed out when due, so that a tick that takes longer than a period now and
then uses the time the others left. For each frame the thread applies the commands that
arrived since the last one, all prepared off this thread
(:mod:`~emotive.serve.preparation`); new agents join in one batched call (so a hundred new
agents cost one warm-up of the network) of at most :data:`JOIN_PER_TICK`, the others (and
the later commands of their clients, which stay in order) at the next ticks. It then steps
the engine (its own, or the step worker processes of
:class:`~emotive.serve.workers.ShardedEngine`), encodes the frame once in each layout some
client asked for (:func:`~emotive.serve.frames.encode_frame`), hands the bytes to the
:class:`Sink` (which fans them out to the clients without waiting for any) and feeds the
running recordings. A frame handed out after the next tick was due counts as late; when the
thread falls more than a frame behind it skips the missed ticks instead of bursting to catch
up, so scene time (frame number / fps) then runs behind wall time.

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

import contextlib
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
from emotive.serve.capacity import StepCosts
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
#: Share of the frame period the engine's step may take with every agent the scene admits,
#: unless ``--step-budget`` says otherwise.
STEP_BUDGET = ServeSettings.step_budget
#: Valence and arousal of an agent the scene no longer knows.
_NO_VA = (0.0, 0.0)


class Sink(Protocol):
    """Where the simulation thread sends what it makes; every call must return at once."""

    def encodings(self) -> frozenset[int]:
        """The frame layouts (versions) some client asked for now."""

    def frame(self, data: dict[int, bytes]) -> None:
        """One frame for every client, encoded in each layout of :meth:`encodings`."""

    def notice(self, client: int | None, message: dict[str, Any]) -> None:
        """A message for one client (e.g. its recording reached its limit); ``None``: all."""


@dataclass
class _Agent:
    """What the server knows of an agent beside the engine."""

    path: GroundPath
    schedule: EmotionSchedule
    since: float
    pace: float
    owner: int = -1
    #: Its valence and arousal when its schedule holds one emotion, else ``None``.
    constant_va: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        self.set_schedule(self.schedule, self.since)

    def set_schedule(self, schedule: EmotionSchedule, since: float) -> None:
        """A new emotion schedule, its time 0 at scene time ``since``."""
        self.schedule, self.since = schedule, since
        if schedule is None:  # no emotion known (a stand-in in tests): neutral
            self.constant_va = _NO_VA
            return
        pts = schedule.points
        self.constant_va = ((float(pts[0, 0]), float(pts[0, 1])) if len(schedule.times) == 1
                            else None)


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
        #: Counts changes of the agents' emotions (the valence/arousal rows are kept until).
        self._emotions = 0
        self._va_key: tuple | None = None
        self._va_base = np.zeros((0, 2))
        self._va_moving: list[tuple[int, _Agent]] = []
        self.recorder = Recorder(settings.recording_seconds * self.fps,
                                 settings.recording_megabytes * 1e6, settings.kept_recordings)
        self._lock = threading.Lock()
        self._steps: deque[float] = deque(maxlen=STEP_WINDOW)
        self._pending: deque[tuple[Command, int, Future]] = deque()
        self._owned: dict[int, int] = {}
        self._costs: dict[int, StepCosts] = {}
        self._capacity = settings.max_agents
        self._done: deque[float] = deque()
        self._phases: deque[tuple[float, float, float, float]] = deque(maxlen=STEP_WINDOW)
        self.frames = 0
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
            # Frame k is made as soon as frame k - 1 is out, and handed out when due: a tick
            # that takes longer than a period now and then uses the time the others left.
            start = self._clock()
            data: dict[int, bytes] | None = None
            try:
                self._apply_pending()
                data = self._tick(self._clock() - start)
            except Exception:
                # Nothing may end the stream: log it and go on with the next tick.
                log.exception("simulation tick failed")
            made = self._clock()
            wait = t0 + k * period - made
            if wait > 0 and self._stop.wait(wait):
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
            self._va_base = np.array([_NO_VA if f is None else f for f in fixed],
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

    # ----------------------------------------------------------------------------- commands

    def owned(self, client: int) -> int:
        """Agents client ``client`` has in the scene (any thread: a read of one number)."""
        return self._owned.get(client, 0)

    def capacity(self) -> int:
        """Agents the scene admits now: ``max_agents``, or fewer by the measured step time."""
        return self._capacity

    def _measured(self, agents: int, seconds: float, shard: int = 0) -> None:
        """Take one step's time (of the engine stepping part ``shard``) into the limit."""
        costs = self._costs.get(shard)
        if costs is None:
            costs = self._costs[shard] = StepCosts(self.settings.step_budget / self.fps,
                                                   self.settings.max_agents)
        costs.measured(agents, seconds)
        self._update_capacity()

    def _update_capacity(self) -> None:
        limits = sum(c.limit for c in self._costs.values())
        self._capacity = min(self.settings.max_agents, limits) if self._costs else (
            self.settings.max_agents)

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
        self._check_lost()

    def _apply(self, command: Command, client: int, future: Future) -> None:
        try:
            reply = self._reply(command, client)
        except Exception as exc:  # every failure becomes this message's error reply
            future.set_exception(exc)
        else:
            future.set_result(reply)
        self._check_lost()

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
            f"{100 * s.step_budget:.0f} % of a {1000 / self.fps:.1f} ms frame by its measured "
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
            self._emotions += 1
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
            self._emotions += 1
            self._owned[info.owner] = self._owned.get(info.owner, 1) - 1
        elif kind == "set_emotion":
            self.engine.set_emotion(agent, value)
            info.set_schedule(value, self.frames / self.fps)
            self._emotions += 1
        elif kind == "set_path":
            self.engine.set_path(agent, value)
            info.path = value
        elif kind == "set_target":
            path = self.engine.set_target(agent, value)
            if path is not None:  # step workers answer with it later (_tick)
                info.path = path
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
        worker_of = getattr(self.engine, "worker_of", None)
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
            if worker_of is not None:
                with contextlib.suppress(KeyError):  # its worker was just lost
                    out[-1]["worker"] = worker_of(agent)
        return out

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
