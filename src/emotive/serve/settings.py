"""The server's settings: where it binds, which engine it runs, and its limits.

One frozen :class:`ServeSettings` is made by the command (or by
:func:`emotive.serve.testing.running_server`) and checked once by
:meth:`ServeSettings.checked`: a host other than a loopback address needs a token, every
limit must be positive, the model and backend must be known.
"""

from __future__ import annotations

import ipaddress
import math
import os
from dataclasses import dataclass, fields, replace

from emotive.serve.errors import ServeError

#: Models ``--model`` can name.
MODELS = ("gait", "fcrbm")
#: Backends ``--backend`` can name (ONNX Runtime runs the gait network only).
BACKENDS = ("torch", "onnx")
#: Host names that always mean this machine.
LOOPBACK_NAMES = ("localhost",)
#: Most step workers ``emotive serve`` starts by itself (each loads its own engine).
MAX_DEFAULT_WORKERS = 4
#: What ``--worker-kind`` can name.
WORKER_KINDS = ("auto", "threads", "processes")
#: Largest ``--step-budget`` (a share of the frame period).
MAX_STEP_BUDGET = 10.0


def default_workers() -> int:
    """Step workers ``emotive serve`` uses unless told.

    The cores it may run on, at most :data:`MAX_DEFAULT_WORKERS` (1: the scene steps in the
    server's own process).
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(cores, MAX_DEFAULT_WORKERS))


def is_loopback(host: str) -> bool:
    """Whether ``host`` is ``localhost`` or a loopback address (``127.0.0.0/8``, ``::1``)."""
    if host.lower() in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class ServeSettings:
    """Everything one server needs to know.

    Attributes:
        host: address to bind (default ``127.0.0.1``; any other than a loopback address
            needs ``token``).
        port: TCP port (``0``: any free port).
        token: shared secret every ``/api`` request and the websocket must present; ``None``
            for none (loopback only).
        model: ``"gait"`` (the main network) or ``"fcrbm"``.
        backend: ``"torch"`` or ``"onnx"`` (the gait agents' whole exported step,
            ``emotive export onnx --step agent``, on ONNX Runtime).
        seed: seed of the agents' starting phases (and, with a scene, of every random
            choice of its crowd).
        scene: a scene file (``scene.toml``, ``docs/crowd.md``): the server runs its crowd
            (:mod:`~emotive.serve.crowd_engine`), whose groups spawn and navigate, on the
            gait network (torch) in the simulation thread; ``None``: no scene, agents walk
            paths.
        workers: processes that step the scene's agents, each its share (1: the server's
            own simulation thread steps them all, in its process).
        worker_kind: with ``workers`` above 1, what a worker is: ``"threads"`` (threads of
            the server's process), ``"processes"``, or ``"auto"``: threads for the torch
            backend (its step releases the interpreter lock: two threads stepped 1.9 times
            as many agents as one), processes for ONNX Runtime (two threads stepped no
            more than one there; two processes 1.7 times as many).
        step_budget: share of a frame period the step of each stepping engine (the
            simulation thread's, or each worker's) may take, by its measured processor
            time, with every agent the scene admits (above 0; above 1 admits more agents
            than are stepped in a frame, so frames come late: for load tests only).
        max_agents: agents the scene may hold at once (the server may hold fewer: as many as
            its measured step time lets it step within half a frame).
        max_agents_per_client: agents one connection may have in the scene at once.
        max_message_bytes: largest control message, bytes (UTF-8).
        max_depth: deepest nesting of ``[`` and ``{`` in a control message.
        max_values: most values (commas + 1) in a control message.
        rate: control messages per second a client may send, sustained.
        burst: control messages a client may send at once (the token bucket's size).
        server_rate: control messages per second the server reads from all its clients
            together (a client over it waits its turn; bursts of one second).
        work_per_second: seconds of the server's work a client's messages may cost per second
            of scene time (frame number / fps), sustained: their preparation (parsing,
            checking, building paths and schedules; thread time) and their commands' time
            on the simulation thread (a share of each batch of new agents they join).
        work_burst: seconds of that work a client may use at once.
        queued_messages: a client's messages waiting for preparation at most; the server
            reads no more of its messages until one is prepared.
        queued_megabytes: those messages' size at most, MB.
        buffered_frames: newest frames kept for a client that reads slowly; older are dropped.
        max_backlog_frames: a client with more unread frames than this (frames made since
            the newest one it has read, while data sent to it waits unread) is disconnected
            (close code 1008).
        max_replies: replies waiting for a client at most; the server reads no more of its
            messages until it has read some.
        recording_seconds: longest recording, seconds of scene time.
        recording_megabytes: most memory one recording may hold, MB.
        kept_recordings: finished recordings kept for download (the oldest go first).
    """

    host: str = "127.0.0.1"
    port: int = 8000
    token: str | None = None
    model: str = "gait"
    backend: str = "torch"
    seed: int = 0
    scene: str | None = None
    workers: int = 1
    worker_kind: str = "auto"
    step_budget: float = 0.5
    max_agents: int = 500
    max_agents_per_client: int = 200
    max_message_bytes: int = 1_000_000
    max_depth: int = 64
    max_values: int = 25_000
    rate: float = 100.0
    burst: int = 200
    server_rate: float = 500.0
    work_per_second: float = 0.1
    work_burst: float = 0.5
    queued_messages: int = 32
    queued_megabytes: float = 1.0
    buffered_frames: int = 2
    max_backlog_frames: int = 60
    max_replies: int = 1000
    recording_seconds: float = 600.0
    recording_megabytes: float = 256.0
    kept_recordings: int = 16

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The setting names, as :func:`emotive.serve.testing.running_server` takes them."""
        return tuple(f.name for f in fields(cls))

    def checked(self) -> ServeSettings:
        """These settings, if they are usable (a token given as ``""`` becomes ``None``).

        Raises:
            ServeError: a non-loopback host without a token, an unknown model or backend, a
                scene with another model, backend or more workers than one, a port outside
                0-65535, or a limit that is not a positive number.
        """
        token = self.token or None
        if not is_loopback(self.host) and token is None:
            raise ServeError(
                f"--host {self.host} would let other machines control the server without a "
                "password: add --token SECRET (e.g. --token \"$(openssl rand -hex 16)\"), or "
                "bind 127.0.0.1")
        if self.model not in MODELS:
            raise ServeError(f"--model {self.model!r} is not a streaming model; use one of "
                             f"{', '.join(MODELS)}")
        if self.backend not in BACKENDS:
            raise ServeError(f"--backend {self.backend!r} is unknown; use one of "
                             f"{', '.join(BACKENDS)}")
        if self.backend == "onnx" and self.model != "gait":
            raise ServeError(f"--backend onnx runs the gait network only; drop it or use "
                             f"--model gait (got --model {self.model})")
        if self.scene is not None and (self.model, self.backend) != ("gait", "torch"):
            raise ServeError(f"--scene runs its crowd on the gait network on torch; drop "
                             f"--model {self.model} --backend {self.backend}")
        if self.scene is not None and self.workers != 1:
            raise ServeError(f"--scene steps its crowd in the simulation thread (navigation "
                             f"sees every agent at once); drop --workers {self.workers} or give "
                             "--workers 1")
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) \
                or not 1 <= self.workers <= 64:
            raise ServeError(f"--workers must be a whole number 1-64, got {self.workers!r} "
                             "(1: step in the server's own process)")
        if self.worker_kind not in WORKER_KINDS:
            raise ServeError(f"--worker-kind {self.worker_kind!r} is unknown; use one of "
                             f"{', '.join(WORKER_KINDS)}")
        budget = self.step_budget
        if not (isinstance(budget, int | float) and math.isfinite(budget)
                and 0 < budget <= MAX_STEP_BUDGET):
            raise ServeError(f"--step-budget is a share of a frame, above 0 and at most "
                             f"{MAX_STEP_BUDGET:g}; got {budget!r}")
        if not 0 <= self.port <= 65535:
            raise ServeError(f"--port {self.port} is not a TCP port; use 1-65535 (0: any free)")
        for name in ("max_agents", "max_agents_per_client", "max_message_bytes", "max_depth",
                     "max_values", "rate", "burst", "server_rate", "work_per_second", "work_burst",
                     "queued_messages", "queued_megabytes", "buffered_frames",
                     "max_backlog_frames", "max_replies", "recording_seconds",
                     "recording_megabytes", "kept_recordings"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                flag = name.replace("_", "-")
                raise ServeError(f"{flag} must be a positive number, got {value!r}")
        return replace(self, token=token)

    @property
    def worker_threads(self) -> bool:
        """Whether the step workers are threads (``worker_kind``, ``"auto"`` resolved)."""
        if self.worker_kind == "auto":
            return self.backend == "torch"
        return self.worker_kind == "threads"

    @property
    def ws_max_size(self) -> int:
        """Largest websocket message uvicorn accepts, bytes.

        Above :attr:`max_message_bytes`, so that a message somewhat too large still reaches
        the server and gets an ``error`` reply; a far larger one closes the connection (code
        1009).
        """
        return 2 * self.max_message_bytes + 65536
