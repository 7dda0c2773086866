"""A real server for tests and benchmarks: uvicorn in a background thread on 127.0.0.1.

Example::

    with running_server(max_agents=50) as url:      # "http://127.0.0.1:PORT"
        httpx.get(f"{url}/api/health")
        # websocket: url.replace("http", "ws", 1) + "/ws"
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from emotive.serve.app import create_app
from emotive.serve.errors import ServeError
from emotive.serve.server import base_url, bind, bound_port, uvicorn_server
from emotive.serve.settings import ServeSettings

#: Seconds to wait for the server to start or stop.
START_TIMEOUT = 60.0


@contextmanager
def running_server(**settings: Any) -> Iterator[str]:
    """Start the real server on a free loopback port; yield its base URL; stop it on exit.

    Args:
        **settings: any field of :class:`~emotive.serve.settings.ServeSettings` but ``host``
            and ``port`` (always ``127.0.0.1`` and a free port): ``token``, ``model``
            (``"gait"``, ``"fcrbm"``), ``backend`` (``"torch"``, ``"onnx"``), ``seed``,
            ``scene`` (a scene file: its crowd, ``--scene``),
            ``max_agents`` (500), ``max_agents_per_client`` (200), ``max_message_bytes``
            (1,000,000), ``max_depth`` (64), ``max_values`` (25,000), ``rate`` (100
            messages/s), ``burst`` (200), ``server_rate`` (500 messages/s),
            ``work_per_second`` (0.1 s per second of scene time), ``work_burst`` (0.5 s),
            ``queued_messages`` (32), ``queued_megabytes`` (1), ``buffered_frames`` (2),
            ``max_backlog_frames`` (60), ``max_replies`` (1000), ``recording_seconds`` (600),
            ``recording_megabytes`` (256), ``kept_recordings`` (16).

    Yields:
        ``"http://127.0.0.1:PORT"``.

    Raises:
        ServeError: an unknown setting, bad settings, or a server that did not start.
    """
    unknown = set(settings) - set(ServeSettings.names()) | ({"host", "port"} & set(settings))
    if unknown:
        usable = [n for n in ServeSettings.names() if n not in ("host", "port")]
        raise ServeError(f"running_server: unknown or fixed settings {sorted(unknown)}; "
                         f"use {', '.join(usable)}")
    sock = bind("127.0.0.1", 0)
    config = ServeSettings(host="127.0.0.1", port=bound_port(sock), **settings)
    try:
        app = create_app(config)
    except BaseException:
        sock.close()
        raise
    server = uvicorn_server(app, config.checked())
    failure: list[BaseException] = []

    def serve() -> None:
        try:
            asyncio.run(server.serve(sockets=[sock]))
        except BaseException as exc:  # reported to the caller below
            failure.append(exc)

    thread = threading.Thread(target=serve, name="emotive-test-server", daemon=True)
    thread.start()
    deadline = time.monotonic() + START_TIMEOUT
    while not server.started and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)
    try:
        if not server.started:
            raise ServeError(f"the test server did not start: {failure or 'timed out'}")
        yield base_url("127.0.0.1", config.port)
    finally:
        server.should_exit = True
        thread.join(START_TIMEOUT)
        sock.close()
