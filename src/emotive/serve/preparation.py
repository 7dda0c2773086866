"""Preparing control messages off the event loop and off the simulation thread.

Parsing a large message, checking its fields and building its path or schedule
(:func:`~emotive.serve.limits.parse_message`, :func:`~emotive.serve.messages.to_command`)
takes milliseconds; on the event loop it would hold up every client's frames, on the
simulation thread the scene's clock. Here each client has a :class:`Lane`: a queue of at most
``queued_messages`` messages and ``queued_megabytes`` MB (its session reads no more of the
client's messages while the lane is full, so a flood waits in the client's own socket) and a
:class:`~emotive.serve.limits.WorkBudget` of ``work_per_second`` seconds of the server's work
per second of *scene* time (frame number / fps): its messages' preparation (thread time) and
what its commands then cost the simulation thread (:mod:`~emotive.serve.commands`: a share of
each batch of new agents it joins, each other command's time), so that a client's share of
the scene's time stays the same when a busy machine slows the scene. While the budget is
overdrawn the client's messages are refused (an ``error`` reply) and its commands already
prepared wait; nobody else's do. One :class:`Preparer` task on the event loop takes one
message from each non-empty lane in turn and prepares it in one worker thread; the
simulation thread receives only finished :class:`~emotive.serve.messages.Command` objects.

The worker shares the interpreter with the simulation thread, and preparing holds the
interpreter lock: a 256-keyframe schedule takes 30 ms of it, during which every tensor
operation of a tick that gives the lock up waits to take it back. So the worker prepares a
message expected to take more than :data:`GATE_MIN` while the simulation thread waits for
its next frame's due time: when that wait has the time the client's messages took lately
left, else from the start of the next wait
(:meth:`~emotive.serve.simulation.Simulation.wait_spare`; a message waits :data:`PATIENCE`
frame periods at most, for a scene that is late, with no waits), and it works at most
:data:`DUTY` of wall time (thread time measured per message, then a pause). No single step
of a message is long: every message is small enough by its limits (size, values, points,
keyframes) to be prepared within a frame.
``add_agent`` beyond a client's ``max_agents_per_client`` (those it has in the scene and those
on their way) is refused before its path is built.
"""

from __future__ import annotations

import asyncio
import ctypes
import logging
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from emotive.serve.errors import NO_REF, MessageError
from emotive.serve.hub import Outbox
from emotive.serve.limits import WorkBudget, head_ref, parse_message
from emotive.serve.messages import to_command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation, error_text

log = logging.getLogger("emotive.serve")

#: The largest share of wall time the worker thread spends preparing messages.
DUTY = 0.2
#: Seconds of pause owed before the preparer takes it (shorter pauses add up first).
MIN_PAUSE = 0.005
#: Seconds of preparation each lane's share grows by per turn.
QUANTUM = 0.005
#: Most messages one lane gives per turn.
ROUND_ITEMS = 8
#: Frame periods a message waits at most for the simulation thread to wait for a due time.
PATIENCE = 4
#: Seconds a lane's messages are expected to take from which they wait for spare time
#: (a shorter one hardly lengthens a tick it runs beside).
GATE_MIN = 0.002
#: Weight of a message's cost in its lane's expected cost, when lower (higher: taken at once).
EXPECT_WEIGHT = 0.2


#: Bytes of messages prepared after which the worker, once every lane is empty, hands the
#: freed memory back to the system.
TRIM_AFTER = 4_000_000


def _malloc_trim() -> Callable[[int], int] | None:
    """The C library's ``malloc_trim`` (glibc), or ``None`` where it has none.

    Parsing a large message makes many short-lived objects; glibc keeps the memory they
    freed inside its heap, where it counts in the server's resident size, until it is
    trimmed.
    """
    try:
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return None


def work_refusal(settings: ServeSettings) -> str:
    """The ``error`` reply's text for a message refused while its client's budget is overdrawn."""
    return (f"too much work: your messages may cost {1000 * settings.work_per_second:g} ms of "
            "the server's time per second of scene time, and the last ones cost more; this one "
            "was not applied: send fewer or smaller messages, or wait a moment")


def error_reply(message: str, ref: Any = NO_REF) -> dict[str, Any]:
    """``{"type": "error", "message": ..., "ref": ...}`` (``ref`` only when the message had it)."""
    return with_ref({"type": "error", "message": message}, ref)


def with_ref(reply: dict[str, Any], ref: Any) -> dict[str, Any]:
    """``reply`` with ``"ref"`` set, unless ``ref`` is :data:`~emotive.serve.errors.NO_REF`."""
    if ref is not NO_REF:
        reply["ref"] = ref
    return reply


