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
is sent again, a submission with the *same* ``Idempotency-Key`` and body, after a backoff
(``Retry-After`` for a 429), so a retried submission is stored once; a replayed reply
(``200 "replayed": true``) acknowledges it. Once every request has failed for ``gone_after``
seconds with no reply in between, the server is taken as gone: every participant stops and
the summary says ``"server_gone": true``. Only values the server confirmed are counted
(``acknowledged``) and written to the receipts file.
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

#: Seconds a request may wait for a reply at least (longer when ``gone_after`` is longer).
REQUEST_TIMEOUT = 10.0
#: First retry delay, seconds; doubled per retry up to :data:`MAX_BACKOFF`.
FIRST_BACKOFF = 0.05
#: Longest retry delay, seconds.
MAX_BACKOFF = 2.0
#: Longest wait a ``Retry-After`` header is honoured for, seconds.
MAX_RETRY_AFTER = 30.0
#: Tries of a request answered 5xx while the server otherwise answers (then it is refused).
MAX_SERVER_ERRORS = 20
#: Seconds between checks of whether the server is gone.
WATCH_INTERVAL = 0.1
def base_url(url: str) -> str:
    """The server's base URL without a trailing ``/``.

    Raises:
        StudyError: not an ``http://`` or ``https://`` URL with a host.
    """
    fix = "give the study server's address, e.g. --url http://127.0.0.1:8000"
    try:
        parsed = httpx.URL(url)
    except (httpx.InvalidURL, TypeError) as exc:
        raise StudyError(f"--url {url!r} is not a URL ({exc}); {fix}") from None
    if parsed.scheme not in ("http", "https") or not parsed.host:
        raise StudyError(f"--url {url!r} is not an http(s) URL with a host; {fix}")
    if parsed.query or parsed.fragment:
        raise StudyError(f"--url {url!r} has a query or fragment; {fix}")
    return str(parsed).rstrip("/")


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


def _reason(reply: httpx.Response) -> str:
    try:
        return str(reply.json().get("error", ""))[:200]
    except (ValueError, AttributeError):
        return reply.text[:200]


def _retry_after(reply: httpx.Response | None) -> float | None:
    if reply is None or reply.status_code != 429:
        return None
    try:
        return min(max(float(reply.headers.get("retry-after", "")), 0.0), MAX_RETRY_AFTER)
    except ValueError:
        return None


