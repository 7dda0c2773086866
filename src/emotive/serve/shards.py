"""The server's handles on its step workers: a process each, or a thread each.

Both kinds have the same surface, which :class:`~emotive.serve.workers.ShardedEngine` drives:
``send`` a request whose answer ``receive`` returns, ``post`` one whose answer is only
handled (in order, before the next ``receive``), ``adopt`` the scene's ids of new agents, a
:class:`~emotive.serve.worker_process.FrameBlock` the worker writes its frames into, and
``close``.

* :class:`StepWorker`: a process (``python -m emotive.serve.worker_process``) with its own
  interpreter, so its step runs beside the server's whatever the step does with the
  interpreter lock; requests go over a socket pair, frames through an unlinked file in
  shared memory; a process that dies is noticed (its socket closes) and reported.
* :class:`ThreadWorker`: a thread of the server's process with its own engine: no start-up
  process, no copies between processes; its step runs beside the others only while it has
  released the interpreter lock (the gait network's traced step does, for most of it).

Legend: ``R`` rows of a block.
"""

from __future__ import annotations

import logging
import mmap
import os
import socket
import subprocess
import sys
import tempfile
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from multiprocessing.connection import Connection, wait
from typing import Any

import numpy as np
import torch

from emotive.serve.engines import load_engine
from emotive.serve.errors import MessageError, ServeError
from emotive.serve.worker_process import FrameBlock, RequestHandler, WorkerSpec, warm_up

log = logging.getLogger("emotive.serve")

#: Seconds a worker may take to load its engine and say ready.
START_TIMEOUT = 180.0
#: Seconds a worker may take to answer one request before it counts as lost (a hang guard:
#: a step takes milliseconds, adding a batch of agents tens of them).
CALL_TIMEOUT = 60.0
#: Seconds a worker may take to stop before it is terminated, then killed.
STOP_TIMEOUT = 5.0
#: Where the shared frame blocks live (memory, on Linux); elsewhere the temporary folder.
SHARED_DIR = "/dev/shm"


def _ignore(_: Any) -> None:
    """The handler of a posted request whose answer says only that it was done."""


class WorkerLost(MessageError):
    """A step worker that died or stopped answering; its agents left the scene."""


class Shard:
    """What both kinds of worker keep: their number, their agents' scene ids, their block.

    Args:
        spec: what the worker runs.
    """

    def __init__(self, spec: WorkerSpec) -> None:
        self.spec = spec
        self.index = spec.index
        self.alive = False
        self.block: FrameBlock | None = None
        #: Scene ids of this worker's agents by its own ids.
        self.globals: dict[int, int] = {}
        self._lut = np.zeros(0, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.globals)

    def adopt(self, local: Sequence[int], agents: Sequence[int]) -> None:
        """Remember that this worker's ids ``local`` are the scene's ``agents``."""
        for a, g in zip(local, agents, strict=True):
            self.globals[int(a)] = int(g)
        top = max(local, default=-1)
        if top >= len(self._lut):
            grown = np.full(max(top + 1, 2 * len(self._lut)), -1, dtype=np.int64)
            grown[:len(self._lut)] = self._lut
            self._lut = grown
        self._lut[np.asarray(local, dtype=np.int64)] = agents

    def scene_ids(self, local: np.ndarray) -> np.ndarray:
        """``(B,)`` the scene's ids of this worker's ids ``local``."""
        return self._lut[local]

    def call(self, op: str, *args: Any) -> Any:
        """Send a request and wait for its answer (see ``receive``)."""
        self.send(op, *args)
        return self.receive()

    def send(self, op: str, *args: Any) -> None:  # pragma: no cover - each kind has its own
        """Send a request whose answer :meth:`receive` gets."""
        raise NotImplementedError

    def receive(self, timeout: float = CALL_TIMEOUT) -> Any:  # pragma: no cover
        """The answer to the oldest request :meth:`send` sent."""
        raise NotImplementedError


