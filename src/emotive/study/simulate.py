"""``emotive study simulate``: simulated participants through the study server's HTTP API.

Each simulated participant does what the participant page does (``docs/study-protocol.md``):
``GET /api/study``, ``POST /api/participants`` with consent, ``GET /api/plan``, one
``POST /api/responses`` per item with a fresh ``Idempotency-Key``, then ``POST /api/complete``.
``participants`` of them run, at most ``concurrency`` at a time, on one event loop sharing one
HTTP/1.1 client.

**Answers** (:mod:`emotive.study.simulate_raters`): careful raters answer from the
classifier's reading of each stimulus with rater noise and pass the attention checks; a
``careless`` share answer at random and fail them. Every draw is a function of ``(seed,
participant index in the simulation, item)``.

**Reliability.** A request that gets no reply (a connection error or timeout), a 5xx or a 429
is sent again, a submission with the *same* ``Idempotency-Key`` and body, so a retried
submission is stored once; a replayed reply (``200 "replayed": true``) acknowledges it. The
wait before a retry grows from :data:`FIRST_BACKOFF` to :data:`MAX_BACKOFF` (doubling),
jittered by a generator seeded from ``(seed, participant)``, and is at least the server's
``Retry-After`` (429, 503). No reply, 502, 503 and 504 are what a restarting server, a full
disk or a lost database give: such a request is retried until it has failed for ``deadline``
seconds (default :data:`DEFAULT_DEADLINE`, longer than a server restart). Then the run gives
up: every participant stops and the summary says ``"server_gone": true`` and why
(``gave_up``). Any other 5xx is a server bug, tried :data:`MAX_SERVER_ERRORS` times. Waiting
for the server to start is the same: it is asked for the study until ``deadline``, then
:class:`~emotive.study.errors.ServerUnavailable`. Each wait that lasted a second or more is
reported (``notify`` and the summary's ``waits``). Only values the server confirmed are
counted (``acknowledged``) and written to the receipts file.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import time
import uuid
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import httpx
import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from emotive.study.config import AttentionCheck, StudyConfig, stored_values
from emotive.study.errors import StudyError
from emotive.study.simulate_raters import (
    _JITTER,
    Rater,
    _rng,
    check_items,
    draw_answers,
    find_check,
    rater_for,
    stimulus_reading,
)
from emotive.study.simulate_wait import (
    DEFAULT_DEADLINE,
    REQUEST_TIMEOUT,
    TRANSIENT,
    Notify,
    Waits,
    backoff,
    base_url,
    no_reply,
    reason_of,
    retry_after,
    wait_for_server,
)

#: Tries of a request answered another 5xx (a server bug; then it is refused).
MAX_SERVER_ERRORS = 20
#: Seconds between checks of the deadline.
WATCH_INTERVAL = 0.1


class _Gone(Exception):
    """The server went away; the participant stops."""


@dataclass
class _Stats:
    acknowledged: int = 0
    submissions: int = 0
    joined: int = 0
    completed: int = 0
    careless: list[str] = field(default_factory=list)
    rejected: int = 0
    first_rejection: str | None = None
    retries: int = 0
    latencies_ms: list[float] = field(default_factory=list)


class _Run:
    """One simulation: the shared client, counters, the server-gone watch and the receipts."""

    def __init__(self, client: httpx.AsyncClient, study: StudyConfig, seed: int,
                 careless: float, readings: Mapping[str, Any] | None, waits: Waits,
                 receipts: IO[str] | None, bar: _Bar) -> None:
        self.client, self.study, self.seed, self.careless = client, study, seed, careless
        self.readings, self.waits, self.receipts, self.bar = readings, waits, receipts, bar
        self.stats = _Stats()
        self.gone = asyncio.Event()
        self.started = time.perf_counter()
        self._checks: dict[str, dict[int, AttentionCheck]] = {}

    async def watch(self) -> None:
        """Set :attr:`gone` once a request has failed for the deadline."""
        while not self.gone.is_set():
            if self.waits.expired():
                self.gone.set()
                return
            await asyncio.sleep(WATCH_INTERVAL)

    # -- requests ------------------------------------------------------------------------------

    async def send(self, method: str, path: str, jitter: np.random.Generator,
                   token: str | None = None, body: Any = None, key: str | None = None
                   ) -> tuple[httpx.Response, float]:
        """Send until a reply that is neither 5xx nor 429 (see the module docstring).

        Returns:
            The reply and the seconds its request took.

        Raises:
            _Gone: the run gave up (a request failed for the deadline).
        """
        headers = {}
        if token is not None:
            headers["Authorization"] = f"Bearer {token}"
        if key is not None:
            headers["Idempotency-Key"] = key
        server_errors = 0
        me = object()
        try:
            for attempt in itertools.count():
                if self.gone.is_set():
                    raise _Gone
                reply: httpx.Response | None = None
                start = time.perf_counter()
                try:
                    reply = await self.client.request(method, path, json=body, headers=headers)
                except httpx.TransportError as exc:
                    self.waits.failed(me, f"{method} {path}: {no_reply(exc)}")
                else:
                    seconds = time.perf_counter() - start
                    status = reply.status_code
                    if status in TRANSIENT:
                        self.waits.failed(me, f"{method} {path}: {status} {reason_of(reply)}")
                    else:
                        self.waits.answered(me)  # there: a reply, a 429 (busy) or a bug
                        if status < 500 and status != 429:
                            return reply, seconds
                        server_errors += status >= 500
                        if server_errors >= MAX_SERVER_ERRORS:
                            return reply, seconds
                self.stats.retries += 1
                pause = backoff(attempt, jitter)
                delay = retry_after(reply)
                await asyncio.sleep(pause if delay is None else max(delay, pause))
        finally:
            self.waits.answered(me)
        raise AssertionError("unreachable")  # pragma: no cover

    def refuse(self, what: str, reply: httpx.Response) -> None:
        """Count a refused request and keep the first reason."""
        self.stats.rejected += 1
        if self.stats.first_rejection is None:
            self.stats.first_rejection = f"{what}: {reply.status_code} {reason_of(reply)}"

    # -- participants --------------------------------------------------------------------------

    def checks_of(self, condition: str) -> dict[int, AttentionCheck]:
        """Attention checks by item number in a condition's plans (cached)."""
        if condition not in self._checks:
            self._checks[condition] = check_items(self.study, condition)
        return self._checks[condition]

    async def participant(self, index: int) -> None:
        """One simulated participant from consent to completion."""
        rater = rater_for(self.seed, index, self.careless)
        jitter = _rng(self.seed, index, _JITTER)
        reply, _ = await self.send("GET", "/api/study", jitter)
        if reply.status_code != 200:
            self.refuse("GET /api/study", reply)
            return
        reply, _ = await self.send("POST", "/api/participants", jitter, body={"consent": True})
        if reply.status_code != 201:
            self.refuse("POST /api/participants", reply)
            return
        joined = reply.json()
        token, public_id = str(joined["token"]), str(joined["participant"])
        self.stats.joined += 1
        if rater.careless:
            self.stats.careless.append(public_id)
        reply, _ = await self.send("GET", "/api/plan", jitter, token=token)
        if reply.status_code != 200:
            self.refuse("GET /api/plan", reply)
            return
        plan = reply.json()
        at = self.checks_of(str(plan.get("condition", "")))
        answered = set(plan.get("answered") or ())
        for item in plan["items"]:
            if item["item"] not in answered:
                await self.submit(rater, public_id, token, item, find_check(self.study, at, item),
                                  jitter)
        reply, _ = await self.send("POST", "/api/complete", jitter, token=token, body={})
        if reply.status_code == 200:
            self.stats.completed += 1
        else:
            self.refuse("POST /api/complete", reply)

    async def submit(self, rater: Rater, public_id: str, token: str, item: Mapping[str, Any],
                     check: AttentionCheck | None, jitter: np.random.Generator) -> None:
        """Answer one item; count and record it once the server confirmed it."""
        number, stimulus = int(item["item"]), str(item["stimulus"])
        reading = stimulus_reading(self.study, self.readings, stimulus)
        answers, rt_ms = draw_answers(self.study, rater, self.seed, number, reading, check)
        key = uuid.uuid4().hex
        body = {"item": number, "stimulus": stimulus, "answers": answers, "rt_ms": rt_ms}
        reply, seconds = await self.send("POST", "/api/responses", jitter, token=token,
                                         body=body, key=key)
        if reply.status_code not in (200, 201):
            self.refuse("POST /api/responses", reply)
            return
        values: dict[str, Any] = {}
        for question in self.study.questions:
            values.update(stored_values(question, answers[question.id]))
        stored = reply.json().get("stored", len(values))
        # No await from here on: a cancelled run never counts a submission it did not record.
        self.stats.acknowledged += int(stored)
        self.stats.submissions += 1
        self.stats.latencies_ms.append(1000.0 * seconds)
        if self.receipts is not None:
            line = json.dumps({"participant": public_id, "index": rater.index, "item": number,
                               "stimulus": stimulus, "values": values, "key": key})
            try:
                self.receipts.write(line + "\n")
                self.receipts.flush()
            except OSError as exc:
                raise StudyError(f"--receipts {self.receipts.name}: cannot write ({exc}); free "
                                 "space or give another file") from None
        self.bar.submitted(self.stats.submissions, self.rate())

    def rate(self) -> float:
        """Acknowledged values per second so far."""
        return self.stats.acknowledged / max(time.perf_counter() - self.started, 1e-9)

    async def worker(self, indices: Iterator[int]) -> None:
        """Run participants from ``indices`` one after another until none is left."""
        for index in indices:
            if self.gone.is_set():
                return
            try:
                await self.participant(index)
            except _Gone:
                return
            except (ValueError, KeyError, TypeError, AttributeError, httpx.HTTPError) as exc:
                # A reply outside the protocol: this participant stops, the others go on.
                self.stats.rejected += 1
                if self.stats.first_rejection is None:
                    self.stats.first_rejection = f"a reply outside the protocol ({exc!r})"
            self.bar.participant_done()

    def summary(self, participants: int) -> dict[str, Any]:
        """The summary line's fields (see :func:`run_simulation`)."""
        s = self.stats
        seconds = time.perf_counter() - self.started
        latencies = np.asarray(s.latencies_ms)
        p50 = round(float(np.percentile(latencies, 50)), 2) if latencies.size else None
        p99 = round(float(np.percentile(latencies, 99)), 2) if latencies.size else None
        return {"acknowledged": s.acknowledged, "submissions": s.submissions,
                "participants": s.joined, "simulated": participants, "completed": s.completed,
                "careless": sorted(s.careless), "rejected": s.rejected,
                "first_rejection": s.first_rejection, "retries": s.retries,
                "server_gone": self.gone.is_set(), "gave_up": self.waits.gave_up,
                "deadline_s": self.waits.deadline, "waits": self.waits.done,
                "p50_ms": p50, "p99_ms": p99,
                "responses_per_s": round(s.acknowledged / max(seconds, 1e-9), 2),
                "seconds": round(seconds, 3)}


