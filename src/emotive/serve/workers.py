"""The scene's agents split over step workers: :class:`ShardedEngine`.

With ``--workers N`` (N > 1) the simulation thread does not step the engine itself: it
drives ``N`` workers (:mod:`~emotive.serve.shards`: threads of the server's process, or
processes of :mod:`~emotive.serve.worker_process`), each with its own engine stepping its
share of the agents, so that the scene's step runs on ``N`` cores. :class:`ShardedEngine` has
the surface of :class:`~emotive.serve.engines.Engine`, so the simulation thread's clock,
admission, commands, recordings and stats are the same as with one in-process engine:

* new agents go to the workers with the fewest agents (a batch is split between them, and
  they warm it up at once); the server numbers agents itself (ids unique across workers)
  and remembers which worker steps each, so a command goes to its owner only, and without
  waiting (``post``: the worker applies it before its next step, and ``set_target``'s new
  path comes back with that answer, :meth:`ShardedEngine.take_paths`); only adding agents
  waits for the workers' ids;
* a tick asks every worker to step; each steps and writes its frame into its block
  (:class:`~emotive.serve.worker_process.FrameBlock`), rotations already coded for the
  compact frame; the server joins the blocks into one frame (:class:`ShardFrame`), agents in
  worker order, float rotations and positions only when asked (``full``);
* each worker reports its step's processor time, so the admission limit is fitted per
  worker (:attr:`ShardedEngine.costs`).

A worker process that dies (killed, out of memory), or a worker that does not answer within
:data:`~emotive.serve.shards.CALL_TIMEOUT`, is stopped and *lost*: its agents leave the
scene, the frame goes on with the others, and :meth:`ShardedEngine.take_lost` tells the
simulation thread which agents went, so that every client gets a notice.
:meth:`ShardedEngine.close` stops every worker (processes: ``stop``, then terminate and kill
after :data:`~emotive.serve.shards.STOP_TIMEOUT`) and frees their blocks: no process outlives
the server.

Legend: ``B`` agents, ``J`` joints, ``P`` points, ``C`` emotion labels.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from emotive.data.emotion import EmotionSchedule
from emotive.paths import GroundPath
from emotive.serve.engines import Engine
from emotive.serve.errors import MessageError
from emotive.serve.shards import Shard, StepWorker, ThreadWorker, WorkerLost
from emotive.serve.worker_process import WorkerSpec

log = logging.getLogger("emotive.serve")


class ShardFrame(NamedTuple):
    """One frame of the whole scene, joined from the workers' blocks.

    The fields of :class:`~emotive.models.gait.generate.GaitFrame` (``float32``; without
    ``full``, ``rotations``, ``positions`` and ``world`` are ``None``), the mover joints'
    world positions ``(B, 3)`` and the rotations' smallest-three codes ``(B, J, 3)``
    (:mod:`~emotive.serve.quantize`).
    """

    agents: tuple[int, ...]
    rotations: np.ndarray | None
    positions: np.ndarray | None
    world: np.ndarray | None
    emotion: np.ndarray
    root: np.ndarray
    mover_positions: np.ndarray
    rotation_codes: np.ndarray


@dataclass
class Lost:
    """A worker that was lost: its number, why, and the ids of the agents it took along."""

    index: int
    reason: str
    agents: list[int]


class ShardedEngine:
    """An :class:`~emotive.serve.engines.Engine` whose agents are stepped by workers.

    Args:
        engine: the server's own engine of the same model and backend (its rig, labels and
            mannequin; it steps nothing here).
        workers: number of workers (at least 2).
        rows: agents one worker can hold (``--max-agents``: after a loss one may hold all).
        seed: seed of the agents' starting phases (worker ``k`` draws from ``seed + k``).
        threads: workers are threads of this process (:class:`ThreadWorker`) instead of
            processes (:class:`StepWorker`).

    Raises:
        ServeError: a worker failed to start (the others are stopped).
    """

    def __init__(self, engine: Engine, workers: int, rows: int, seed: int = 0,
                 threads: bool = False) -> None:
        self.meta = engine
        self.skeleton = engine.skeleton
        self.mover = engine.mover
        self.rest = engine.rest
        self.model = engine.model
        self.backend = engine.backend
        self.labels = engine.labels
        self.points_over = engine.points_over
        self.fps = engine.fps
        j = engine.skeleton.num_joints
        self._shape = (j, j + len(engine.skeleton.end_site_parents), len(engine.labels))
        kind = ThreadWorker if threads else StepWorker
        self.workers: list[Shard] = []
        #: The worker stepping each agent, and the agent's id there, by scene id.
        self._owner: dict[int, tuple[Shard, int]] = {}
        self._next = 0
        self._lost: list[Lost] = []
        self._paths: list[tuple[int, GroundPath]] = []
        #: ``(agents, processor seconds)`` of each live worker's last step, by its number.
        self.costs: dict[int, tuple[int, float]] = {}
        try:
            for k in range(workers):
                self.workers.append(kind(WorkerSpec(
                    k, engine.model, engine.backend, seed + k, max(int(rows), 1),
                    *self._shape)))
            for worker in self.workers:
                worker.started()
        except BaseException:
            self.close()
            raise

    # ------------------------------------------------------------------------- the scene

    def __len__(self) -> int:
        return len(self._owner)

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents."""
        return tuple(self._owner)

    def worker_of(self, agent: int) -> int:
        """The number of the worker stepping ``agent`` (``KeyError``: no such agent)."""
        return self._owner[agent][0].index

    def live(self) -> list[Shard]:
        """The workers still running."""
        return [w for w in self.workers if w.alive]

    def take_lost(self) -> list[Lost]:
        """The workers lost since the last call (and the agents they took along)."""
        lost, self._lost = self._lost, []
        return lost

    def _lose(self, worker: Shard, exc: BaseException) -> None:
        worker.kill()
        agents = sorted(worker.globals.values())
        for agent in agents:
            self._owner.pop(agent, None)
        worker.globals.clear()
        log.error("%s; its %d agents left the scene", exc, len(agents))
        self._lost.append(Lost(worker.index, str(exc), agents))

    # ------------------------------------------------------------------------- commands

    def add_agents(self, paths: Sequence[GroundPath], schedules: Sequence[EmotionSchedule],
                   starts: Sequence[float], paces: Sequence[float]) -> list[int]:
        """Add agents, spread over the workers with the fewest; returns their scene ids.

        All or nothing: when one worker refuses its share, the others' are removed again
        and its error is raised.

        Raises:
            MessageError: no worker is running.
        """
        live = self.live()
        if not live:
            raise MessageError("every step worker of the server stopped, so it can step no "
                               "agents: restart the server (see its log for why)")
        counts = {w.index: len(w) for w in live}
        share: dict[int, list[int]] = {w.index: [] for w in live}
        for k in range(len(paths)):
            index = min(counts, key=lambda i: (counts[i], i))
            share[index].append(k)
            counts[index] += 1
        asked = [(w, share[w.index]) for w in live if share[w.index]]
        answers: list[tuple[Shard, list[int], Any]] = []
        for worker, rows in asked:
            try:
                worker.send("add_agents", [paths[k] for k in rows],
                            [schedules[k] for k in rows], [starts[k] for k in rows],
                            [paces[k] for k in rows])
            except WorkerLost as exc:
                self._lose(worker, exc)
                answers.append((worker, rows, exc))
        for worker, rows in asked:
            if not worker.alive:
                continue
            try:
                answers.append((worker, rows, worker.receive()))
            except WorkerLost as exc:
                self._lose(worker, exc)
                answers.append((worker, rows, exc))
            except Exception as exc:  # the whole batch fails with it
                answers.append((worker, rows, exc))
        failure = next((a for _, _, a in answers if isinstance(a, BaseException)), None)
        if failure is not None:
            for worker, _, local in answers:
                if worker.alive and not isinstance(local, BaseException):
                    for agent in local:
                        self._call(worker, "remove_agent", agent)
            raise failure
        ids = list(range(self._next, self._next + len(paths)))
        self._next += len(paths)
        for worker, rows, local in answers:
            worker.adopt(local, [ids[k] for k in rows])
            for a, k in zip(local, rows, strict=True):
                self._owner[ids[k]] = (worker, int(a))
        return ids

    def _call(self, worker: Shard, op: str, *args: Any) -> Any:
        try:
            return worker.call(op, *args)
        except WorkerLost as exc:
            self._lose(worker, exc)
            raise

    def _post(self, op: str, agent: int, *args: Any,
              then: Callable[[Any], None] | None = None) -> None:
        """Post a request about ``agent`` to its worker (answered before its next step)."""
        if agent not in self._owner:
            raise KeyError(f"no live agent with id {agent}")
        worker, local = self._owner[agent]
        try:
            worker.post(op, local, *args, then=then)
        except WorkerLost as exc:
            self._lose(worker, exc)
            raise
        if op == "remove_agent":
            del self._owner[agent]
            del worker.globals[local]

    def remove_agent(self, agent: int) -> None:
        """Remove an agent (``KeyError``: no such agent)."""
        self._post("remove_agent", agent)

    def set_emotion(self, agent: int, schedule: EmotionSchedule) -> None:
        """Give an agent a new emotion or schedule, its time 0 now."""
        self._post("set_emotion", agent, schedule)

    def set_path(self, agent: int, path: GroundPath) -> None:
        """Send an agent along another path from its nearest point."""
        self._post("set_path", agent, path)

    def set_target(self, agent: int, xz: Sequence[float]) -> None:
        """Send an agent to a ground point ``(x, z)``.

        The path it then follows is made by its worker; it comes with the worker's next
        answer, in :meth:`take_paths`. Returns ``None`` (an in-process engine returns the
        path at once).
        """
        self._post("set_target", agent, np.asarray(xz, dtype=np.float64),
                   then=lambda path: self._paths.append((agent, path)))

    def set_pace(self, agent: int, pace: float) -> None:
        """Walk an agent faster or slower than its emotion does."""
        self._post("set_pace", agent, pace)

    def take_paths(self) -> list[tuple[int, GroundPath]]:
        """``(agent, path)`` of each ``set_target`` answered since the last call."""
        paths, self._paths = self._paths, []
        return paths

    # ------------------------------------------------------------------------- stepping

    #: :meth:`step` takes ``full``: the simulation thread asks for what it needs.
    partial_frames = True

    def step(self, full: bool = True) -> ShardFrame:
        """Step every worker at once and join their frames (a lost worker's agents are gone).

        Args:
            full: join the float rotations, local translations and world positions too
                (version-1 frames, recordings); else only what version-2 frames need.
        """
        stepping = []
        for worker in self.live():
            try:
                worker.send("step", full)
                stepping.append((worker, len(worker)))
            except WorkerLost as exc:
                self._lose(worker, exc)
        parts: list[tuple[Shard, int]] = []
        costs = {}
        for worker, agents in stepping:
            try:
                rows, seconds = worker.receive()
            except WorkerLost as exc:
                self._lose(worker, exc)
                continue
            parts.append((worker, rows))
            costs[worker.index] = (agents, seconds)
        self.costs = costs
        return self._joined(parts, full)

    def _joined(self, parts: list[tuple[Shard, int]], full: bool) -> ShardFrame:
        """One frame of the first ``rows`` rows of each worker's block."""
        if not parts:
            j, p, c = self._shape
            return ShardFrame((), np.zeros((0, j, 4), np.float32), np.zeros((0, j, 3), np.float32),
                              np.zeros((0, p, 3), np.float32), np.zeros((0, c), np.float32),
                              np.zeros((0, 2), np.float32), np.zeros((0, 3), np.float32),
                              np.zeros((0, j, 3), np.uint16))
        ids = np.concatenate([w.scene_ids(w.block.ids[:n]) for w, n in parts])

        def joined(name: str) -> np.ndarray:
            return np.concatenate([getattr(w.block, name)[:n] for w, n in parts])

        floats = [joined(n) if full else None for n in ("rotations", "positions", "world")]
        return ShardFrame(tuple(ids.tolist()), *floats, joined("emotion"), joined("root"),
                          joined("mover"), joined("codes"))

    def close(self) -> None:
        """Stop every worker and free the shared memory (idempotent)."""
        for worker in self.workers:
            if worker.block is not None:
                worker.close()

