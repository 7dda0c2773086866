"""How ``emotive study simulate`` waits for its server: retries, backoff and the deadline.

A failed try (no reply, or a 502, 503 or 504: a server restarting, or one whose storage
fails) is retried after a backoff from :data:`FIRST_BACKOFF` doubling to :data:`MAX_BACKOFF`,
jittered by a generator seeded from the simulation's seed, and never shorter than the
server's ``Retry-After`` (429 and 503, up to :data:`MAX_RETRY_AFTER`). A request that has
failed for the deadline (default :data:`DEFAULT_DEADLINE`, longer than a server restart)
makes the run give up. :class:`Waits` keeps which requests are failing, since when and why,
and reports each wait that lasts :data:`NOTICE_AFTER` seconds, and any wait for the server to
start.
"""

from __future__ import annotations

import asyncio
import itertools
import time
from collections.abc import Callable
from typing import Any

import httpx
import numpy as np

from emotive.study.config import StudyConfig
from emotive.study.errors import ServerUnavailable, StudyError
from emotive.study.simulate_raters import _JITTER, _rng

#: Seconds a request may wait for its reply (then it is a failed try).
REQUEST_TIMEOUT = 30.0
#: Seconds of failing tries after which the run gives up: a restarting server took 10.4 to
#: 14.9 s on the 2-core development machine.
DEFAULT_DEADLINE = 60.0
#: First retry delay, seconds; doubled per retry up to :data:`MAX_BACKOFF`.
FIRST_BACKOFF = 0.05
#: Longest retry delay, seconds.
MAX_BACKOFF = 2.0
#: Longest wait a ``Retry-After`` header is honoured for, seconds.
MAX_RETRY_AFTER = 30.0
#: Replies that a server being restarted, or one whose storage fails, gives: retried until
#: the deadline.
TRANSIENT = frozenset({502, 503, 504})
#: Seconds a wait must last to be reported.
NOTICE_AFTER = 1.0
#: Waits listed in the summary at most (the first ones).
MAX_WAITS = 20
#: Key of the jitter generator of the wait for the server (beyond any participant index).
_START_STREAM = 2**31

#: Called with one line when a wait begins and when it ends.
Notify = Callable[[str], None]


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


def reason_of(reply: httpx.Response) -> str:
    """A refusal's one-line reason (its JSON ``error``, else the start of its body)."""
    try:
        return str(reply.json().get("error", ""))[:200]
    except (ValueError, AttributeError):
        return reply.text[:200]


def retry_after(reply: httpx.Response | None) -> float | None:
    """The seconds of a 429's or 503's ``Retry-After`` (capped), or ``None``."""
    if reply is None or reply.status_code not in (429, 503):
        return None
    try:
        return min(max(float(reply.headers.get("retry-after", "")), 0.0), MAX_RETRY_AFTER)
    except ValueError:
        return None


def no_reply(exc: httpx.TransportError) -> str:
    """Why a request got no reply, in one line."""
    detail = " ".join(str(exc).split())[:200] or "no detail"
    return f"no reply ({type(exc).__name__}: {detail})"


def backoff(attempt: int, jitter: np.random.Generator) -> float:
    """Seconds before retry number ``attempt`` (0 first): capped doubling, jittered."""
    return min(FIRST_BACKOFF * 2.0 ** min(attempt, 10), MAX_BACKOFF) * float(
        jitter.uniform(0.5, 1.0))


class Waits:
    """The run's waits: requests failing since when and why, the deadline, what to report.

    A wait lasts while at least one request is being retried after no reply or a transient
    5xx; it is reported once it lasted :data:`NOTICE_AFTER` seconds.
    """

    def __init__(self, url: str, deadline: float, notify: Notify | None) -> None:
        self.url, self.deadline, self.notify = url, deadline, notify
        self.failing: dict[object, tuple[float, str]] = {}
        self.started: float | None = None
        self.why = ""
        self.noticed = False
        self.done: list[dict[str, Any]] = []
        self.gave_up: str | None = None

    def failed(self, request: object, why: str) -> None:
        """``request`` failed again (a new wait begins if none was going on)."""
        now = time.monotonic()
        since = self.failing.get(request, (now, why))[0]
        self.failing[request] = (since, why)
        if self.started is None:
            self.started, self.why, self.noticed = now, why, False

    def answered(self, request: object) -> None:
        """``request`` got a reply or ended; the wait ends when no request fails any more."""
        self.failing.pop(request, None)
        if self.failing or self.started is None:
            return
        self._close(time.monotonic())
        if self.noticed and self.notify is not None:
            self.notify(f"the study server at {self.url} answers again")

    def add(self, why: str, seconds: float, always: bool = False) -> None:
        """Record a wait of ``seconds``: one of :data:`NOTICE_AFTER` or more, or ``always``."""
        if (always or seconds >= NOTICE_AFTER) and len(self.done) < MAX_WAITS:
            self.done.append({"for": why, "seconds": round(seconds, 3)})

    def _close(self, now: float) -> None:
        assert self.started is not None
        self.add(self.why, now - self.started)
        self.started = None

    def expired(self) -> bool:
        """Whether a request has failed for ``deadline`` seconds (then :attr:`gave_up`)."""
        if self.started is None:
            return False
        now = time.monotonic()
        if not self.noticed and now - self.started >= NOTICE_AFTER:
            self.noticed = True
            if self.notify is not None:
                self.notify(f"waiting for the study server at {self.url}: {self.why} (giving "
                            f"up after {self.deadline:g} s)")
        since, why = min(self.failing.values(), default=(now, self.why))
        if now - since < self.deadline:
            return False
        self.gave_up = f"{why}, for {self.deadline:g} s"
        self._close(now)
        return True


async def wait_for_server(client: httpx.AsyncClient, study: StudyConfig, url: str,
                           waits: Waits, seed: int) -> None:
    """Ask for the study until a reply that is not transient, for at most the deadline.

    Raises:
        ServerUnavailable: no such reply within the deadline.
        StudyError: the reply is not this study's server's.
    """
    jitter = _rng(seed, _START_STREAM, _JITTER)
    start = f"start it with `emotive study serve {study.folder}`"
    began = time.monotonic()
    for attempt in itertools.count():
        try:
            reply = await client.get("/api/study")
        except httpx.TransportError as exc:
            why = no_reply(exc)
        else:
            if reply.status_code not in TRANSIENT:
                break
            why = f"{reply.status_code} {reason_of(reply)}"
        waited = time.monotonic() - began
        if waited >= waits.deadline:
            waits.add(f"GET /api/study: {why}", waited, always=True)
            raise ServerUnavailable(
                f"no study server at {url} within --deadline {waits.deadline:g} s ({attempt + 1} "
                f"tries, the last: {why}); {start}, or give a longer --deadline")
        if attempt == 0 and waits.notify is not None:
            waits.notify(f"waiting for the study server at {url}: {why} (giving up after "
                         f"{waits.deadline:g} s)")
        await asyncio.sleep(min(backoff(attempt, jitter), waits.deadline - waited))
    if attempt:
        waits.add(f"GET /api/study: {why}", time.monotonic() - began, always=True)
        if waits.notify is not None:
            waits.notify(f"the study server at {url} answers after "
                         f"{time.monotonic() - began:.1f} s")
    check_study(reply, study, url, start)


def check_study(reply: httpx.Response, study: StudyConfig, url: str, start: str) -> None:
    """Refuse a ``GET /api/study`` reply that is not this study's server's.

    Raises:
        StudyError: another server, API version, study or version of the study.
    """
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
