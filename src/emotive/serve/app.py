"""The ASGI app of ``emotive serve``: the HTTP API, the websocket and the browser app.

:func:`create_app` loads the engine first (so a missing model or backend fails before
anything binds), then builds a FastAPI app whose lifespan starts the step workers (with
``workers`` > 1, :class:`~emotive.serve.workers.ShardedEngine`), the simulation thread
(:class:`~emotive.serve.simulation.Simulation`) and the preparer of control messages
(:class:`~emotive.serve.preparation.Preparer`) and stops them all, workers last. A websocket
chooses its frame layout with ``?encoding=1`` or ``2`` (default
:data:`~emotive.serve.frames.DEFAULT_ENCODING`). Routes are those of
``docs/serve.md``; with ``--scene`` the engine is the scene's crowd
(:mod:`~emotive.serve.crowd_engine`), whose geometry every websocket gets first and
``/api/scene`` answers. With a token every ``/api`` route and the websocket check it with
:func:`hmac.compare_digest` (``Authorization: Bearer T`` or ``?token=T``); the page at ``/``
and its files under ``/static`` are public, as they hold no scene data. Browsers let any site
reach ``127.0.0.1``, so a websocket from a page of another site is refused
(:func:`same_origin`), and without a token only requests naming a loopback host are answered
(:func:`host_allowed`, against DNS rebinding).
"""

from __future__ import annotations

import asyncio
import hmac
import sys
import tempfile
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from fastapi import FastAPI, Request, WebSocket
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.background import BackgroundTask

import emotive
from emotive.data.emotion import label_points
from emotive.io.gltf import encode_gltf, gltf_document
from emotive.serve.engines import Engine, load_engine
from emotive.serve.errors import MessageError
from emotive.serve.frames import DEFAULT_ENCODING, ENCODINGS
from emotive.serve.hub import Hub, LoopSink
from emotive.serve.limits import TokenBucket
from emotive.serve.messages import Command
from emotive.serve.preparation import Preparer
from emotive.serve.recording import FORMATS, write_recording
from emotive.serve.session import Session
from emotive.serve.settings import ServeSettings, is_loopback
from emotive.serve.simulation import Simulation
from emotive.serve.workers import ShardedEngine

#: The browser app's folder, shipped inside the package.
STATIC = Path(__file__).parent / "static"
#: Close code of a websocket without the right token.
UNAUTHORIZED_CLOSE = 4401
#: Close code of a websocket opened by a page of another site.
FORBIDDEN_CLOSE = 4403
#: Close code of a websocket asking for a frame layout the server does not have.
BAD_ENCODING_CLOSE = 4400
#: Seconds an HTTP request waits for the simulation thread.
REPLY_TIMEOUT = 10.0
#: The interpreter's thread switch interval while the server runs, seconds (Python's
#: default is 0.005). The engine releases the interpreter lock inside each tensor operation
#: and takes it again after; while the event loop or the preparer runs Python, each retake
#: waits up to this long, so a short interval keeps the tick's many retakes short.
SWITCH_INTERVAL = 0.0005


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"type": "error", "message": message}, status_code=status)


def token_ok(expected: str | None, headers: Any, query: Any) -> bool:
    """Whether a request presents the token (always, when the server has none)."""
    if expected is None:
        return True
    given = query.get("token")
    auth = headers.get("authorization", "")
    if given is None and auth.lower().startswith("bearer "):
        given = auth[7:].strip()
    return given is not None and hmac.compare_digest(given.encode(), expected.encode())


def same_origin(headers: Any) -> bool:
    """Whether a websocket comes from a page of this server, or from no page at all.

    Browsers let any site open websockets to ``127.0.0.1``; they send its ``Origin``, which
    must then name the host the request went to.
    """
    origin = headers.get("origin")
    return origin is None or urlsplit(origin).netloc.lower() == headers.get("host", "").lower()


def host_allowed(settings: ServeSettings, headers: Any) -> bool:
    """Whether a request names this machine, or the server has a token.

    Without a token the server answers only requests whose ``Host`` is a loopback name, so
    that a site whose name is made to resolve to ``127.0.0.1`` (DNS rebinding) cannot read
    the scene.
    """
    if settings.token is not None:
        return True
    name = urlsplit("//" + headers.get("host", "")).hostname
    return name is None or is_loopback(name)


