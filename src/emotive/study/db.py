"""The study database: tables, engines for SQLite and PostgreSQL, migrations.

SQLAlchemy 2 (Core tables, no ORM session state to go stale across threads) with Alembic
migrations shipped in ``emotive/study/migrations``; :func:`open_database` brings any database
to the newest revision before use.

* **SQLite** (default, ``DIR/study.db``): WAL journal, ``synchronous=FULL`` (a committed
  response is in the WAL file on disk before the reply is sent, so neither a killed server nor
  a power cut loses an acknowledged answer), foreign keys on, a 30 s busy timeout.
* **PostgreSQL** by URL (``postgresql://user@host/db``, driven by psycopg 3), connections
  checked before use and opened within :data:`CONNECT_TIMEOUT_S`.

What is stored: no personal data. A participant is a random public id, the SHA-256 of their
token, their join order, condition and plan; a response is the item, stimulus, question and
value, with the submission's time, idempotency key and response time.

Tables:

* ``study_meta``: ``key`` -> ``value`` (the design fingerprint the database was made for).
* ``participants``: one row per participant.
* ``submissions``: one row per answered item (unique per participant and item, and per
  participant and idempotency key).
* ``responses``: one row per stored value (unique per participant, item and question).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import (
    Boolean,
    Column,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
    create_engine,
    event,
)
from sqlalchemy.engine import Engine, make_url
from sqlalchemy.exc import ArgumentError, OperationalError

from emotive.study.errors import StudyError

#: The database file of a study folder when no ``--db`` is given.
DEFAULT_DB_FILE = "study.db"
#: Seconds a PostgreSQL connection may take to open (then it is a storage fault: 503).
CONNECT_TIMEOUT_S = 10
#: The newest migration (``migrations/versions``).
HEAD_REVISION = "0001"

metadata = MetaData()

study_meta = Table(
    "study_meta", metadata,
    Column("key", String(64), primary_key=True),
    Column("value", Text, nullable=False),
)

participants = Table(
    "participants", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("public_id", String(32), nullable=False, unique=True),
    Column("token_hash", String(64), nullable=False, unique=True),
    Column("join_index", Integer, nullable=False, unique=True),
    Column("condition", String(64), nullable=False),
    Column("plan", Text, nullable=False),
    Column("joined_at", DateTime(timezone=True), nullable=False),
    Column("completed_at", DateTime(timezone=True), nullable=True),
    Column("excluded", Boolean, nullable=False, default=False),
    Column("exclusion_reason", String(500), nullable=False, default=""),
)

submissions = Table(
    "submissions", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("participant_id", Integer, ForeignKey("participants.id"), nullable=False),
    Column("item", Integer, nullable=False),
    Column("idempotency_key", String(128), nullable=False),
    Column("body_hash", String(64), nullable=False),
    Column("rt_ms", Integer, nullable=True),
    Column("created_at", DateTime(timezone=True), nullable=False),
    UniqueConstraint("participant_id", "item", name="uq_submission_item"),
    UniqueConstraint("participant_id", "idempotency_key", name="uq_submission_key"),
)

responses = Table(
    "responses", metadata,
    Column("id", Integer, primary_key=True, autoincrement=True),
    Column("submission_id", Integer, ForeignKey("submissions.id"), nullable=False),
    Column("participant_id", Integer, ForeignKey("participants.id"), nullable=False),
    Column("item", Integer, nullable=False),
    Column("stimulus", String(64), nullable=False),
    Column("question", String(64), nullable=False),
    Column("value_num", Float, nullable=True),
    Column("value_text", String(200), nullable=True),
    UniqueConstraint("participant_id", "item", "question", name="uq_response_question"),
)


def now() -> datetime:
    """The current time, UTC."""
    return datetime.now(UTC)


def as_utc(moment: datetime) -> datetime:
    """A stored time as an aware UTC datetime (SQLite gives naive ones)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def database_url(folder: Path, url: str | None) -> str:
    """The SQLAlchemy URL of a study's database.

    Args:
        folder: the study folder (the default database is ``folder/study.db``).
        url: ``None``, a ``sqlite:///PATH`` URL or a ``postgresql://`` URL (``postgresql+psycopg``
            is used for the latter).

    Raises:
        StudyError: a URL of another database or one that cannot be parsed.
    """
    if url is None:
        return f"sqlite:///{(folder / DEFAULT_DB_FILE).resolve()}"
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise StudyError(f"--db {url!r} is not a database URL; give sqlite:///PATH or "
                         "postgresql://USER@HOST/DB") from None
    backend = parsed.get_backend_name()
    if backend == "postgresql":
        return parsed.set(drivername="postgresql+psycopg").render_as_string(hide_password=False)
    if backend == "sqlite":
        if not parsed.database or parsed.database == ":memory:":
            raise StudyError(f"--db {url!r}: give a file (sqlite:///PATH); an in-memory "
                             "database would lose every response when the server stops")
        return url
    raise StudyError(f"--db {url!r}: only SQLite (sqlite:///PATH) and PostgreSQL "
                     "(postgresql://USER@HOST/DB) are supported")


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=FULL")
    cursor.execute("PRAGMA foreign_keys=ON")
    cursor.execute("PRAGMA busy_timeout=30000")
    cursor.close()


def make_engine(url: str, pool_size: int = 8) -> Engine:
    """An engine for ``url`` (from :func:`database_url`) with the settings of the module docstring.

    Raises:
        StudyError: the driver is not installed.
    """
    try:
        if url.startswith("sqlite"):
            engine = create_engine(url, pool_size=pool_size, max_overflow=pool_size,
                                   connect_args={"check_same_thread": False, "timeout": 30})
            event.listen(engine, "connect", _sqlite_pragmas)
            return engine
        given = "connect_timeout" in make_url(url).query  # the URL's own setting wins
        return create_engine(url, pool_size=pool_size, max_overflow=pool_size,
                             pool_pre_ping=True,
                             connect_args={} if given else {"connect_timeout": CONNECT_TIMEOUT_S})
    except ImportError as exc:
        raise StudyError(f"the database driver for {make_url(url).drivername} is missing "
                         f"({exc}); install it with: pip install 'emotive[study]'") from None


def backend_name(engine: Engine) -> str:
    """``"sqlite"`` or ``"postgresql"``."""
    return engine.dialect.name


def migrate(engine: Engine) -> None:
    """Bring the database to :data:`HEAD_REVISION` with the shipped Alembic migrations.

    Raises:
        StudyError: the database cannot be reached or written.
    """
    from alembic import command  # noqa: PLC0415 - Alembic loads only when a database opens
    from alembic.config import Config  # noqa: PLC0415

    config = Config()
    config.set_main_option("script_location", str(Path(__file__).with_name("migrations")))
    try:
        with engine.begin() as connection:
            config.attributes["connection"] = connection
            command.upgrade(config, "head")
    except OperationalError as exc:
        raise StudyError(f"cannot open the study database {engine.url.render_as_string()} "
                         f"({str(exc.orig).strip()}); check the path or --db URL and that "
                         "the database server runs") from None


def open_database(folder: Path, url: str | None, pool_size: int = 8) -> Engine:
    """The migrated engine of a study's database (see :func:`database_url`)."""
    engine = make_engine(database_url(folder, url), pool_size=pool_size)
    migrate(engine)
    return engine
