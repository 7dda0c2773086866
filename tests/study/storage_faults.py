"""Storage faults of a study server's database, switched on and off by the test.

Each acts on every connection the engine's pool hands out (the ``checkout`` event), so it
holds for the server's next database call, and heals the same way, without a restart:

* ``full`` on SQLite: ``PRAGMA max_page_count`` at the database's current size (SQLite
  never sets it lower), so a write that needs a new page fails with SQLite's own "database or
  disk is full", as on a full disk: a real full database, without root or a mount. Healing
  gives back the default limit (space freed).
* ``read-only`` on SQLite: ``PRAGMA query_only`` ("attempt to write a readonly database").
* ``read-only`` on PostgreSQL: the session's ``default_transaction_read_only``, the refusal
  of a standby or of an administrator's setting (SQLSTATE 25006).
* ``full`` on PostgreSQL (simulated: filling a shared test server's disk is not an option):
  every ``INSERT``, ``UPDATE`` and ``DELETE`` raises psycopg's ``DiskFull`` (SQLSTATE 53100)
  as the server does when it cannot extend a file.

:mod:`disk_faults` fails files written through :mod:`emotive.io.atomic`; a database writes
its own files, so it does not reach them.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import event
from sqlalchemy.engine import Engine

#: SQLite's largest page count (its default limit).
SQLITE_MAX_PAGES = 4_294_967_294
#: The faults this module makes.
KINDS = ("full", "read-only")


class DatabaseFault:
    """A storage fault of ``engine``'s database, off until :meth:`fail`.

    Args:
        engine: the study server's engine (``app.state.study.engine``).
        kind: ``"full"`` or ``"read-only"`` (see the module docstring).
    """

    def __init__(self, engine: Engine, kind: str) -> None:
        assert kind in KINDS, kind
        self.engine, self.kind, self.active = engine, kind, False
        self.backend = engine.dialect.name
        event.listen(engine, "checkout", self._apply)
        if self.backend == "postgresql" and kind == "full":
            event.listen(engine, "before_cursor_execute", self._disk_full)

    def fail(self) -> None:
        """From the next database call on, writes fail."""
        self.active = True

    def heal(self) -> None:
        """From the next database call on, writes succeed again."""
        self.active = False

    def remove(self) -> None:
        """Take the event hooks off the engine (the fault must be healed)."""
        event.remove(self.engine, "checkout", self._apply)
        if self.backend == "postgresql" and self.kind == "full":
            event.remove(self.engine, "before_cursor_execute", self._disk_full)

    def _apply(self, dbapi_connection: Any, _record: Any, _proxy: Any) -> None:
        cursor = dbapi_connection.cursor()
        if self.backend == "sqlite" and self.kind == "full":
            # max_page_count = 1 becomes the database's current size.
            cursor.execute(f"PRAGMA max_page_count = {1 if self.active else SQLITE_MAX_PAGES}")
        elif self.backend == "sqlite":
            cursor.execute(f"PRAGMA query_only = {int(self.active)}")
        elif self.kind == "read-only":
            # Takes effect from the next transaction: end this one at once.
            cursor.execute(f"SET default_transaction_read_only = {'on' if self.active else 'off'}")
            dbapi_connection.commit()
        cursor.close()

    def _disk_full(self, _conn: Any, _cursor: Any, statement: str, *_args: Any) -> None:
        if self.active and statement.lstrip().split(None, 1)[0].upper() in (
                "INSERT", "UPDATE", "DELETE"):
            import psycopg.errors

            raise psycopg.errors.DiskFull('could not extend file "base/16384/16400": No space '
                                          "left on device")