def skeleton_info(engine: Engine) -> dict[str, Any]:
    """``GET /api/skeleton``: the rig of every frame, its labels and their circumplex points."""
    sk = engine.skeleton
    points = label_points(engine.labels)
    return {
        "joints": list(sk.names), "parents": sk.parents.tolist(),
        "end_site_parents": sk.end_site_parents.tolist(),
        "offsets": np.round(sk.offsets, 6).tolist(), "mover": engine.mover,
        "end_site_offsets": np.round(np.asarray(sk.end_site_offsets).reshape(-1, 3),
                                     6).tolist(),
        "labels": list(engine.labels), "fps": engine.fps,
        "points": {n: [round(float(v), 4), round(float(a), 4)]
                   for n, (v, a) in zip(engine.labels, points, strict=True)},
    }


class _State:
    """What the routes share: settings, engine, clients, the scene and the mannequin."""

    def __init__(self, settings: ServeSettings, engine: Engine) -> None:
        self.settings = settings
        self.engine = engine
        self.hub = Hub(settings)
        self.sim: Simulation | None = None
        self.preparer: Preparer | None = None
        self.reads = TokenBucket(settings.server_rate, int(settings.server_rate))
        self.mannequin: bytes | None = None

    def scene(self) -> Simulation:
        if self.sim is None:
            raise MessageError("the scene is not running (the server is starting or stopping)")
        return self.sim

    async def ask(self, command: Command) -> dict[str, Any]:
        future = self.scene().submit(command)
        return await asyncio.wait_for(asyncio.wrap_future(future), REPLY_TIMEOUT)


def _mannequin_bytes(engine: Engine) -> bytes:
    doc, blob = gltf_document(engine.rest, mesh=True)
    return encode_gltf(doc, blob, binary=True)


def create_app(settings: ServeSettings | None = None, engine: Any = None) -> FastAPI:
    """The app of one server, with a fresh engine of the settings' model and backend.

    Args:
        settings: the server's settings (checked here; default: :class:`ServeSettings`).
        engine: the engine, already loaded (the command loads a scene's before it binds);
            ``None``: loaded here, a scene's crowd with ``settings.scene``
            (:func:`~emotive.serve.crowd_engine.load_crowd_engine`).

    Raises:
        ServeError: bad settings, or a model or backend this installation lacks.
        SceneError: a bad scene file. CrowdError: JuPedSim is missing or refuses the scene.
        ConfigError: the model's weights are missing or corrupt.
    """
    settings = (settings or ServeSettings()).checked()
    if engine is None and settings.scene is not None:
        from emotive.serve.crowd_engine import load_crowd_engine  # noqa: PLC0415 (the crowd)

        engine = load_crowd_engine(settings.scene, settings.seed)
    elif engine is None:
        engine = load_engine(settings.model, settings.backend, settings.seed)
    state = _State(settings, engine)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        scene: Engine | ShardedEngine = engine
        if settings.workers > 1:
            scene = await asyncio.to_thread(ShardedEngine, engine, settings.workers,
                                            settings.max_agents, settings.seed,
                                            settings.worker_threads)
        state.sim = Simulation(scene, settings, LoopSink(state.hub, asyncio.get_running_loop()))
        state.preparer = Preparer(state.sim, settings)
        switch = sys.getswitchinterval()
        sys.setswitchinterval(SWITCH_INTERVAL)
        state.sim.start()
        state.preparer.start()
        try:
            yield
        finally:
            sys.setswitchinterval(switch)
            sim, preparer, state.sim, state.preparer = state.sim, state.preparer, None, None
            await preparer.stop()
            await asyncio.to_thread(sim.stop)
            if isinstance(scene, ShardedEngine):
                await asyncio.to_thread(scene.close)

    app = FastAPI(title="emotive serve", version=emotive.__version__, lifespan=lifespan,
                  docs_url=None, redoc_url=None, openapi_url=None)
    app.state.emotive = state
    _guards(app, settings)
    _api_routes(app, state)
    _page_routes(app)

    @app.websocket("/ws")
    async def ws(websocket: WebSocket) -> None:
        await websocket.accept()
        if not (same_origin(websocket.headers) and host_allowed(settings, websocket.headers)):
            await websocket.close(FORBIDDEN_CLOSE, "pages of other sites may not connect")
            return
        if not token_ok(settings.token, websocket.headers, websocket.query_params):
            await websocket.close(UNAUTHORIZED_CLOSE, "missing or wrong token")
            return
        encoding = websocket.query_params.get("encoding", str(DEFAULT_ENCODING))
        if encoding not in [str(v) for v in ENCODINGS]:
            await websocket.close(BAD_ENCODING_CLOSE, f"unknown frame encoding "
                                  f"{encoding[:20]!r}: use ?encoding=1 or ?encoding=2")
            return
        if state.sim is None or state.preparer is None:
            await websocket.close(1013, "the scene is not running")
            return
        session = Session(websocket, state.sim, state.hub, state.preparer, settings,
                          state.reads, int(encoding))
        scene = getattr(engine, "scene_message", None)
        if scene is not None:  # the geometry first (later changes reach every client)
            session.box.put_reply(dict(scene))
        await session.run()

    return app