class StepWorker(Shard):
    """The server's side of one worker process: its socket, its block and its agents.

    Args:
        spec: what the worker runs.
    """

    #: What kind of worker it is (in messages).
    kind = "process"

    def __init__(self, spec: WorkerSpec) -> None:
        super().__init__(spec)
        # An unlinked file in shared memory: nothing to clean up if anyone dies.
        self._file = tempfile.TemporaryFile(dir=SHARED_DIR if os.path.isdir(SHARED_DIR)
                                            else None)
        self._file.truncate(spec.block_size)
        self._map = mmap.mmap(self._file.fileno(), spec.block_size)
        self.block: FrameBlock | None = FrameBlock(self._map, spec.rows, spec.joints,
                                                   spec.points, spec.labels)
        ours, theirs = socket.socketpair()
        self.conn = Connection(ours.detach())
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "emotive.serve.worker_process", spec.to_json(),
                 str(theirs.fileno()), str(self._file.fileno())],
                pass_fds=(theirs.fileno(), self._file.fileno()), stdin=subprocess.DEVNULL)
        finally:
            theirs.close()
        self.pid = self.process.pid
        #: What to do with each answer still to come, in order: ``None`` for one that
        #: :meth:`receive` returns, else the handler of a posted request's answer.
        self._expected: deque[Callable[[Any], None] | None] = deque()

    def _dead(self, what: str) -> WorkerLost:
        try:
            self.process.wait(0.5)
        except subprocess.TimeoutExpired:
            pass
        code = self.process.returncode
        how = ("is not running" if code is None else
               f"was killed by signal {-code}" if code < 0 else f"exited with code {code}")
        self.alive = False
        return WorkerLost(f"step worker {self.index} (process {self.pid}) {how} ({what})")

    def send(self, op: str, *args: Any) -> None:
        """Send a request whose answer :meth:`receive` gets."""
        self._write(op, args)
        self._expected.append(None)

    def post(self, op: str, *args: Any, then: Callable[[Any], None] | None = None) -> None:
        """Send a request without waiting for its answer.

        The worker answers requests in order; the answer of a posted one is read by the next
        :meth:`receive` and handed to ``then`` (a failure is logged: the server checked the
        request before, so none is expected).
        """
        self._write(op, args)
        self._expected.append(then or _ignore)

    def _write(self, op: str, args: tuple) -> None:
        try:
            self.conn.send((op, args))
        except (OSError, ValueError) as exc:
            raise self._dead(f"its socket failed: {exc}") from None

    def _read(self, timeout: float) -> tuple[str, Any]:
        if not wait([self.conn], timeout):
            self.kill()
            raise self._dead(f"no answer within {timeout:g} s; it was stopped")
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            raise self._dead("it died") from None

    def receive(self, timeout: float = CALL_TIMEOUT) -> Any:
        """The answer to the oldest request :meth:`send` sent (posted ones' answers first).

        Raises:
            WorkerLost: the process died (its socket closed) or did not answer within
                ``timeout`` (then it is stopped).
            Exception: the request failed in the worker (its exception, re-raised here).
        """
        while self._expected and self._expected[0] is not None:
            then = self._expected.popleft()
            kind, value = self._read(timeout)
            if kind == "error":
                log.error("step worker %d: a request failed: %s: %s", self.index,
                          type(value).__name__, value)
            else:
                then(value)
        if self._expected:
            self._expected.popleft()
        kind, value = self._read(timeout)
        if kind == "error":
            raise value
        return value

    def started(self, timeout: float = START_TIMEOUT) -> None:
        """Wait until the worker has loaded its engine.

        Raises:
            ServeError: it failed to start (its error) or took longer than ``timeout``.
        """
        try:
            self.receive(timeout)
        except WorkerLost as exc:
            raise ServeError(f"{exc}: it did not start") from None
        except Exception as exc:
            raise ServeError(f"step worker {self.index} could not load the engine: "
                             f"{type(exc).__name__}: {exc}") from None
        self.alive = True

    def kill(self) -> None:
        """Stop the process at once (and reap it)."""
        if self.process.poll() is None:
            self.process.kill()
        try:
            self.process.wait(STOP_TIMEOUT)
        except subprocess.TimeoutExpired:  # pragma: no cover - SIGKILL is not refused
            log.error("step worker %d (process %d) did not die", self.index, self.pid)

    def close(self) -> None:
        """Stop the process (in order if it answers, else by force) and free the block."""
        if self.process.poll() is None:
            try:
                self.conn.send(("stop", ()))
                self.process.wait(STOP_TIMEOUT)
            except (OSError, ValueError, subprocess.TimeoutExpired):
                self.process.terminate()
                try:
                    self.process.wait(STOP_TIMEOUT)
                except subprocess.TimeoutExpired:
                    pass
        self.kill()
        self.alive = False
        self.conn.close()
        self.block = None
        try:
            self._map.close()
        except BufferError:  # a view of it is still alive somewhere: freed with it
            pass
        self._file.close()