class _Bar:
    """Progress on stderr (rich): participants done, submissions, responses per second."""

    def __init__(self, participants: int, show: bool) -> None:
        self.progress: Progress | None = None
        if show:
            self.progress = Progress(
                TextColumn("simulated participants"), BarColumn(), MofNCompleteColumn(),
                TextColumn("{task.fields[submissions]} submissions, "
                           "{task.fields[rate]:.0f} responses/s"), TimeElapsedColumn(),
                console=Console(stderr=True), transient=False)
            self.task = self.progress.add_task("simulate", total=participants, submissions=0,
                                               rate=0.0)

    def __enter__(self) -> _Bar:
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.progress is not None:
            self.progress.stop()

    def participant_done(self) -> None:
        """One more participant finished."""
        if self.progress is not None:
            self.progress.advance(self.task)

    def submitted(self, submissions: int, rate: float) -> None:
        """Show the submissions so far and the rate of acknowledged values."""
        if self.progress is not None:
            self.progress.update(self.task, submissions=submissions, rate=rate)


def _open_receipts(path: Path) -> IO[str]:
    try:
        return Path(path).open("a", encoding="utf-8")
    except OSError as exc:
        raise StudyError(f"--receipts {path}: cannot write there ({exc.strerror or exc}); give "
                         "a file in an existing, writable folder") from None


