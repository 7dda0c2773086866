"""Shared fixtures of the study tests: a small study folder, and both database backends.

``study_folder`` copies one session-made ``gaits`` study (3 stimuli of 3 s, made once by
``emotive study init``) into the test's own folder, so every test starts with an empty
database. ``db_url`` runs a test on SQLite (``None``: the folder's ``study.db``) and on
PostgreSQL: a new database on the server of ``EMOTIVE_TEST_POSTGRES_URL`` (``.ci/run`` starts
one), else on a cluster the session starts itself where Debian's ``postgresql`` is installed;
without either the PostgreSQL cases skip, and fail under ``EMOTIVE_REQUIRE_TOOLS=1``.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import uuid
from collections.abc import Iterator
from pathlib import Path

import postgres_cluster
import pytest

from tools import require_tool

#: Environment variable naming a PostgreSQL server for the tests.
POSTGRES_ENV = "EMOTIVE_TEST_POSTGRES_URL"


@pytest.fixture(scope="session")
def study_template(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from emotive.study.create import create_study

    return create_study(tmp_path_factory.mktemp("study-template") / "gaits", "gaits",
                        count=3, seconds=3.0, seed=1)


@pytest.fixture
def study_folder(study_template: Path, tmp_path: Path) -> Path:
    folder = tmp_path / "study"
    shutil.copytree(study_template, folder)
    return folder


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[str]:
    """The URL of a PostgreSQL server's ``postgres`` database."""
    given = os.environ.get(POSTGRES_ENV)
    if given:
        yield given
        return
    require_tool(postgres_cluster.bin_dir() is not None,
                 f"PostgreSQL is not installed (apt-get install postgresql), and "
                 f"{POSTGRES_ENV} is not set")
    folder = Path(tempfile.mkdtemp(prefix="emotive-pg-"))
    folder.chmod(0o755)
    try:
        yield postgres_cluster.start(folder / "cluster")
    finally:
        postgres_cluster.stop(folder / "cluster")
        shutil.rmtree(folder, ignore_errors=True)


def new_postgres_database(server: str) -> tuple[str, str]:
    """Create an empty database on ``server``; its URL and name."""
    from sqlalchemy import create_engine, text

    name = "emotive_" + uuid.uuid4().hex[:12]
    admin = server.replace("postgresql://", "postgresql+psycopg://", 1)
    engine = create_engine(admin, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    engine.dispose()
    return server.rsplit("/", 1)[0] + "/" + name, name


def drop_postgres_database(server: str, name: str) -> None:
    from sqlalchemy import create_engine, text

    admin = server.replace("postgresql://", "postgresql+psycopg://", 1)
    engine = create_engine(admin, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    engine.dispose()


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request: pytest.FixtureRequest) -> Iterator[str | None]:
    """``None`` (SQLite in the study folder) or the URL of a fresh PostgreSQL database."""
    if request.param == "sqlite":
        yield None
        return
    server = request.getfixturevalue("postgres_server")
    url, name = new_postgres_database(server)
    try:
        yield url
    finally:
        drop_postgres_database(server, name)
