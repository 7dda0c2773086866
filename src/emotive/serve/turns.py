"""Fair turns on the simulation thread: each client's commands in order, one at a time.

Commands reach the simulation thread from every client through one queue; here they wait per
client (:class:`Turns`), in the order the client sent them, with the client's work budget
(:class:`~emotive.serve.limits.WorkBudget`: seconds of the server's work per second of scene
time). The thread takes them in turns, the head of one client after the other
(:meth:`Turns.next_command`), and skips a client whose budget is overdrawn: its commands wait
until the budget refills with scene time, and nobody else's do.

New agents are the costly command: each batch of them warms up the network (12-19 ms for 1-32
gait agents on the 2-core development machine, idle; several times that on a loaded one). A
client's ``add_agent`` waits at the head of its queue, and its later commands behind it,
until it joins. :meth:`Turns.joins` takes a batch, one waiting agent of each client a round,
and :class:`JoinCosts` estimates what a batch of ``n`` costs from the batches so far, so that
the simulation thread joins only as many as fit in the time its tick has to spare.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future
from dataclasses import dataclass

from emotive.serve.limits import WorkBudget
from emotive.serve.messages import Command

#: Agents whose warm-up costs as much again as one agent's (a batch of ``n`` costs
#: ``(1 + n / JOIN_SCALE)`` times one agent's: 12.6 ms for 1, 18.6 ms for 32, measured).
JOIN_SCALE = 64.0
#: First guess of one agent's join, seconds (before any was measured).
FIRST_JOIN = 0.015
#: Weight of a new measurement in the join estimate.
JOIN_WEIGHT = 0.3


@dataclass
class Pending:
    """One command waiting for the simulation thread.

    Attributes:
        command: the prepared command.
        client: its connection number (-1: the HTTP API or the server itself).
        future: where its reply goes.
        budget: its client's work budget (``None``: not charged, never waits).
    """

    command: Command
    client: int
    future: Future
    budget: WorkBudget | None = None

    @property
    def joins(self) -> bool:
        """Whether it adds an agent."""
        return self.command.kind == "add_agent"

    def allowed(self) -> bool:
        """Whether its client's budget lets it run now."""
        return self.budget is None or self.budget.allowed()

    def charge(self, seconds: float) -> None:
        """Charge its client ``seconds`` of the simulation thread's time."""
        if self.budget is not None:
            self.budget.charge(seconds)


class Turns:
    """Every client's waiting commands, taken in turns (simulation thread only)."""

    def __init__(self) -> None:
        self._queues: dict[int, deque[Pending]] = {}
        #: Clients with commands, the next to serve first.
        self._ring: deque[int] = deque()

    def __len__(self) -> int:
        return sum(len(q) for q in self._queues.values())

    def __iter__(self) -> Iterator[Pending]:
        for queue in self._queues.values():
            yield from queue

    def clear(self) -> None:
        """Forget every waiting command."""
        self._queues.clear()
        self._ring.clear()

    def put(self, item: Pending) -> None:
        """Queue a command behind its client's earlier ones."""
        queue = self._queues.get(item.client)
        if queue is None:
            queue = self._queues[item.client] = deque()
            self._ring.append(item.client)
        queue.append(item)

    def _pop(self, client: int) -> Pending:
        queue = self._queues[client]
        item = queue.popleft()
        if not queue:
            del self._queues[client]
            self._ring.remove(client)
        return item

    def next_command(self) -> Pending | None:
        """The next command to apply, or ``None``.

        The head of the next client in turn that is not an ``add_agent`` and whose budget
        allows it; that client then goes to the end of the turn.
        """
        for _ in range(len(self._ring)):
            client = self._ring[0]
            self._ring.rotate(-1)
            head = self._queues[client][0]
            if not head.joins and head.allowed():
                return self._pop(client)
        return None

    def joining(self) -> bool:
        """Whether some client's next command is an ``add_agent`` it may run now."""
        return any(q[0].joins and q[0].allowed() for q in self._queues.values())

    def joins(self, limit: int) -> list[Pending]:
        """Up to ``limit`` ``add_agent`` commands, one of each client a round, in turn.

        A client gives its waiting ``add_agent`` commands in order, up to the first other
        command; one whose budget is overdrawn gives none.
        """
        batch: list[Pending] = []
        while len(batch) < limit:
            ready = [c for c in self._ring
                     if self._queues[c][0].joins and self._queues[c][0].allowed()]
            if not ready:
                break
            for client in ready[:limit - len(batch)]:
                batch.append(self._pop(client))
                if client in self._queues:  # to the end of the turn
                    self._ring.remove(client)
                    self._ring.append(client)
        return batch


class JoinCosts:
    """Seconds a batch of new agents takes to join, learned from the batches so far.

    A batch of ``n`` is taken to cost ``base * (1 + n / JOIN_SCALE)``; ``base`` follows the
    measured batches (wall time on the simulation thread: what delays the frame).

    Args:
        base: the first guess of one agent's join, seconds.
    """

    def __init__(self, base: float = FIRST_JOIN) -> None:
        self.base = float(base)

    def estimate(self, agents: int) -> float:
        """Expected seconds of a batch of ``agents``."""
        return self.base * (1.0 + agents / JOIN_SCALE)

    def fitting(self, seconds: float, limit: int) -> int:
        """The most agents (at most ``limit``) expected to join within ``seconds``; 0: none."""
        if self.estimate(1) > seconds:
            return 0
        return int(min(limit, (seconds / self.base - 1.0) * JOIN_SCALE))

    def measured(self, agents: int, seconds: float) -> None:
        """Take a batch of ``agents`` that took ``seconds`` into the estimate."""
        one = seconds / (1.0 + agents / JOIN_SCALE)
        self.base += JOIN_WEIGHT * (one - self.base)


def share(items: list[Pending], seconds: float) -> None:
    """Charge each item's client its share of ``seconds`` of a batch (split evenly)."""
    for item in items:
        item.charge(seconds / len(items))
