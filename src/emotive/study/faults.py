"""Storage faults of the study server: a database that cannot store now, and whether it can.

A request that fails because of the storage, not because of what it asked, is answered
``503`` with a one-line reason and a ``Retry-After`` header (:data:`RETRY_AFTER_S`); the
participant's page and ``emotive study simulate`` send it again with the same idempotency
key, so an answer is stored once whatever the number of tries. The failed transaction was
rolled back, so nothing of a refused request is stored.

What counts (:func:`storage_fault`): SQLAlchemy's ``OperationalError`` and ``InterfaceError``
(SQLite's "database or disk is full", "attempt to write a readonly database", "unable to open
database file", "disk I/O error", "database is locked"; PostgreSQL's failed or lost
connections, a full disk and a server shutting down), the connection pool's ``TimeoutError``,
and a PostgreSQL error of SQLSTATE class 08 (connection), 53 (insufficient resources) or 57
(operator intervention), or 25006 (a read-only transaction: a standby, or
``default_transaction_read_only``). Any other database error is a bug and stays a 500.

:class:`WriteHealth` is what ``/api/health`` reports: the database takes writes until a
storage fault, and again after the next write that succeeds, a participant's or the health
check's own test write (:func:`probe_write`), made when the database was failing or when no
write has succeeded for :data:`PROBE_INTERVAL_S`. The log gets one line when the database
stops taking writes, one a minute while it takes none, and one when it takes them again: no
traceback per request, as a full disk may be where the log goes too.
"""

from __future__ import annotations

import logging
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import delete, insert
from sqlalchemy import exc as sa_exc
from sqlalchemy.engine import Engine

from emotive.study import db

#: Seconds a client is asked to wait before sending a request refused by a storage fault.
RETRY_AFTER_S = 5
#: Seconds without a successful write after which ``/api/health`` makes a test write.
PROBE_INTERVAL_S = 10.0
#: Bytes of the health check's test write: more than one submission ever needs (16 SQLite
#: pages of 4 KiB), so a database that takes the test write takes the next submission.
PROBE_BYTES = 65_536
#: Seconds between the log lines of a database that still takes no writes.
LOG_EVERY_S = 60.0
#: The key prefix of the test writes' rows in ``study_meta`` (each is deleted at once).
PROBE_KEY = "write-probe"
#: What a participant is told, by kind of fault (the driver's words go to the log only).
REASONS = {
    "full": "the study database is full (no space left)",
    "read-only": "the study database is read-only",
    "unreachable": "the study database cannot be reached",
    "busy": "the study database is busy",
    "failing": "the study database failed to store",
}
#: SQLSTATE classes of PostgreSQL errors that are storage faults (see the module docstring).
_SQLSTATE_CLASSES = ("08", "53", "57")

logger = logging.getLogger("emotive.study")


@dataclass(frozen=True)
class StorageFault:
    """Why the database cannot serve a request now.

    Attributes:
        kind: a key of :data:`REASONS`.
        detail: the driver's message, first line (for the log: it may name paths and hosts).
    """

    kind: str
    detail: str

    @property
    def reason(self) -> str:
        """The one-line reason a client is given."""
        return REASONS[self.kind]


def _first_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return (text[0] if text else type(error).__name__)[:300]


def _kind(text: str, sqlstate: str, code: str) -> str:
    if code == "SQLITE_FULL" or sqlstate == "53100" or "full" in text or "no space" in text:
        return "full"
    if code.startswith("SQLITE_READONLY") or sqlstate == "25006" or "readonly" in text \
            or "read-only" in text:
        return "read-only"
    if code.startswith(("SQLITE_BUSY", "SQLITE_LOCKED")) or "locked" in text:
        return "busy"
    if code == "SQLITE_CANTOPEN" or sqlstate.startswith(("08", "57")) or "unable to open" \
            in text or "connect" in text or "closed" in text:
        return "unreachable"
    return "failing"


def storage_fault(error: BaseException) -> StorageFault | None:
    """The storage fault behind a database error, or ``None`` for any other error."""
    if isinstance(error, sa_exc.TimeoutError):
        return StorageFault("busy", _first_line(error))
    if not isinstance(error, sa_exc.DBAPIError):
        return None
    orig = error.orig if error.orig is not None else error
    sqlstate = str(getattr(orig, "sqlstate", None) or "")
    code = str(getattr(orig, "sqlite_errorname", None) or "")
    if not (isinstance(error, sa_exc.OperationalError | sa_exc.InterfaceError)
            or error.connection_invalidated or sqlstate == "25006"
            or sqlstate.startswith(_SQLSTATE_CLASSES)):
        return None
    detail = _first_line(orig)
    return StorageFault(_kind(detail.lower(), sqlstate, code), detail)


def probe_write(engine: Engine) -> None:
    """Commit a row of :data:`PROBE_BYTES` to ``study_meta``, then delete it.

    Raises:
        sqlalchemy.exc.DBAPIError: the database cannot store it (see :func:`storage_fault`).
    """
    key = f"{PROBE_KEY}-{secrets.token_hex(8)}"
    meta = db.study_meta
    with engine.begin() as conn:
        conn.execute(insert(meta).values(key=key, value=secrets.token_hex(PROBE_BYTES // 2)))
    with engine.begin() as conn:
        conn.execute(delete(meta).where(meta.c.key.startswith(PROBE_KEY)))


class WriteHealth:
    """Whether the study database takes writes, as the server last saw it.

    Used from the server's event loop only (the routes record what their database calls did
    once the call is back), so it needs no lock.

    Args:
        clock: seconds, monotonic (tests give their own).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.fault: StorageFault | None = None
        self.failing_since: float | None = None
        self.last_write: float | None = None
        self.refused = 0
        self._refused_logged = 0
        self._logged_at = 0.0

    @property
    def writable(self) -> bool:
        """No storage fault since the last successful write."""
        return self.fault is None

    def probe_due(self) -> bool:
        """Whether the health check should make a test write (see the module docstring)."""
        return (self.fault is not None or self.last_write is None
                or self.clock() - self.last_write >= PROBE_INTERVAL_S)

    def wrote(self) -> None:
        """A write succeeded: the database takes writes (again)."""
        now = self.clock()
        if self.fault is not None and self.failing_since is not None:
            logger.warning("the study database takes writes again after %.1f s; %d request(s) "
                           "were refused meanwhile (answered 503)", now - self.failing_since,
                           self.refused)
        self.fault, self.failing_since, self.last_write = None, None, now
        self.refused = self._refused_logged = 0

    def failed(self, fault: StorageFault, where: str, refused: bool = True) -> None:
        """A database call failed with ``fault``; ``refused``: a request was answered 503."""
        now = self.clock()
        self.refused += int(refused)
        if self.fault is None or fault.kind != self.fault.kind:
            if self.failing_since is None:
                self.failing_since = now
            self.fault, self._logged_at, self._refused_logged = fault, now, self.refused
            logger.warning("the study database takes no writes (%s, at %s: %s); answering 503 "
                           "with Retry-After: %d until it does", fault.reason, where,
                           fault.detail, RETRY_AFTER_S)
        elif now - self._logged_at >= LOG_EVERY_S:
            logger.warning("the study database still takes no writes (%s): %d request(s) "
                           "refused in the last %.0f s", fault.detail,
                           self.refused - self._refused_logged, now - self._logged_at)
            self._logged_at, self._refused_logged = now, self.refused