class ThreadWorker(Shard):
    """A step worker that is a thread of the server's process, with its own engine.

    Its requests run in order on its one thread (:class:`ThreadPoolExecutor`); its block is
    plain memory.

    Args:
        spec: what the worker runs.
    """

    #: What kind of worker it is (in messages).
    kind = "thread"

    def __init__(self, spec: WorkerSpec) -> None:
        super().__init__(spec)
        self.pid = os.getpid()
        self.block = FrameBlock(bytearray(spec.block_size), spec.rows, spec.joints,
                                spec.points, spec.labels)
        self._pool = ThreadPoolExecutor(1, thread_name_prefix=f"emotive-step-{spec.index}")
        self._handler: RequestHandler | None = None
        self._expected: deque[tuple[Future, Callable[[Any], None] | None]] = deque()
        self._expected.append((self._pool.submit(self._load), None))

    def _load(self) -> int:
        # One intra-op thread for the whole process: the engine would otherwise set it for
        # each step and put it back after, a global setting that the other step threads
        # would see change under them.
        torch.set_num_threads(1)
        engine = load_engine(self.spec.model, self.spec.backend, self.spec.seed)
        warm_up(engine)
        assert self.block is not None
        self._handler = RequestHandler(engine, self.block)
        return self.pid

    def send(self, op: str, *args: Any) -> None:
        """Queue a request whose answer :meth:`receive` gets."""
        self._expected.append((self._submit(op, args), None))

    def post(self, op: str, *args: Any, then: Callable[[Any], None] | None = None) -> None:
        """Queue a request without waiting for its answer (handled by the next receive)."""
        self._expected.append((self._submit(op, args), then or _ignore))

    def _submit(self, op: str, args: tuple) -> Future:
        if not self.alive:
            raise WorkerLost(f"step worker {self.index} (a thread) stopped")
        return self._pool.submit(lambda: self._handler.handle(op, args))

    def _result(self, future: Future, timeout: float) -> Any:
        try:
            return future.result(timeout)
        except FutureTimeout:
            # A thread cannot be stopped: it is left to finish, and never asked again.
            self.alive = False
            raise WorkerLost(f"step worker {self.index} (a thread) gave no answer within "
                             f"{timeout:g} s") from None

    def receive(self, timeout: float = CALL_TIMEOUT) -> Any:
        """The answer to the oldest request :meth:`send` queued (posted ones' answers first).

        Raises:
            WorkerLost: no answer within ``timeout``.
            Exception: the request failed (its exception).
        """
        while self._expected and self._expected[0][1] is not None:
            future, then = self._expected.popleft()
            try:
                value = self._result(future, timeout)
            except WorkerLost:
                raise
            except Exception as exc:  # checked before it was posted: none is expected
                log.error("step worker %d: a request failed: %s: %s", self.index,
                          type(exc).__name__, exc)
            else:
                then(value)
        future, _ = self._expected.popleft()
        return self._result(future, timeout)

    def started(self, timeout: float = START_TIMEOUT) -> None:
        """Wait until the thread has loaded its engine.

        Raises:
            ServeError: loading failed, or took longer than ``timeout``.
        """
        self.alive = True
        try:
            self.receive(timeout)
        except Exception as exc:
            self.alive = False
            raise ServeError(f"step worker {self.index} (a thread) could not load the engine: "
                             f"{type(exc).__name__}: {exc}") from None

    def kill(self) -> None:
        """Stop asking it anything (a thread cannot be stopped from outside)."""
        self.alive = False

    def close(self) -> None:
        """Let the thread finish what it has and end."""
        self.alive = False
        self._pool.shutdown(wait=True, cancel_futures=True)
        self.block = None
