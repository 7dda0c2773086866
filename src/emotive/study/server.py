"""Running the study app on uvicorn.

The listening socket comes from :func:`emotive.serve.server.bind`, which turns a busy port or
a foreign address into one clear error.
"""

from __future__ import annotations

import uvicorn
from fastapi import FastAPI

#: Seconds uvicorn waits for open requests when stopping.
GRACEFUL_SHUTDOWN = 5.0


def study_uvicorn(app: FastAPI, log_level: str = "warning") -> uvicorn.Server:
    """A uvicorn server for the study app (run it with ``server.run(sockets=[sock])``)."""
    config = uvicorn.Config(app, lifespan="off", log_level=log_level, access_log=False,
                            timeout_graceful_shutdown=GRACEFUL_SHUTDOWN,
                            limit_concurrency=1000, backlog=2048)
    return uvicorn.Server(config)