def pong(message: dict[str, Any]) -> dict[str, Any]:
    """The reply to a parsed ``ping`` (without its ``ref``).

    Raises:
        MessageError: a field other than ``t``.
    """
    unknown = set(message) - {"type", "ref", "t"}
    if unknown:
        raise MessageError(f"ping has no field {', '.join(sorted(map(str, unknown)))}; its "
                           "fields: t")
    return {"type": "pong", "t": message.get("t"), "server_time": time.time()}


@dataclass
class Lane:
    """One client's messages waiting for preparation.

    Attributes:
        client: the connection number.
        box: its outbox (where the replies go).
        budget: its seconds of preparation.
        items: ``(message, size)``: a parsed object, or text still to be parsed; bytes.
        size: bytes waiting.
        adding: its ``add_agent`` commands prepared and not yet answered.
        share: its share of preparation time, seconds (see :meth:`Preparer._round`).
        mean_cost: the mean cost of its messages so far, seconds of thread time.
        expected: what its next message is expected to cost, seconds: its costs lately,
            a higher one taken at once (the spare time the worker waits for).
    """

    client: int
    box: Outbox
    budget: WorkBudget
    items: deque[tuple[dict[str, Any] | str, int]] = field(default_factory=deque)
    size: int = 0
    adding: int = 0
    share: float = 0.0
    mean_cost: float = 0.001
    expected: float = 0.001
    _room: asyncio.Event = field(default_factory=asyncio.Event)


