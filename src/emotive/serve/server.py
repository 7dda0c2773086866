"""Running the app on uvicorn: the listening socket, the uvicorn config, the URLs.

:func:`bind` opens the listening socket first, so that a port in use or an address that is
not this machine's is a :class:`~emotive.serve.errors.ServeError` before anything starts;
:func:`uvicorn_server` configures uvicorn for the scene: the ``websockets-sansio`` protocol
(its ``send`` waits while the socket's buffer is full, so the per-client frame bound holds;
:class:`WebSocketProtocol` hands each connection's transport to the app, which measures a
client's unread backlog there), no per-message compression (every client gets the same
frame bytes, and compressing them per connection would cost more than the network step), a
maximum message size a little above the control-message limit, and a short graceful
shutdown.
"""

from __future__ import annotations

import socket
from typing import Any

import uvicorn
from fastapi import FastAPI
from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol

from emotive.serve.errors import ServeError
from emotive.serve.settings import ServeSettings

#: Seconds uvicorn waits for open connections when stopping.
GRACEFUL_SHUTDOWN = 2.0
#: The key of a websocket's ASGI scope ``extensions`` that holds its asyncio transport.
TRANSPORT_EXTENSION = "emotive.transport"


class WebSocketProtocol(WebSocketsSansIOProtocol):
    """uvicorn's ``websockets-sansio`` protocol, with the transport in the scope.

    ASGI gives the app no view of the socket; the server puts the connection's transport in
    ``scope["extensions"][TRANSPORT_EXTENSION]`` (ASGI's place for what a server adds), so
    that the app can read how many bytes wait unread for a client and abort the connection
    of one that stopped reading. A uvicorn that connects otherwise leaves it out, and the
    app makes do without.
    """

    def handle_connect(self, event: Any) -> None:
        """Accept the handshake (uvicorn's), then add the transport to the scope."""
        super().handle_connect(event)
        scope = getattr(self, "scope", None)
        if isinstance(scope, dict):
            scope.setdefault("extensions", {})[TRANSPORT_EXTENSION] = self.transport


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (``port`` 0: any free one).

    Raises:
        ServeError: the port is in use or not allowed, or the address is not this machine's.
    """
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM,
                                   flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise ServeError(f"--host {host} is not an address of this machine ({exc.strerror}); "
                         "use 127.0.0.1, or this machine's IP address with --token") from None
    family, kind, proto, _, address = infos[0]
    sock = socket.socket(family, kind, proto)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(address)
        sock.listen(128)
    except OSError as exc:
        sock.close()
        raise ServeError(f"cannot listen on {host}:{port} ({exc.strerror}): choose another "
                         "port with --port, or stop the program using it") from None
    sock.set_inheritable(True)
    return sock


def bound_port(sock: socket.socket) -> int:
    """The port a listening socket got."""
    return int(sock.getsockname()[1])


def base_url(host: str, port: int) -> str:
    """``http://HOST:PORT`` (IPv6 addresses bracketed)."""
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}"


def uvicorn_server(app: FastAPI, settings: ServeSettings, log_level: str = "warning"
                   ) -> uvicorn.Server:
    """A uvicorn server for ``app`` (run it with ``server.run(sockets=[bind(...)])``)."""
    config = uvicorn.Config(
        app, host=settings.host, port=settings.port, ws=WebSocketProtocol,
        ws_max_size=settings.ws_max_size, ws_per_message_deflate=False, lifespan="on",
        log_level=log_level, timeout_graceful_shutdown=GRACEFUL_SHUTDOWN, access_log=False,
    )
    return uvicorn.Server(config)