async def _run_workers(run: _Run, participants: int, workers: int) -> None:
    """Run every participant on ``workers`` tasks; stop them all once the server is gone.

    Raises:
        StudyError: the receipts could not be written.
    """
    indices = iter(range(participants))
    tasks = [asyncio.create_task(run.worker(indices)) for _ in range(workers)]
    watch = asyncio.create_task(run.watch())
    gone = asyncio.create_task(run.gone.wait())
    everyone = asyncio.gather(*tasks)
    await asyncio.wait({everyone, gone}, return_when=asyncio.FIRST_COMPLETED)
    for task in (*tasks, watch, gone):
        task.cancel()
    await asyncio.gather(everyone, watch, gone, return_exceptions=True)
    failure = next((t.exception() for t in tasks if t.done() and not t.cancelled()
                    and t.exception() is not None), None)
    if failure is not None:
        raise failure


def _check_arguments(participants: int, concurrency: int, careless: float,
                     deadline: float) -> None:
    if participants < 1:
        raise StudyError(f"--participants {participants}: give 1 or more")
    if concurrency < 1:
        raise StudyError(f"--concurrency {concurrency}: give 1 or more")
    if not 0.0 <= careless <= 1.0:
        raise StudyError(f"--careless {careless}: give a share from 0 to 1")
    if not deadline > 0:
        raise StudyError(f"--deadline {deadline:g}: give a positive number of seconds")


