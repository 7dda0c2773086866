"""One step worker: a process that owns an engine and steps its share of the scene's agents.

Started by :class:`~emotive.serve.workers.StepWorker` as ``python -m
emotive.serve.worker_process SPEC CONN BLOCK`` (a fresh interpreter: no copy of the server's
threads, and no import of the program that runs the server), with two inherited file
descriptors: ``CONN`` one end of a socket pair to the server, ``BLOCK`` an unlinked file in
shared memory that both map. :func:`run_worker` loads the engine of the server's model and
backend, maps the block, says ``ready`` and then answers the server's requests, one at a
time, over the socket: ``(op, args)`` in,
``("ok", result)`` or ``("error", exception)`` out. ``step`` writes the new frame of its
agents into the shared block (:class:`FrameBlock`), with the rotations' smallest-three codes
of the compact frame layout (so that quantizing, like stepping, is split over the workers),
and answers with the number of agents written and the step's processor time. The worker
ignores ``SIGINT`` (Ctrl-C reaches the whole process group: the server stops it in order)
and ends on ``stop`` or when its pipe closes (the server is gone).

Legend: ``R`` rows of the block (agents it can hold), ``J`` joints, ``P`` points (joints then
end sites), ``C`` emotion labels.
"""

from __future__ import annotations

import gc
import json
import mmap
import os
import signal
import sys
import time
from dataclasses import asdict, dataclass
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import torch

from emotive.data.emotion import coerce_emotion
from emotive.paths import circle
from emotive.serve.engines import load_engine
from emotive.serve.quantize import quaternion_to_smallest_three

#: Requests that change an agent, by name: the engine's method of the same name.
AGENT_OPS = ("remove_agent", "set_emotion", "set_path", "set_target", "set_pace")
#: Steps of the warm-up agent before the worker says ready (:func:`warm_up`).
WARM_UP_STEPS = 3


@dataclass(frozen=True)
class WorkerSpec:
    """What a worker needs to start.

    Attributes:
        index: its number among the server's workers.
        model: ``"gait"`` or ``"fcrbm"``.
        backend: ``"torch"`` or ``"onnx"``.
        seed: seed of its agents' starting phases.
        rows: agents the block holds at most (``R``).
        joints: ``J``.
        points: ``P``.
        labels: ``C``.
    """

    index: int
    model: str
    backend: str
    seed: int
    rows: int
    joints: int
    points: int
    labels: int

    def to_json(self) -> str:
        """The spec as one JSON text (the worker's first argument)."""
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> WorkerSpec:
        """The spec of :meth:`to_json`."""
        return cls(**json.loads(text))

    @property
    def block_size(self) -> int:
        """Bytes of its :class:`FrameBlock`."""
        return FrameBlock.size(self.rows, self.joints, self.points, self.labels)


class FrameBlock:
    """Views of one worker's frame arrays in a shared buffer (the same on both sides).

    Args:
        buffer: the shared memory, at least :meth:`size` bytes.
        rows: ``R``; joints ``J``; points ``P``; labels ``C``.

    Attributes:
        ids: ``(R,)`` int32 the worker's own agent ids.
        mover: ``(R, 3)`` float32 world position of the mover joint, metres.
        rotations: ``(R, J, 4)`` float32 local rotations ``(w, x, y, z)``.
        positions: ``(R, J, 3)`` float32 local translations, the mover's its world position.
        world: ``(R, P, 3)`` float32 world positions of joints then end sites, metres.
        emotion: ``(R, C)`` float32 emotion weights.
        root: ``(R, 2)`` float32 ground position ``(x, z)``, metres.
        codes: ``(R, J, 3)`` uint16 smallest-three codes of the rotations.
    """

    def __init__(self, buffer: Any, rows: int, joints: int, points: int, labels: int) -> None:
        offset = 0
        for name, dtype, shape in self.fields(rows, joints, points, labels):
            array = np.ndarray(shape, dtype=dtype, buffer=buffer, offset=offset)
            setattr(self, name, array)
            offset += array.nbytes + -array.nbytes % 8

    @staticmethod
    def fields(rows: int, joints: int, points: int, labels: int
               ) -> list[tuple[str, str, tuple[int, ...]]]:
        """``(name, dtype, shape)`` of each array, in the block's order."""
        r, j = rows, joints
        return [("ids", "<i4", (r,)), ("mover", "<f4", (r, 3)), ("rotations", "<f4", (r, j, 4)),
                ("positions", "<f4", (r, j, 3)), ("world", "<f4", (r, points, 3)),
                ("emotion", "<f4", (r, labels)), ("root", "<f4", (r, 2)),
                ("codes", "<u2", (r, j, 3))]

    @classmethod
    def size(cls, rows: int, joints: int, points: int, labels: int) -> int:
        """Bytes of a block."""
        total = 0
        for _, dtype, shape in cls.fields(rows, joints, points, labels):
            n = int(np.prod(shape)) * np.dtype(dtype).itemsize
            total += n + -n % 8
        return max(total, 8)

    def write(self, frame: Any, mover: int, full: bool = True) -> int:
        """Copy a frame of ``B <= R`` agents in (coding its rotations); returns ``B``.

        Args:
            frame: the engine's frame.
            mover: the mover joint.
            full: also the float rotations, local translations and world positions (for
                version-1 frames and recordings); else ids, mover positions, emotions,
                ground positions and rotation codes only.

        Raises:
            ValueError: more agents than rows.
        """
        b = len(frame.agents)
        if b > len(self.ids):
            raise ValueError(f"a frame of {b} agents does not fit a block of {len(self.ids)} "
                             "rows")
        self.ids[:b] = frame.agents
        self.mover[:b] = frame.positions[:, mover]
        if full:
            self.rotations[:b] = frame.rotations
            self.positions[:b] = frame.positions
            self.world[:b] = frame.world
        self.emotion[:b] = frame.emotion
        self.root[:b] = frame.root
        self.codes[:b] = quaternion_to_smallest_three(frame.rotations)
        return b


