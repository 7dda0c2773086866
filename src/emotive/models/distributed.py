"""Data-parallel training on several processes or machines (``torch.distributed``, gloo on CPU).

Synchronous data parallelism as in PyTorch Distributed (Li et al. 2020, section 3.2): every
process holds the whole model and the same random state, so each one draws the same batch
order, the same teacher-forcing choices and the same global batch; each trains on its own
contiguous share of that batch (:meth:`World.rows`), its gradient weighted by the share of the
global loss its rows carry (Goyal et al. 2017, section 3: normalize by the global batch, not the
local one), and one all-reduce sums the gradients (:meth:`World.sum_gradients`). Every process
then takes the same optimizer step, so the weights stay identical without being sent, and the
update is that of one process on the global batch up to float rounding. Dropout draws the
global batch's mask on every process and keeps its rows (:meth:`World.batch_dropout`): one
process's masks. Loss sums for the log are summed the same way (:meth:`World.sum_terms`);
validation is shared out batch by batch and its per-batch values put back in the one-process
order (:meth:`World.merge_rows`), so a validation number is bit-identical to one process's at
the same weights.

How processes are started:

* :func:`launch`: ``N`` processes on this machine (``emotive train ... --nproc N``), spawned
  fresh, meeting through a store this process hosts. A failing process stops the others at once
  and its error comes back as one line (:class:`TrainingProcessError`, or the process's own
  :class:`~emotive.errors.EmotiveError`); Ctrl-C gives every process
  :data:`INTERRUPT_GRACE_S` to leave its files at the last finished epoch; a process whose
  parent dies exits.
* ``torchrun`` (one or several machines): :func:`run_parallel` joins the group from the
  environment torchrun sets (``RANK``, ``WORLD_SIZE``, ``MASTER_ADDR``, ``MASTER_PORT``,
  ``LOCAL_WORLD_SIZE``).
* Ray Train, or a caller that set up ``torch.distributed`` itself: the trainers take the
  group that is already there (:func:`current_world`).

Process 0 alone writes checkpoints, logs and progress. Each process runs
``max(1, CPUs // local processes)`` torch threads. A collective that fails or waits longer
than its timeout raises :class:`PeerLostError`.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import timedelta
from multiprocessing.connection import Connection, wait
from typing import Any, TypeVar

import numpy as np
import torch
import torch.distributed as dist
from torch import nn

from emotive.errors import ConfigError, EmotiveError
from emotive.models.training import one_line

T = TypeVar("T")

#: Seconds a process waits for the others, to meet at start-up or in one collective, before
#: giving up: long enough for a slower machine to build its data cache.
DEFAULT_TIMEOUT_S = 1800.0
#: Seconds the processes get after Ctrl-C to leave their files at the last finished epoch.
INTERRUPT_GRACE_S = 10.0
#: Seconds to wait, after a process lost contact with the others, for the error that caused it.
_SETTLE_S = 3.0
#: Seconds a terminated process gets before it is killed.
_STOP_S = 5.0
#: Seconds after Ctrl-C before the processes it did not reach are sent one.
_FORWARD_S = 1.0


class TrainingProcessError(EmotiveError):
    """A process of a multi-process training failed; the others were stopped."""


class PeerLostError(TrainingProcessError):
    """A collective failed: another process stopped, or none came within the timeout."""


def available_cpus() -> int:
    """CPUs this process may run on (its affinity where the platform tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


@dataclass(frozen=True)
class World:
    """This process's place among the training processes (one process: the defaults).

    Attributes:
        rank: this process, 0 to ``size - 1``; process 0 writes the files.
        size: processes in all.
        local_rank: this process among those of its machine.
        local_size: processes on this machine (they share its CPUs).
    """

    rank: int = 0
    size: int = 1
    local_rank: int = 0
    local_size: int = 1

    @property
    def is_main(self) -> bool:
        """Whether this process writes checkpoints, logs and progress."""
        return self.rank == 0

    def check_batch(self, batch_size: int, name: str) -> None:
        """Refuse a global batch smaller than the processes: one would never get a row.

        Raises:
            ConfigError: ``batch_size`` below :attr:`size`.
        """
        if batch_size < self.size:
            raise ConfigError(f"{name} {batch_size}: fewer rows than the {self.size} training "
                              f"processes; use at most {batch_size} processes or a larger "
                              "batch_size")

    def rows(self, n: int) -> slice:
        """This process's contiguous share of ``n`` rows (shares differ by at most one row)."""
        base, extra = divmod(n, self.size)
        start = self.rank * base + min(self.rank, extra)
        return slice(start, start + base + (self.rank < extra))

    def split(self, n: int, *weights: np.ndarray) -> tuple[slice, list[float]]:
        """This process's :meth:`rows` of a global batch, and its part of each loss term.

        A term's mean over this process's rows times its part sums, over the processes, to
        the term's mean over the global batch (Goyal et al. 2017, section 3).

        Args:
            n: ``B``, rows of the global batch.
            *weights: ``(B,)`` weight of each row in a weighted mean (a class-weighted
                cross-entropy; 0 where the term ignores the row).

        Returns:
            The rows, and the parts: first of a plain mean over rows, then of each
            ``weights`` (this process's sum over the total; 0 when the total is 0). For one
            process every part is 1.

        Raises:
            ConfigError: fewer rows than processes.
        """
        self.check_batch(n, "a batch of")
        rows = self.rows(n)
        if self.size == 1:
            return rows, [1.0] * (1 + len(weights))
        parts = [(rows.stop - rows.start) / n]
        for w in weights:
            total = float(np.sum(w))
            parts.append(float(np.sum(w[rows])) / total if total else 0.0)
        return rows, parts

    def sum_gradients(self, parameters: Iterable[torch.nn.Parameter], share: float) -> None:
        """Make every ``.grad`` the sum over the processes of ``share`` times their own.

        One all-reduce of every gradient flattened together. A parameter without a gradient on
        every process keeps none (as one process's optimizer would skip it); a process with no
        rows sends zeros. Nothing happens for one process.

        Args:
            parameters: the model's parameters, in the same order on every process.
            share: the factor on this process's gradients (1 when its loss is already its
                part of the global loss, :meth:`split`; ``rows / global rows`` for a mean).
        """
        if self.size == 1:
            return
        params = list(parameters)
        flat = torch.cat([
            *(p.grad.reshape(-1) * share if p.grad is not None
              else torch.zeros(p.numel(), dtype=p.dtype) for p in params),
            torch.tensor([float(p.grad is not None) for p in params], dtype=params[0].dtype),
        ])
        _all_reduce(flat, "the gradient sum")
        offset, present = 0, flat[-len(params):]
        for p, has in zip(params, present.tolist(), strict=True):
            grad = flat[offset:offset + p.numel()].view_as(p)
            offset += p.numel()
            if not has:
                p.grad = None
            elif p.grad is None:
                p.grad = grad.clone()
            else:
                p.grad.copy_(grad)

    def sum_terms(self, sums: dict[str, float], seen: int, names: Sequence[str]
                  ) -> tuple[dict[str, float], int]:
        """``sums`` (row-weighted loss sums) and ``seen`` (rows) summed over the processes.

        Args:
            sums: ``{name: sum of value * rows}`` of this process (names among ``names``).
            seen: rows this process trained on.
            names: every name a process may have, in one order on every process.

        Returns:
            The summed ``{name: sum}`` (names some process had, in ``names`` order) and rows;
            ``(sums, seen)`` themselves for one process.
        """
        if self.size == 1:
            return sums, seen
        values = torch.tensor([*(sums.get(n, 0.0) for n in names),
                               *(float(n in sums) for n in names), float(seen)],
                              dtype=torch.float64)
        _all_reduce(values, "the loss sums")
        k = len(names)
        return ({n: float(values[i]) for i, n in enumerate(names) if values[k + i] > 0},
                int(values[-1]))

    def merge_rows(self, rows: list[dict[str, float]], names: Sequence[str]
                   ) -> list[dict[str, float]]:
        """Per-batch values, each computed by one process, gathered on every process.

        Args:
            rows: one dict per batch, in batch order: this process's values for its batches,
                ``{}`` for the others'.
            names: every name a row may hold, in one order on every process.

        Returns:
            Every batch's values as the process that owned it computed them (adding zeros is
            exact, so they are bit for bit that process's); ``rows`` for one process.
        """
        if self.size == 1:
            return rows
        table = torch.zeros((len(rows), 2 * len(names)), dtype=torch.float64)
        for i, row in enumerate(rows):
            for j, name in enumerate(names):
                if name in row:
                    table[i, j], table[i, len(names) + j] = row[name], 1.0
        _all_reduce(table, "the validation values")
        return [{n: float(table[i, j]) for j, n in enumerate(names) if table[i, len(names) + j]}
                for i in range(len(rows))]

    def broadcast_module(self, module: torch.nn.Module) -> None:
        """Copy process 0's parameters and buffers into ``module`` on every process."""
        if self.size == 1:
            return
        for tensor in module.state_dict().values():
            _collective("the weights' broadcast", lambda t=tensor: dist.broadcast(t, src=0))

    def from_main(self, make: Callable[[], T]) -> T:
        """``make()`` on process 0 (e.g. reading a checkpoint), sent to every process.

        So that processes on machines without a shared disk resume from process 0's file.
        """
        if self.size == 1:
            return make()
        box = [make() if self.is_main else None]
        _collective("a broadcast", lambda: dist.broadcast_object_list(box, src=0))
        return box[0]

    @contextmanager
    def batch_dropout(self, module: torch.nn.Module, n: int) -> Iterator[None]:
        """Within the block, ``module``'s dropout draws the masks one process would.

        Every :class:`torch.nn.Dropout` of ``module`` is swapped for one that draws the mask of
        the whole global batch of ``n`` rows (every process draws the same, from the same
        generator state) and keeps this process's :meth:`rows`; the modules are put back
        after. Nothing changes for one process.

        Args:
            module: the network.
            n: ``B``, rows of every global batch the block trains on.
        """
        if self.size == 1:
            yield
            return
        swapped = [(parent, name, child) for parent in module.modules()
                   for name, child in parent.named_children() if isinstance(child, nn.Dropout)]
        for parent, name, child in swapped:
            setattr(parent, name, _RowsDropout(child.p, self.rows(n), n).train(child.training))
        try:
            yield
        finally:
            for parent, name, child in swapped:
                setattr(parent, name, child)


class _RowsDropout(nn.Module):
    """Dropout of ``torch.nn.functional.dropout`` on the rows ``rows`` of ``n``.

    The mask is drawn for ``(n, ...)`` as one process's ``empty_like(x).bernoulli_(1 - p)``
    divided by ``1 - p``, then cut to ``rows``: the same draws, so the same masks.
    """

    def __init__(self, p: float, rows: slice, n: int) -> None:
        super().__init__()
        self.p, self.rows, self.n = p, rows, n

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0:
            return x
        if self.p == 1:
            return x * torch.zeros((), dtype=x.dtype)
        noise = torch.empty((self.n, *x.shape[1:]), dtype=x.dtype).bernoulli_(1 - self.p)
        return x * noise.div_(1 - self.p)[self.rows]


def current_world() -> World:
    """The processes ``torch.distributed`` has joined this one to; :class:`World` () if none."""
    if not (dist.is_available() and dist.is_initialized()):
        return World()
    rank, size = dist.get_rank(), dist.get_world_size()
    return World(rank, size, int(os.environ.get("LOCAL_RANK", rank)),
                 int(os.environ.get("LOCAL_WORLD_SIZE", size)))


def _collective(what: str, run: Callable[[], Any]) -> Any:
    """``run()``, its failure a :class:`PeerLostError` naming ``what``."""
    try:
        return run()
    except RuntimeError as exc:  # gloo's failures and timeouts (DistBackendError among them)
        raise PeerLostError(f"lost contact with the other training processes in {what} "
                            f"({one_line(exc)})") from None


def _all_reduce(tensor: torch.Tensor, what: str) -> None:
    _collective(what, lambda: dist.all_reduce(tensor, op=dist.ReduceOp.SUM))


def check_nproc(nproc: int) -> None:
    """Refuse fewer than 1 process or more than this machine's CPUs.

    More processes than CPUs only share them and train slower; several machines are joined
    with ``torchrun`` instead.

    Raises:
        ConfigError: ``nproc`` out of range, with the range.
    """
    cpus = available_cpus()
    if isinstance(nproc, bool) or not isinstance(nproc, int) or not 1 <= nproc <= cpus:
        raise ConfigError(f"--nproc {nproc}: give 1 to {cpus} processes, the CPUs of this "
                          "machine (train on several machines with torchrun, see the docs' "
                          "'Training on several processes or machines')")


def one_process_only() -> None:
    """Refuse a one-process trainer in a torchrun or Ray job (each process would train alone).

    Raises:
        ConfigError: ``WORLD_SIZE`` above 1, or ``torch.distributed`` already joined.
    """
    if int(os.environ.get("WORLD_SIZE") or 1) > 1 or (dist.is_available()
                                                      and dist.is_initialized()):
        raise ConfigError("this trainer runs in one process; start it without torchrun or Ray "
                          "(emotive train gait and classifier run on several)")


def run_parallel(fn: Callable[..., T], /, *args: Any, nproc: int = 1,
                 timeout: float = DEFAULT_TIMEOUT_S, **kwargs: Any) -> T | None:
    """``fn(*args, **kwargs)`` in one process, in ``nproc`` local ones, or as torchrun's part.

    Args:
        fn: a function importable by name (a trainer); it finds its place with
            :func:`current_world`.
        *args: its positional arguments (picklable when ``nproc > 1``).
        nproc: processes to start on this machine; must be 1 when this process was started by
            torchrun (``WORLD_SIZE`` above 1) or joined to a group already (Ray Train).
        timeout: seconds to wait for the other processes, at start-up and in a collective.
        **kwargs: its keyword arguments.

    Returns:
        What ``fn`` returns on process 0 (here, or in the first spawned process); ``None`` on
        the other processes of a torchrun or Ray job.

    Raises:
        ConfigError: a bad ``nproc``, or ``nproc > 1`` inside a torchrun or Ray job.
        TrainingProcessError: a process failed (an :class:`EmotiveError` of a process is
            raised as itself).
        KeyboardInterrupt: Ctrl-C.
    """
    size = int(os.environ.get("WORLD_SIZE") or 1)
    joined = dist.is_available() and dist.is_initialized()
    if (joined or size > 1) and nproc != 1:
        raise ConfigError(f"--nproc {nproc}: this process is one of {size} started by torchrun "
                          "or Ray; leave out --nproc (torchrun's --nproc-per-node sets it)")
    if joined:
        value = fn(*args, **kwargs)
        return value if current_world().is_main else None
    if size > 1:
        _join_from_environment(timeout)
        try:
            value = fn(*args, **kwargs)
            main = current_world().is_main
        finally:
            dist.destroy_process_group()
        return value if main else None
    check_nproc(nproc)
    if nproc == 1:
        return fn(*args, **kwargs)
    return launch(fn, args, kwargs, nproc, timeout)


def _join_from_environment(timeout: float) -> None:
    """Join the group torchrun describes in the environment; threads per local process."""
    local = int(os.environ.get("LOCAL_WORLD_SIZE") or 1)
    torch.set_num_threads(max(1, available_cpus() // local))
    where = f"{os.environ.get('MASTER_ADDR')}:{os.environ.get('MASTER_PORT')}"
    try:
        dist.init_process_group("gloo", init_method="env://",
                                timeout=timedelta(seconds=timeout))
    except (RuntimeError, ValueError) as exc:
        raise TrainingProcessError(f"cannot join the training processes at {where} "
                                   f"({one_line(exc)}); check MASTER_ADDR and MASTER_PORT"
                                   ) from None


def launch(fn: Callable[..., T], args: Sequence[Any], kwargs: dict[str, Any], nproc: int,
           timeout: float = DEFAULT_TIMEOUT_S, threads: int | None = None) -> T:
    """Run ``fn(*args, **kwargs)`` in ``nproc`` fresh processes on this machine, joined by gloo.

    Args:
        fn: a module-level function (the spawned processes import it by name).
        args: positional arguments, picklable.
        kwargs: keyword arguments, picklable.
        nproc: processes (1 runs ``fn`` in one fresh process, as a baseline).
        timeout: seconds to meet, and per collective.
        threads: torch threads per process; ``None``: ``max(1, CPUs // nproc)``.

    Returns:
        Process 0's return value (sent back pickled).

    Raises:
        TrainingProcessError: a process failed or died; every process was stopped.
        EmotiveError: a process's own error of this kind (a bad config, a missing checkpoint).
        KeyboardInterrupt: Ctrl-C, after the processes' grace.
    """
    ctx = multiprocessing.get_context("spawn")
    # The store is this process's: no port is chosen and then taken by someone else.
    store = dist.TCPStore("127.0.0.1", 0, None, True, timedelta(seconds=timeout),
                          wait_for_workers=False)
    threads = threads or max(1, available_cpus() // nproc)
    procs, reports, lifelines = [], [], []  # the processes, their reports' and lifelines' pipes
    try:
        for rank in range(nproc):
            report_in, report_out = ctx.Pipe(duplex=False)
            lifeline_in, lifeline_out = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_process, name=f"emotive-train-{rank}", args=(
                rank, nproc, store.port, threads, timeout, fn, tuple(args), dict(kwargs),
                report_out, lifeline_in))
            proc.start()
            report_out.close()
            lifeline_in.close()
            procs.append(proc)
            reports.append(report_in)
            lifelines.append(lifeline_out)
        try:
            return _supervise(procs, reports)
        except KeyboardInterrupt:
            _interrupt(procs)
            raise
    finally:
        _stop(procs)
        for conn in (*reports, *lifelines):
            conn.close()
        del store


def _supervise(procs: list[Any], reports: list[Connection]) -> Any:
    """Wait for every process's report; on the first failure, the error to raise."""
    n = len(procs)
    messages: dict[int, tuple[str, Any]] = {}
    while len(messages) < n:
        waiting = [r for r in range(n) if r not in messages]
        ready = wait([reports[r] for r in waiting] + [procs[r].sentinel for r in waiting])
        for r in waiting:
            if reports[r] in ready or procs[r].sentinel in ready:
                messages[r] = _receive(reports[r], procs[r])
        if any(kind != "done" for kind, _ in messages.values()):
            _settle(procs, reports, messages)
            raise _failure(messages, n)
    return pickle.loads(messages[0][1])


def _receive(report: Connection, proc: Any) -> tuple[str, Any]:
    """A process's report, or why it has none (it died)."""
    try:
        if report.poll():
            return report.recv()
    except (EOFError, OSError):
        pass
    proc.join(_STOP_S)
    code = proc.exitcode
    how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
    return "error", {"kind": "died", "text": f"died ({how}) without a report", "error": None}


def _settle(procs: list[Any], reports: list[Connection], messages: dict[int, tuple]) -> None:
    """After only lost-contact failures, wait a moment for the report of the cause."""
    deadline = time.monotonic() + _SETTLE_S
    while not any(kind == "error" and info["kind"] not in ("peer", "died")
                  for kind, info in messages.values()):
        waiting = [r for r in range(len(procs)) if r not in messages]
        left = deadline - time.monotonic()
        if not waiting or left <= 0:
            return
        ready = wait([reports[r] for r in waiting], left)
        for r in waiting:
            if reports[r] in ready:
                messages[r] = _receive(reports[r], procs[r])


def _failure(messages: dict[int, tuple[str, Any]], n: int) -> BaseException:
    """The error to raise: the first cause, before lost contacts and deaths."""
    if any(kind == "interrupted" for kind, _ in messages.values()):
        return KeyboardInterrupt()
    failed = sorted((r, info) for r, (kind, info) in messages.items() if kind == "error")
    rank, info = min(failed, key=lambda f: (f[1]["kind"] in ("peer", "died"), f[0]))
    if info["kind"] == "emotive" and info["error"] is not None:
        try:
            return pickle.loads(info["error"])
        except Exception:  # an error class whose arguments do not round-trip
            pass
    return TrainingProcessError(f"training process {rank} of {n} failed: {info['text']}; "
                                "every process was stopped")


def _interrupt(procs: list[Any]) -> None:
    """After Ctrl-C here, give the processes :data:`INTERRUPT_GRACE_S` to tidy up.

    Ctrl-C in a terminal reaches every process of its group; a process still running a moment
    later (this process alone was interrupted, ``kill -INT``) is sent its own.
    """
    deadline = time.monotonic() + INTERRUPT_GRACE_S
    for proc in procs:
        proc.join(_FORWARD_S / len(procs))
    for proc in procs:
        if proc.is_alive():
            os.kill(proc.pid, signal.SIGINT)
    for proc in procs:
        proc.join(max(0.0, deadline - time.monotonic()))


def _stop(procs: list[Any]) -> None:
    """Terminate the processes still running, then kill those that do not stop."""
    for proc in procs:
        if proc.is_alive():
            proc.terminate()
    for proc in procs:
        proc.join(_STOP_S)
        if proc.is_alive():
            proc.kill()
            proc.join()


def _exit_with_parent(lifeline: Connection) -> None:
    """Exit when the launching process is gone (its end of ``lifeline`` closes)."""
    try:
        lifeline.recv()
    except (EOFError, OSError):
        pass
    os._exit(1)


def _process(rank: int, size: int, port: int, threads: int, timeout: float,
             fn: Callable[..., Any], args: tuple, kwargs: dict, report: Connection,
             lifeline: Connection) -> None:
    """Body of a spawned process: join the group, run ``fn``, report back."""
    threading.Thread(target=_exit_with_parent, args=(lifeline,), daemon=True).start()
    os.environ.update(RANK=str(rank), WORLD_SIZE=str(size), LOCAL_RANK=str(rank),
                      LOCAL_WORLD_SIZE=str(size), MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))
    torch.set_num_threads(threads)
    try:
        delta = timedelta(seconds=timeout)
        store = dist.TCPStore("127.0.0.1", port, None, False, delta)
        dist.init_process_group("gloo", store=store, rank=rank, world_size=size, timeout=delta)
        value = fn(*args, **kwargs)
        payload = pickle.dumps(value) if rank == 0 else None
        dist.destroy_process_group()
        report.send(("done", payload))
        return
    except KeyboardInterrupt:
        message: tuple[str, Any] = ("interrupted", None)
        code = 130
    except BaseException as exc:  # every failure goes back to the launcher, in one line
        message, code = ("error", _describe(exc)), 1
    try:
        report.send(message)
    finally:
        # No interpreter teardown: it could wait on the other processes' sockets.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def _describe(exc: BaseException) -> dict[str, Any]:
    """What the launcher needs of a process's exception: kind, one line, the error itself."""
    kind = ("peer" if isinstance(exc, PeerLostError)
            else "emotive" if isinstance(exc, EmotiveError) else "other")
    text = one_line(exc) if kind != "other" else f"{type(exc).__name__}: {one_line(exc)}"
    try:
        error = pickle.dumps(exc) if kind == "emotive" else None
    except Exception:  # an error holding something that cannot be pickled
        error = None
    return {"kind": kind, "text": text, "error": error}