async def simulate(study: StudyConfig, url: str, participants: int, concurrency: int,
                   seed: int, careless: float = 0.1, readings: Mapping[str, Any] | None = None,
                   receipts: Path | None = None, progress: bool = True,
                   deadline: float = DEFAULT_DEADLINE, notify: Notify | None = None,
                   transport: httpx.AsyncBaseTransport | None = None) -> dict[str, Any]:
    """The coroutine of :func:`run_simulation` (same arguments and result).

    Args:
        study: see :func:`run_simulation`.
        url: see :func:`run_simulation`.
        participants: see :func:`run_simulation`.
        concurrency: see :func:`run_simulation`.
        seed: see :func:`run_simulation`.
        careless: see :func:`run_simulation`.
        readings: see :func:`run_simulation`.
        receipts: see :func:`run_simulation`.
        progress: see :func:`run_simulation`.
        deadline: see :func:`run_simulation`.
        notify: see :func:`run_simulation`.
        transport: an httpx transport to send through instead of the network (tests).
    """
    _check_arguments(participants, concurrency, careless, deadline)
    base = base_url(url)
    workers = min(concurrency, participants)
    limits = httpx.Limits(max_connections=workers, max_keepalive_connections=workers)
    waits = Waits(base, deadline, notify)
    async with httpx.AsyncClient(base_url=base, http1=True, http2=False, limits=limits,
                                 timeout=httpx.Timeout(REQUEST_TIMEOUT),
                                 transport=transport) as client:
        await wait_for_server(client, study, base, waits, seed)
        with contextlib.ExitStack() as stack:
            out = None if receipts is None else stack.enter_context(_open_receipts(receipts))
            bar = stack.enter_context(_Bar(participants, progress))
            run = _Run(client, study, seed, careless, readings, waits, out, bar)
            await _run_workers(run, participants, workers)
            return run.summary(participants)


def run_simulation(study: StudyConfig, url: str, participants: int, concurrency: int,
                   seed: int, careless: float = 0.1, readings: dict | None = None,
                   receipts: Path | None = None, progress: bool = True,
                   deadline: float = DEFAULT_DEADLINE, notify: Notify | None = None
                   ) -> dict[str, Any]:
    """Send simulated participants through the study server at ``url`` (module docstring).

    Args:
        study: the study (its title and questions must be the server's).
        url: the server's base URL, e.g. ``http://127.0.0.1:8000``.
        participants: simulated participants, in all.
        concurrency: participants at a time (and HTTP connections).
        seed: seed of the raters' traits and answers.
        careless: share of careless raters, 0..1.
        readings: the study's ``stimuli/readings.json`` (parsed), or ``None`` to answer from
            the intended emotions.
        receipts: a file to append one JSON line to per acknowledged submission:
            ``{"participant", "index", "item", "stimulus", "values": {name: value}, "key"}``
            (``values`` as stored: a grid's two values on -1..1), flushed once confirmed.
        progress: show progress on stderr.
        deadline: seconds a request may go on failing (no reply, 502, 503, 504) before the
            run gives up; also how long a server that is not up yet is waited for.
        notify: called with one line when a wait begins (it lasted a second) and ends.

    Returns:
        The summary: ``acknowledged`` (values the server confirmed stored), ``submissions``
        (items confirmed), ``participants`` (joined), ``simulated`` (asked for),
        ``completed``, ``careless`` (server ids of the careless raters that joined),
        ``rejected`` (requests refused: a 4xx other than 429, or a 5xx after
        :data:`MAX_SERVER_ERRORS` tries, or a reply outside the protocol),
        ``first_rejection`` (its reason, or ``None``), ``retries`` (requests sent again),
        ``server_gone`` (the run gave up at the deadline), ``gave_up`` (why, one line, or
        ``None``), ``deadline_s``, ``waits`` (each wait of a second or more: ``{"for": the
        last request's failure, "seconds"}``), ``p50_ms`` and ``p99_ms`` (milliseconds the
        confirmed submission's request took; ``None`` without any), ``responses_per_s``
        (acknowledged values per second) and ``seconds`` (wall time of the run).

    Raises:
        ServerUnavailable: no server answered at ``url`` within ``deadline``.
        StudyError: a bad ``url`` or argument, or a server of another study.
    """
    return asyncio.run(simulate(study, url, participants, concurrency, seed, careless=careless,
                                readings=readings, receipts=receipts, progress=progress,
                                deadline=deadline, notify=notify))