class _Run:
    """One simulation: the shared client, counters, the server-gone watch and the receipts."""

    def __init__(self, client: httpx.AsyncClient, study: StudyConfig, seed: int,
                 careless: float, readings: Mapping[str, Any] | None, gone_after: float,
                 receipts: IO[str] | None, bar: _Bar) -> None:
        self.client, self.study, self.seed, self.careless = client, study, seed, careless
        self.readings, self.gone_after, self.receipts, self.bar = (readings, gone_after,
                                                                   receipts, bar)
        self.stats = _Stats()
        self.gone = asyncio.Event()
        self.failing_since: float | None = None
        self.started = time.perf_counter()
        self._checks: dict[str, dict[int, AttentionCheck]] = {}

    # -- the server-gone watch -----------------------------------------------------------------

    def _alive(self) -> None:
        self.failing_since = None

    def _failed(self) -> None:
        now = time.monotonic()
        if self.failing_since is None:
            self.failing_since = now
        elif now - self.failing_since >= self.gone_after:
            self.gone.set()

    async def watch(self) -> None:
        """Set :attr:`gone` once requests have failed for ``gone_after`` seconds."""
        while not self.gone.is_set():
            since = self.failing_since
            if since is not None and time.monotonic() - since >= self.gone_after:
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
            _Gone: the server went away.
        """
        headers = {}
        if token is not None:
            headers["Authorization"] = f"Bearer {token}"
        if key is not None:
            headers["Idempotency-Key"] = key
        server_errors = 0
        for attempt in itertools.count():
            if self.gone.is_set():
                raise _Gone
            reply: httpx.Response | None = None
            start = time.perf_counter()
            try:
                reply = await self.client.request(method, path, json=body, headers=headers)
            except httpx.TransportError:
                self._failed()
            else:
                seconds = time.perf_counter() - start
                if reply.status_code < 500 and reply.status_code != 429:
                    self._alive()
                    return reply, seconds
                if reply.status_code == 429:
                    self._alive()  # there, only busy
                else:
                    self._failed()
                    server_errors += 1
                    if server_errors >= MAX_SERVER_ERRORS:
                        return reply, seconds
            self.stats.retries += 1
            backoff = min(FIRST_BACKOFF * 2.0 ** min(attempt, 10), MAX_BACKOFF)
            delay = _retry_after(reply)
            wait = max(delay, backoff) if delay is not None else backoff
            await asyncio.sleep(wait * float(jitter.uniform(0.5, 1.0)))
        raise AssertionError("unreachable")  # pragma: no cover

    def refuse(self, what: str, reply: httpx.Response) -> None:
        """Count a refused request and keep the first reason."""
        self.stats.rejected += 1
        if self.stats.first_rejection is None:
            self.stats.first_rejection = f"{what}: {reply.status_code} {_reason(reply)}"

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
                "server_gone": self.gone.is_set(), "p50_ms": p50, "p99_ms": p99,
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


async def _check_server(client: httpx.AsyncClient, study: StudyConfig, url: str) -> None:
    start = f"start it with `emotive study serve {study.folder}`"
    try:
        reply = await client.get("/api/study")
    except httpx.TransportError:
        raise StudyError(f"no study server at {url}; {start}") from None
    try:
        info = reply.json() if reply.status_code == 200 else None
    except ValueError:
        info = None
    if not isinstance(info, dict) or "title" not in info:
        raise StudyError(f"{url} is not an emotive study server (GET /api/study answered "
                         f"{reply.status_code}); check --url, or {start}")
    if info.get("version") != 1:
        raise StudyError(f"{url} speaks version {info.get('version')!r} of the study API, not 1; "
                         "use the emotive that serves it")
    if info["title"] != study.title:
        raise StudyError(f"{url} serves the study {info['title']!r}, not {study.title!r} of "
                         f"{study.folder}; give the --url of this study's server")
    asked = [q.get("id") for q in info.get("questions") or () if isinstance(q, dict)]
    if asked != [q.id for q in study.questions]:
        raise StudyError(f"{url} asks the questions {asked}, not {[q.id for q in study.questions]}"
                         f" of {study.folder}: it serves another version of the study; restart "
                         "it on this folder")


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
                     gone_after: float) -> None:
    if participants < 1:
        raise StudyError(f"--participants {participants}: give 1 or more")
    if concurrency < 1:
        raise StudyError(f"--concurrency {concurrency}: give 1 or more")
    if not 0.0 <= careless <= 1.0:
        raise StudyError(f"--careless {careless}: give a share from 0 to 1")
    if not gone_after > 0:
        raise StudyError(f"gone_after {gone_after}: give a positive number of seconds")


async def simulate(study: StudyConfig, url: str, participants: int, concurrency: int,
                   seed: int, careless: float = 0.1, readings: Mapping[str, Any] | None = None,
                   receipts: Path | None = None, progress: bool = True,
                   gone_after: float = 10.0,
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
        gone_after: see :func:`run_simulation`.
        transport: an httpx transport to send through instead of the network (tests).
    """
    _check_arguments(participants, concurrency, careless, gone_after)
    base = base_url(url)
    workers = min(concurrency, participants)
    limits = httpx.Limits(max_connections=workers, max_keepalive_connections=workers)
    timeout = httpx.Timeout(max(REQUEST_TIMEOUT, gone_after))
    async with httpx.AsyncClient(base_url=base, http1=True, http2=False, limits=limits,
                                 timeout=timeout, transport=transport) as client:
        await _check_server(client, study, base)
        with contextlib.ExitStack() as stack:
            out = None if receipts is None else stack.enter_context(_open_receipts(receipts))
            bar = stack.enter_context(_Bar(participants, progress))
            run = _Run(client, study, seed, careless, readings, gone_after, out, bar)
            await _run_workers(run, participants, workers)
            return run.summary(participants)


def run_simulation(study: StudyConfig, url: str, participants: int, concurrency: int,
                   seed: int, careless: float = 0.1, readings: dict | None = None,
                   receipts: Path | None = None, progress: bool = True,
                   gone_after: float = 10.0) -> dict[str, Any]:
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
        gone_after: seconds of failing requests, with no reply in between, after which the
            server is taken as gone and the run stops.

    Returns:
        The summary: ``acknowledged`` (values the server confirmed stored), ``submissions``
        (items confirmed), ``participants`` (joined), ``simulated`` (asked for),
        ``completed``, ``careless`` (server ids of the careless raters that joined),
        ``rejected`` (requests refused: a 4xx other than 429, or a 5xx after
        :data:`MAX_SERVER_ERRORS` tries, or a reply outside the protocol),
        ``first_rejection`` (its reason, or ``None``), ``retries`` (requests sent again),
        ``server_gone``, ``p50_ms`` and ``p99_ms`` (milliseconds the confirmed submission's
        request took; ``None`` without any), ``responses_per_s`` (acknowledged values per
        second) and ``seconds`` (wall time of the run).

    Raises:
        StudyError: a bad ``url`` or argument, no server at ``url``, or a server of another
            study.
    """
    return asyncio.run(simulate(study, url, participants, concurrency, seed, careless=careless,
                                readings=readings, receipts=receipts, progress=progress,
                                gone_after=gone_after))
