"""Ray runs the shards: a local instance of ``N`` workers, or a cluster at ``--address``.

The main paper's augmented data set (Bhattacharya et al. 2020, section 5.2) is thousands of
walks; each shard (:mod:`emotive.synth.shards`) is one Ray task that makes its walks in one
batched generator call on one CPU and returns its files' bytes, and this process, which
holds the folder, writes them (:meth:`Folder.write_files
<emotive.synth.store.Folder.write_files>`) as they come back. So the workers need no shared
file system, and a shard is written whole or not at all.

* Local (no address): ``ray.init(address="local", num_cpus=N)``, a Ray instance of this
  process whose node is 127.0.0.1, its workers at normal priority (Ray's default is
  niceness 15, which lets any other work on the machine starve them), stopped at the end. A
  process already connected to Ray (a notebook, a test) keeps its connection.
* A cluster: ``ray start --head --port 6379`` on one machine and
  ``ray start --address HEAD:6379`` on the others (each with emotive installed in the same
  version), then ``--address HEAD:6379``; ``N`` defaults to the cluster's CPUs.

At most ``N`` shards are in flight; results are written in the order they finish. A task that
raises a user-facing error (:class:`~emotive.errors.EmotiveError`) stops the run with that
error; a worker that dies is retried by Ray (:data:`MAX_RETRIES`).

Stopping: Ctrl-C (SIGINT), SIGTERM and SIGHUP stop the run through ``finally``, which cancels
the tasks and stops the local Ray with all its processes (``ray.shutdown``; about 4 s), and
the command exits 130, 143 or 129. Python's default SIGTERM ends the process without
``finally``, and the handler ``ray.init`` installs aborts it; a driver that ends without
``ray.shutdown`` leaves the local Ray's dashboard and runtime-env agents running for about a
minute, until they notice. So while shards run, SIGTERM and SIGHUP are handled as Ctrl-C is.
Only SIGKILL, which no process can handle, still leaves them to stop by themselves.

Progress: a bar on stderr (walks done, walks/s, time left) on a terminal, else one line per
finished shard.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any

from emotive.errors import EmotiveError
from emotive.synth.recipe import SynthError
from emotive.synth.shards import ShardResult

#: Times Ray starts a shard again after its worker died.
MAX_RETRIES = 2
#: Seconds to wait for a cluster's head to answer before calling the address unreachable.
CONNECT_TIMEOUT_S = 3.0
#: Port of a ``ray://`` client address without one.
CLIENT_PORT = 10001


class ClusterError(SynthError):
    """A Ray cluster that cannot be reached, or Ray missing."""


@dataclass(frozen=True)
class RunStats:
    """What a run of the engine did.

    Attributes:
        shards: shards made.
        walks: walks made.
        seconds: wall time from the first task to the last result, seconds.
        workers: tasks in flight at most.
        where: ``"local"`` or the cluster's address.
        first_seconds: wall time to the first shard written (the workers' start-up and one
            shard), seconds.
        first_walks: walks of that first shard.
    """

    shards: int
    walks: int
    seconds: float
    workers: int
    where: str
    first_seconds: float = 0.0
    first_walks: int = 0

    @property
    def walks_per_second(self) -> float:
        """Walks made per second of wall time."""
        return self.walks / self.seconds if self.seconds > 0 else 0.0

    @property
    def steady_walks_per_second(self) -> float:
        """Walks per second after the first shard (the workers started), 0 if one shard."""
        span = self.seconds - self.first_seconds
        return (self.walks - self.first_walks) / span if span > 0 else 0.0


def import_ray() -> Any:
    """The ``ray`` module.

    Raises:
        ClusterError: Ray is not installed, with the command that installs it.
    """
    try:
        # Deferred: Ray is an optional dependency (the ``synth`` extra), loaded only to run.
        import ray  # noqa: PLC0415
    except ImportError:
        raise ClusterError("emotive synth runs on Ray, which is not installed: pip install "
                           "'emotive[synth]' (ray and pyarrow)") from None
    return ray


def host_port(address: str) -> tuple[str, int] | None:
    """``(host, port)`` of a Ray address, or ``None`` for ``auto``.

    Raises:
        ClusterError: an address without a host and port.
    """
    text = address.strip()
    if text == "auto":
        return None
    client = text.startswith("ray://")
    rest = text.removeprefix("ray://").split("/", 1)[0]
    host, sep, port = rest.rpartition(":")
    if not sep:
        host, port = rest, str(CLIENT_PORT) if client else ""
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ClusterError(f"--address {address}: give the head's HOST:PORT (the port "
                           "`ray start --head --port PORT` printed), e.g. 127.0.0.1:6379, or "
                           "leave it out for a local Ray")
    return host.strip("[]"), int(port)


def check_reachable(address: str) -> None:
    """Fail fast unless something answers at ``address`` (a TCP connection to its port).

    Raises:
        ClusterError: a malformed address or nothing listening there.
    """
    target = host_port(address)
    if target is None:
        return
    try:
        with socket.create_connection(target, timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        raise ClusterError(f"--address {address}: no Ray cluster answers there "
                           f"({exc.strerror or exc}); start one with `ray start --head --port "
                           f"{target[1]}`, check the host and port, or leave --address out for "
                           "a local Ray") from None


def connect(ray: Any, address: str | None, workers: int | None) -> tuple[bool, int, str]:
    """Connect to Ray; returns ``(started here, workers, where)``.

    Raises:
        ClusterError: the cluster cannot be joined (naming the address and the fix).
    """
    if ray.is_initialized():
        cpus = int(ray.cluster_resources().get("CPU", 1))
        return False, workers or cpus, "an existing Ray connection"
    options = {"include_dashboard": False, "log_to_driver": False, "logging_level": "ERROR"}
    if address is None:
        n = workers or os.cpu_count() or 1
        # Ray runs workers at niceness 15 by default; here they are the command's own work.
        ray.init(address="local", num_cpus=n, _node_ip_address="127.0.0.1",
                 _system_config={"worker_niceness": 0}, **options)
        return True, n, f"local Ray, {n} worker{'s' * (n != 1)}"
    check_reachable(address)
    try:
        ray.init(address=address, **options)
    except (ConnectionError, RuntimeError, ValueError, TimeoutError) as exc:
        raise ClusterError(f"--address {address}: cannot join that Ray cluster "
                           f"({' '.join(str(exc).split())[:200]}); check that it runs the same "
                           "Ray and Python version, or leave --address out") from None
    n = workers or int(ray.cluster_resources().get("CPU", 1))
    return True, n, f"Ray cluster at {address}, {n} worker{'s' * (n != 1)}"


def run_shards(todo: Iterable[int], task: Callable[..., ShardResult], args: tuple,
               write: Callable[[ShardResult], None], workers: int | None = None,
               address: str | None = None, progress: Callable[[str, int, int], None]
               | None = None) -> RunStats:
    """Run ``task(*args, shard)`` for every shard of ``todo`` on Ray; ``write`` each result.

    Args:
        todo: shard indices to make.
        task: the shard function (:func:`emotive.synth.shards.make_shard` with the
            recipe, the rig and the draws in ``args`` before the shard).
        args: its leading arguments.
        write: called in this process with every result, as they finish.
        workers: shards in flight at most (default: local CPUs, or the cluster's).
        address: the cluster's address, or ``None`` for a local Ray.
        progress: ``progress(event, shards_done, walks_done)`` after connecting
            (``"start"``, with the place in the event text) and after every shard.

    Returns:
        What was made.

    Raises:
        ClusterError: Ray missing, or the cluster unreachable.
        EmotiveError: a task's own user-facing error.
        SynthError: a task that failed otherwise (finished shards are kept).
    """
    ray = import_ray()
    todo = list(todo)
    with _exit_on_termination() as install:
        started, workers, where = connect(ray, address, workers)
        install()           # again: ray.init puts its own SIGTERM handler in place
        return _run(ray, started, workers, where, todo, task, args, write, progress)


def _run(ray: Any, started: bool, workers: int, where: str, todo: list[int],
         task: Callable[..., ShardResult], args: tuple, write: Callable[[ShardResult], None],
         progress: Callable[[str, int, int], None] | None) -> RunStats:
    """The body of :func:`run_shards` once connected; stops a Ray it started, however it ends."""
    remote = ray.remote(num_cpus=1, max_retries=MAX_RETRIES)(task)
    pending: dict[Any, int] = {}
    shards = walks = first_walks = 0
    first = 0.0
    try:
        refs = [ray.put(a) if a is not None else None for a in args]
        if progress is not None:
            progress(f"start:{where}", 0, 0)
        start = time.perf_counter()
        queue = iter(todo)
        for shard in queue:
            pending[remote.remote(*refs, shard)] = shard
            if len(pending) >= workers:
                break
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            shard = pending.pop(ready[0])
            result = _result(ray, ready[0], shard)
            write(result)
            shards, walks = shards + 1, walks + len(result.rows)
            if shards == 1:
                first, first_walks = time.perf_counter() - start, walks
            if progress is not None:
                progress("shard", shards, walks)
            nxt = next(queue, None)
            if nxt is not None:
                pending[remote.remote(*refs, nxt)] = nxt
        return RunStats(shards, walks, time.perf_counter() - start, workers, where, first,
                        first_walks)
    finally:
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished or gone
                pass
        if started:
            ray.shutdown()


#: Signals that stop a run through ``finally`` (Ctrl-C raises KeyboardInterrupt already).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


@contextlib.contextmanager
def _exit_on_termination() -> Iterator[Callable[[], None]]:
    """While inside, :data:`STOP_SIGNALS` stop the run and exit ``128 + signal``.

    The handler raises :class:`KeyboardInterrupt`, which Ray passes on from a wait as it
    passes on Ctrl-C (any other exception it turns into ``SystemExit(1)``); whatever leaves
    the block after such a signal becomes ``SystemExit(128 + signal)``. Yields a function
    that installs the handlers again (after ``ray.init`` replaced them); the handlers from
    before are restored on the way out. Outside the main thread, where Python cannot install
    handlers, it does nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    before = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    received: list[int] = []

    def stop(signum: int, frame: Any) -> None:
        received.append(signum)
        raise KeyboardInterrupt

    def install() -> None:
        for s in STOP_SIGNALS:
            signal.signal(s, stop)

    install()
    try:
        yield install
    except BaseException:
        if received:
            raise SystemExit(128 + received[0]) from None
        raise
    finally:
        for s, handler in before.items():
            signal.signal(s, signal.SIG_DFL if handler is None else handler)


def _result(ray: Any, ref: Any, shard: int) -> ShardResult:
    """The result of shard ``shard``'s task; its own user-facing error raised as it is."""
    try:
        return ray.get(ref)
    except ray.exceptions.RayTaskError as exc:
        cause = getattr(exc, "cause", None)
        if isinstance(cause, EmotiveError):
            raise cause from None
        raise SynthError(f"shard {shard} failed on a worker ({_first_line(cause or exc)}); run "
                         "the command again to continue (finished shards are kept)") from None
    except ray.exceptions.RayError as exc:
        raise SynthError(f"shard {shard} was lost ({_first_line(exc)}); run the command again "
                         "to continue (finished shards are kept)") from None


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[-1] if text else ''}"[:300]