class RequestHandler:
    """The request handlers of one worker (its engine and block): ``handle(op, args)``."""

    def __init__(self, engine: Any, block: FrameBlock) -> None:
        self.engine = engine
        self.block = block

    def handle(self, op: str, args: tuple) -> Any:
        """The answer to request ``op`` with ``args`` (``step``, ``add_agents``, an agent's)."""
        if op == "step":
            start = time.thread_time()
            frame = self.engine.step()
            seconds = time.thread_time() - start
            return self.block.write(frame, self.engine.mover, *args), seconds
        if op == "add_agents":
            return self.engine.add_agents(*args)
        if op in AGENT_OPS:
            return getattr(self.engine, op)(*args)
        if op == "ping":
            return os.getpid()
        raise ValueError(f"step worker: unknown request {op!r}")


def warm_up(engine: Any) -> None:
    """Add one agent, step :data:`WARM_UP_STEPS` times and remove it again.

    The first agent and the first steps of a fresh engine pay one-time costs (over a second
    for the gait network on a 2-core machine); paid here, before the worker says ready, they
    never stall a tick of the scene. The worker's own ids start after it, unseen: the server
    numbers agents itself.
    """
    schedule = coerce_emotion("neutral", engine.labels, engine.points_over)
    (agent,) = engine.add_agents([circle()], [schedule], [0.0], [1.0])
    for _ in range(WARM_UP_STEPS):
        engine.step()
    engine.remove_agent(agent)
    engine.step()


def _reply_error(conn: Connection, exc: BaseException) -> None:
    try:
        conn.send(("error", exc))
    except Exception:  # an exception that does not pickle: send its text
        conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))


def run_worker(conn: Connection, spec: WorkerSpec, block_fd: int) -> None:
    """The worker's main loop: load, map the block, say ready, answer until told to stop.

    Args:
        conn: its end of the socket pair to the server.
        spec: what it runs.
        block_fd: the file descriptor of its shared block (:attr:`WorkerSpec.block_size`).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        torch.set_num_threads(1)
        engine = load_engine(spec.model, spec.backend, spec.seed)
        shared = mmap.mmap(block_fd, spec.block_size)
    except BaseException as exc:  # the server reports it as the worker's start failure
        _reply_error(conn, exc)
        return
    try:
        warm_up(engine)
    except Exception as exc:  # reported to the server as the worker's start failure
        _reply_error(conn, exc)
        return
    block = FrameBlock(shared, spec.rows, spec.joints, spec.points, spec.labels)
    worker = RequestHandler(engine, block)
    # The model is loaded: keep it out of the cyclic collector's full passes.
    gc.freeze()
    conn.send(("ready", os.getpid()))
    try:
        while True:
            try:
                op, args = conn.recv()
            except (EOFError, OSError):
                break
            if op == "stop":
                break
            try:
                result = worker.handle(op, args)
            except Exception as exc:  # every failure is the request's answer
                _reply_error(conn, exc)
            else:
                conn.send(("ok", result))
    finally:
        del block, worker
        shared.close()


def main(argv: list[str] | None = None) -> None:
    """``python -m emotive.serve.worker_process SPEC CONN BLOCK`` (started by the server)."""
    spec_text, conn_fd, block_fd = (sys.argv[1:] if argv is None else argv)
    run_worker(Connection(int(conn_fd)), WorkerSpec.from_json(spec_text), int(block_fd))


if __name__ == "__main__":
    main()