def _guards(app: FastAPI, settings: ServeSettings) -> None:
    """The Host and token checks of every request, and the errors of routes as JSON."""

    @app.middleware("http")
    async def check_token(request: Request, call_next: Any) -> Response:
        if not host_allowed(settings, request.headers):
            return _error(403, "the Host of the request is not this machine: open the app "
                               "at http://127.0.0.1:PORT/, or start the server with --token")
        if request.url.path.startswith("/api/") and not token_ok(
                settings.token, request.headers, request.query_params):
            return _error(401, "missing or wrong token: send 'Authorization: Bearer T' or "
                               "?token=T with the server's --token")
        return await call_next(request)

    @app.exception_handler(MessageError)
    async def not_running(request: Request, exc: MessageError) -> JSONResponse:
        return _error(503, str(exc))

    @app.exception_handler(TimeoutError)
    async def too_slow(request: Request, exc: TimeoutError) -> JSONResponse:
        return _error(503, f"the scene did not answer within {REPLY_TIMEOUT:g} s; try again")


def _api_routes(app: FastAPI, state: _State) -> None:
    engine = state.engine

    @app.get("/api/health")
    async def health() -> dict[str, Any]:
        workers = state.settings.workers
        scene = state.sim.engine if state.sim is not None else None
        live = len(scene.live()) if isinstance(scene, ShardedEngine) else workers
        return {"status": "ok" if live == workers else "degraded",
                "version": emotive.__version__, "model": engine.model,
                "backend": engine.backend, "workers": workers, "live_workers": live,
                "encodings": list(ENCODINGS)}

    @app.get("/api/stats")
    async def stats() -> dict[str, Any]:
        out = state.scene().stats()
        out.update(clients=len(state.hub.outboxes), dropped_frames=state.hub.dropped_frames,
                   slow_clients=state.hub.slow_clients, model=engine.model,
                   backend=engine.backend)
        return out

    @app.get("/api/scene", response_model=None)
    async def scene() -> dict[str, Any] | JSONResponse:
        message = getattr(engine, "scene_message", None)
        if message is None:
            return _error(404, "this server has no scene: start it with --scene SCENE.toml")
        return dict(message)

    @app.get("/api/skeleton")
    async def skeleton() -> dict[str, Any]:
        return skeleton_info(engine)

    @app.get("/api/agents")
    async def agents() -> dict[str, Any]:
        return {"agents": (await state.ask(Command("state")))["agents"]}

    @app.get("/api/mannequin.glb")
    async def mannequin() -> Response:
        if state.mannequin is None:
            state.mannequin = await asyncio.to_thread(_mannequin_bytes, engine)
        return Response(state.mannequin, media_type="model/gltf-binary")

    @app.get("/api/recordings/{rid}", response_model=None)
    async def recording(rid: int, agent: int | None = None, format: str = "bvh"
                        ) -> Response:
        if format not in FORMATS:
            return _error(400, f"format {format!r} is unknown; use format=bvh or format=glb")
        try:
            rec = state.scene().recorder.finished(rid)
        except KeyError as exc:
            return _error(404, str(exc.args[0]))
        folder = Path(tempfile.mkdtemp(prefix="emotive-recording-"))
        try:
            path = await asyncio.to_thread(write_recording, rec, agent, format,
                                           engine.skeleton, engine.fps, folder)
        except MessageError as exc:
            _remove(folder)
            return _error(404, str(exc))
        return FileResponse(path, filename=path.name, media_type="application/octet-stream",
                            background=BackgroundTask(_remove, folder))


def _remove(folder: Path) -> None:
    for child in folder.iterdir():
        child.unlink(missing_ok=True)
    folder.rmdir()


def _page_routes(app: FastAPI) -> None:
    @app.get("/", response_model=None)
    async def index() -> Response:
        page = STATIC / "index.html"
        if not page.is_file():
            return _error(404, "the browser app is not part of this installation "
                               "(emotive/serve/static/index.html is missing); the API and "
                               "the websocket /ws work without it")
        return FileResponse(page, media_type="text/html")

    app.mount("/static", StaticFiles(directory=STATIC, check_dir=False), name="static")