class Preparer:
    """Every client's lane, the turn-taking task and the worker thread.

    Args:
        sim: the scene (commands go to :meth:`Simulation.submit`).
        settings: the queue, work and quota limits.
        clock: thread time, seconds (the cost charged to a client).
    """

    def __init__(self, sim: Simulation, settings: ServeSettings,
                 clock: Callable[[], float] = time.thread_time) -> None:
        self.sim = sim
        self.settings = settings
        self._clock = clock
        self._lanes: dict[int, Lane] = {}
        self._work = asyncio.Event()
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="emotive-prepare")
        self._task: asyncio.Task | None = None
        self._trim = _malloc_trim()
        self._untrimmed = 0
        self._turn = 0

    # --------------------------------------------------------------------- event loop side

    def start(self) -> None:
        """Start the turn-taking task (on the running event loop)."""
        self._task = asyncio.get_running_loop().create_task(self._run())

    async def stop(self) -> None:
        """Stop the task and the worker thread."""
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        self._pool.shutdown(wait=False, cancel_futures=True)

    def open(self, box: Outbox) -> Lane:
        """A new client's lane."""
        s = self.settings
        lane = Lane(box.client, box, WorkBudget(s.work_per_second, s.work_burst,
                                                self.sim.scene_time))
        self._lanes[box.client] = lane
        return lane

    def close(self, lane: Lane) -> None:
        """Forget a client's lane and what waits in it."""
        self._lanes.pop(lane.client, None)
        lane.items.clear()

    def full(self, lane: Lane) -> bool:
        """Whether the lane holds ``queued_messages`` messages or ``queued_megabytes`` MB."""
        s = self.settings
        return (len(lane.items) >= s.queued_messages
                or lane.size >= s.queued_megabytes * 1e6)

    async def put(self, lane: Lane, message: dict[str, Any] | str, size: int) -> None:
        """Queue a message (parsed, or text), first waiting while the lane is full."""
        while self.full(lane):
            lane._room.clear()
            await lane._room.wait()
        lane.items.append((message, size))
        lane.size += size
        self._untrimmed += size
        self._work.set()

    def _round(self) -> list[tuple[Lane, dict[str, Any] | str]]:
        """One turn of the lanes with messages: each takes what its share of time allows.

        A lane whose budget is overdrawn has its messages refused. Deficit round robin on
        preparation time for the others: every turn adds :data:`QUANTUM` seconds to a lane's
        share (up to :data:`ROUND_ITEMS` quanta); a lane gives messages while its share, less
        the expected cost of each (its mean so far), stays positive, and at most
        :data:`ROUND_ITEMS`. So a client of cheap messages is not held up by one of costly
        messages, which waits turns until its share pays for one. A turn ends once its
        messages are expected to take a frame period (the lanes take turns to go first), so
        that refusals and the others' messages do not wait behind a long batch.
        """
        lanes = [lane for lane in self._lanes.values() if lane.items]
        for lane in lanes:
            while lane.items and not lane.budget.allowed():
                message, size = lane.items.popleft()
                lane.size -= size
                lane._room.set()
                self._refuse_work(lane, message)
        if lanes:
            self._turn = (self._turn + 1) % len(lanes)
            lanes = lanes[self._turn:] + lanes[:self._turn]
        batch: list[tuple[Lane, dict[str, Any] | str]] = []
        expected = 0.0
        for lane in lanes:
            if expected >= 1.0 / self.sim.fps:
                break
            lane.share = min(lane.share + QUANTUM, QUANTUM * ROUND_ITEMS)
            taken = 0
            while lane.items and lane.share > 0.0 and taken < ROUND_ITEMS:
                message, size = lane.items.popleft()
                lane.size -= size
                lane._room.set()
                lane.share -= lane.mean_cost
                expected += lane.expected
                batch.append((lane, message))
                taken += 1
        return batch

    def _refuse_work(self, lane: Lane, message: dict[str, Any] | str) -> None:
        s = self.settings
        ref = message.get("ref", NO_REF) if isinstance(message, dict) else head_ref(message)
        lane.box.put_reply(error_reply(work_refusal(s), ref))

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        owed = 0.0
        while True:
            batch = self._round()
            if not batch:
                if any(lane.items for lane in self._lanes.values()):
                    await asyncio.sleep(0)
                    continue
                if self._trim is not None and self._untrimmed >= TRIM_AFTER:
                    self._untrimmed = 0
                    await loop.run_in_executor(self._pool, self._trim, 0)
                self._work.clear()
                await self._work.wait()
                continue
            try:
                results = await loop.run_in_executor(self._pool, self._prepare_all, batch)
            except Exception:
                # Nothing may end the preparer: log it and go on with the next messages.
                log.exception("preparing control messages failed")
                continue
            spent = 0.0
            for (lane, _), (result, ref, cost) in zip(batch, results, strict=True):
                spent += cost
                lane.share += lane.mean_cost - cost
                lane.mean_cost += 0.2 * (cost - lane.mean_cost)
                lane.expected = max(cost, lane.expected + EXPECT_WEIGHT * (cost - lane.expected))
                lane.budget.charge(cost)
                self._answer(lane, result, ref)
            owed += spent * (1.0 / DUTY - 1.0)
            if owed >= MIN_PAUSE:
                await asyncio.sleep(owed)
                owed = 0.0

    def _answer(self, lane: Lane, result: Any, ref: Any) -> None:
        if isinstance(result, BaseException):
            lane.box.put_reply(error_reply(error_text(result), ref))
            return
        if isinstance(result, dict):
            lane.box.put_reply(with_ref(result, ref))
            return
        adding = result.kind == "add_agent"
        future = self.sim.submit(result, lane.client, lane.budget)
        if adding:
            lane.adding += 1

        def done(f: asyncio.Future | Future) -> None:
            if adding:
                lane.adding -= 1
            if f.cancelled():
                return
            exc = f.exception()
            reply = error_reply(error_text(exc)) if exc is not None else dict(f.result())
            lane.box.put_reply(with_ref(reply, ref))

        asyncio.wrap_future(future).add_done_callback(done)

    # --------------------------------------------------------------------- worker thread

    def _prepare_all(self, batch: list[tuple[Lane, dict[str, Any] | str]]
                     ) -> list[tuple[Any, Any, float]]:
        return [self._prepare(lane, message) for lane, message in batch]

    def _prepare(self, lane: Lane, message: dict[str, Any] | str
                 ) -> tuple[Any, Any, float]:
        """``(command or exception, ref, thread seconds)`` of one message (worker thread).

        Waits first for time the simulation thread has to spare (see the module docstring).
        """
        if lane.expected >= GATE_MIN:
            self.sim.wait_spare(lane.expected, PATIENCE / self.sim.fps)
        start = self._clock()
        s = self.settings
        ref = NO_REF
        try:
            if isinstance(message, str):
                message = parse_message(message, s.max_message_bytes, s.max_depth,
                                        s.max_values)
            ref = message.get("ref", NO_REF)
            if message["type"] == "ping":
                return pong(message), ref, self._clock() - start
            if message["type"] == "add_agent":
                self.check_quota(lane)
            result: Any = to_command(message, self.sim.engine.labels,
                                     self.sim.engine.points_over)
        except Exception as exc:  # every failure becomes this message's error reply
            result = exc
            if isinstance(exc, MessageError) and exc.ref is not NO_REF:
                ref = exc.ref
        return result, ref, self._clock() - start

    def check_quota(self, lane: Lane) -> None:
        """Refuse an ``add_agent`` of a client that has its quota in the scene or on the way.

        Raises:
            MessageError: naming ``--max-agents-per-client``.
        """
        quota = self.settings.max_agents_per_client
        have = self.sim.owned(lane.client) + lane.adding
        if have >= quota:
            raise MessageError(
                f"you have {have} agents in the scene or on their way, the limit per client "
                f"(--max-agents-per-client {quota}): remove some of yours first")
