"""A real study server for tests and benchmarks: uvicorn in a background thread on 127.0.0.1.

Example::

    with running_study_server(folder, admin_token="secret") as url:  # "http://127.0.0.1:PORT"
        httpx.get(f"{url}/api/health")
"""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fastapi import FastAPI

from emotive.serve.server import base_url, bind, bound_port
from emotive.study.app import create_app
from emotive.study.errors import StudyError
from emotive.study.server import study_uvicorn

#: Seconds to wait for the server to start or stop (a hang guard).
START_TIMEOUT = 60.0


@contextmanager
def running_study_server(folder: str | Path, admin_token: str | None = None,
                         db_url: str | None = None) -> Iterator[str]:
    """Serve the study in ``folder`` on a free loopback port; yield its base URL; stop on exit.

    Raises:
        StudyError: the server did not start.
    """
    app = create_app(folder, db_url=db_url, admin_token=admin_token)
    try:
        with serving(app) as url:
            yield url
    finally:
        app.state.study.engine.dispose()


@contextmanager
def serving(app: FastAPI, sock: socket.socket | None = None) -> Iterator[str]:
    """Serve a study app (:func:`~emotive.study.app.create_app`) until the block ends.

    Args:
        app: the app; its engine stays open (the caller disposes of it).
        sock: a socket bound on 127.0.0.1, listening or not (its port is served, so a
            server can stop and another start on the same address), or ``None`` for a free
            port. It is closed when the block ends.

    Yields:
        The base URL, ``http://127.0.0.1:PORT``.

    Raises:
        StudyError: the server did not start.
    """
    sock = bind("127.0.0.1", 0) if sock is None else sock
    port = bound_port(sock)
    server = study_uvicorn(app)
    failure: list[BaseException] = []
    started = threading.Event()

    def serve() -> None:
        try:
            asyncio.run(server.serve(sockets=[sock]))
        except BaseException as exc:  # reported to the caller below
            failure.append(exc)
        finally:
            started.set()

    thread = threading.Thread(target=serve, name="emotive-study-server", daemon=True)
    thread.start()
    watcher = threading.Thread(target=lambda: _wait_started(server, started), daemon=True)
    watcher.start()
    started.wait(START_TIMEOUT)
    try:
        if not server.started:
            raise StudyError(f"the study server did not start: {failure or 'timed out'}")
        yield base_url("127.0.0.1", port)
    finally:
        server.should_exit = True
        thread.join(START_TIMEOUT)
        sock.close()


def _wait_started(server: object, started: threading.Event) -> None:
    while not getattr(server, "started", False) and not started.is_set():
        started.wait(0.01)
    started.set()
