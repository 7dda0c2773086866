"""The study server: participant page, participant API and admin API on FastAPI.

The routes, their bodies and their errors are the protocol of ``docs/study-protocol.md``.
Database work runs in worker threads (:mod:`emotive.study.store`); the event loop only reads
bodies, checks limits and answers. Bodies are read here, within the size limit, and checked by
hand rather than by pydantic models, so that every refusal is one line naming the field and
the fix.

Security: a participant is known only by the bearer token in the ``Authorization`` header
(stored hashed); admin routes take the separate admin token and never a participant's; every
body is size-limited and strictly typed; submissions and joins are rate limited per
participant and per client address; responses carry ``Cache-Control: no-store`` and a
content security policy that keeps the page from loading anything off the host.

Storage faults (:mod:`emotive.study.faults`): a request the database cannot serve now (full,
read-only, unreachable) is answered ``503`` with a one-line reason and ``Retry-After``, and
``/api/health`` answers ``503 {"status": "degraded", ...}`` until a write succeeds again.
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import re
from collections import OrderedDict
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from fastapi import FastAPI, Request
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from sqlalchemy import exc as sa_exc
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException as StarletteHTTPException

from emotive.serve.limits import TokenBucket
from emotive.study import store
from emotive.study.config import StudyConfig, load_study
from emotive.study.db import backend_name, open_database
from emotive.study.export import export_csv
from emotive.study.faults import RETRY_AFTER_S, WriteHealth, probe_write, storage_fault
from emotive.study.stimuli import stimulus_effectors
from emotive.study.store import Participant, Rejected

#: Version of the HTTP API (``docs/study-protocol.md``).
API_VERSION = 1
#: Allowed idempotency keys.
KEY_PATTERN = re.compile(r"^[A-Za-z0-9_-]{8,128}$")
#: Longest response time accepted, milliseconds (a day).
MAX_RT_MS = 86_400_000
#: Rate-limit buckets kept (participants and addresses); the oldest are forgotten first.
MAX_BUCKETS = 50_000
#: Headers on every reply.
SECURITY_HEADERS = {
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": (
        "default-src 'self'; script-src 'self' 'unsafe-inline'; style-src 'self' "
        "'unsafe-inline'; img-src 'self' data: blob:; connect-src 'self' data: blob:; "
        "worker-src 'self' blob:; frame-ancestors 'none'"),
}
STUDY_STATIC = Path(__file__).with_name("static")
SERVE_STATIC = Path(__file__).parents[1] / "serve" / "static"
SUBMISSION_KEYS = {"item", "stimulus", "answers", "rt_ms"}

logger = logging.getLogger("emotive.study")
#: Database errors that may be storage faults (:func:`emotive.study.faults.storage_fault`).
DATABASE_ERRORS = (sa_exc.DBAPIError, sa_exc.TimeoutError)


def _reject_constant(name: str) -> float:
    raise Rejected(422, f"the body holds {name}; send finite numbers")


class _Buckets:
    """Token buckets by key, the least recently used forgotten past :data:`MAX_BUCKETS`."""

    def __init__(self, rate: float, burst: int) -> None:
        self.rate, self.burst = rate, burst
        self.buckets: OrderedDict[str, TokenBucket] = OrderedDict()

    def take(self, key: str) -> float:
        """0 when a token was taken, else the seconds to wait."""
        bucket = self.buckets.pop(key, None) or TokenBucket(self.rate, self.burst)
        self.buckets[key] = bucket
        if len(self.buckets) > MAX_BUCKETS:
            self.buckets.popitem(last=False)
        return 0.0 if bucket.take() else max(bucket.delay(), 0.01)


async def read_json(request: Request, limit: int) -> Any:
    """The request's JSON body, at most ``limit`` bytes.

    Raises:
        Rejected: too large (413) or not JSON (422).
    """
    length = request.headers.get("content-length")
    if length is not None and (not length.isdigit() or int(length) > limit):
        raise Rejected(413, f"the body is larger than {limit} bytes")
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > limit:
            raise Rejected(413, f"the body is larger than {limit} bytes")
    try:
        return json.loads(body, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as exc:
        reason = str(exc).splitlines()[0] if isinstance(exc, ValueError) else "nested too deep"
        raise Rejected(422, f"the body is not valid JSON ({reason})") from None


def _bearer(request: Request) -> str | None:
    header = request.headers.get("authorization", "")
    scheme, _, value = header.partition(" ")
    return value.strip() if scheme.lower() == "bearer" and value.strip() else None


def _submission(body: Any) -> tuple[int, str, dict[str, Any], int | None]:
    if not isinstance(body, dict):
        raise Rejected(422, "the body must be a JSON object {item, stimulus, answers, rt_ms}")
    unknown = sorted(set(body) - SUBMISSION_KEYS)
    if unknown:
        raise Rejected(422, f"unknown field(s) {unknown}; send item, stimulus, answers, rt_ms")
    item, stimulus = body.get("item"), body.get("stimulus")
    answers, rt_ms = body.get("answers"), body.get("rt_ms")
    if isinstance(item, bool) or not isinstance(item, int):
        raise Rejected(422, "item must be an integer (the plan's item number)")
    if not isinstance(stimulus, str):
        raise Rejected(422, "stimulus must be the item's stimulus id (a string)")
    if not isinstance(answers, dict):
        raise Rejected(422, "answers must be an object mapping question ids to answers")
    if rt_ms is not None and (isinstance(rt_ms, bool) or not isinstance(rt_ms, int)
                              or not 0 <= rt_ms <= MAX_RT_MS):
        raise Rejected(422, f"rt_ms must be an integer from 0 to {MAX_RT_MS}, or null")
    return item, stimulus, answers, rt_ms


def _question_json(study: StudyConfig) -> list[dict[str, Any]]:
    return [{"id": q.id, "kind": q.kind, "prompt": q.prompt, "min": q.min, "max": q.max,
             "anchors": list(q.anchors), "options": list(q.options), "size": q.size}
            for q in study.questions]


class StudyState:
    """What the routes share: the study, its database, limits and stimulus facts."""

    def __init__(self, study: StudyConfig, engine: Any, admin_token: str | None) -> None:
        self.study = study
        self.engine = engine
        self.admin_token = admin_token
        self.submits = _Buckets(study.limits.submit_per_second, study.limits.submit_burst)
        self.joins = _Buckets(study.limits.joins_per_minute / 60.0,
                              max(1, int(study.limits.joins_per_minute)))
        self.effectors = {s.id: stimulus_effectors(study.stimulus_path(s.id))
                          for s in study.stimuli}
        self.checks = {c.id: c for c in study.checks}
        self.health = WriteHealth()
        self.probing = asyncio.Lock()

    async def probe(self) -> None:
        """Make the health check's test write when one is due (one at a time)."""
        if not self.health.probe_due() or self.probing.locked():
            return
        async with self.probing:
            try:
                await run_in_threadpool(probe_write, self.engine)
            except DATABASE_ERRORS as exc:
                fault = storage_fault(exc)
                if fault is None:
                    raise
                self.health.failed(fault, "the health check's test write", refused=False)
            else:
                self.health.wrote()

    async def health_json(self) -> JSONResponse:
        """``GET /api/health``'s reply: 200 when the database takes writes, else 503."""
        await self.probe()
        joined: int | None = None
        stored: int | None = None
        try:
            joined, stored = await run_in_threadpool(store.counts, self.engine)
        except DATABASE_ERRORS as exc:
            fault = storage_fault(exc)
            if fault is None:
                raise
            self.health.failed(fault, "GET /api/health", refused=False)
        fault = self.health.fault
        body = {"status": "ok" if fault is None else "degraded", "writable": fault is None,
                "reason": None if fault is None else fault.reason,
                "database": backend_name(self.engine), "participants": joined,
                "responses": stored, "version": API_VERSION}
        if fault is None:
            return JSONResponse(body)
        return JSONResponse(body, status_code=503, headers={"Retry-After": str(RETRY_AFTER_S)})

    async def participant(self, request: Request) -> Participant:
        """The participant whose token the request carries (:class:`Rejected` 401 if none)."""
        token = _bearer(request)
        if token is None:
            raise Rejected(401, "send your participant token as 'Authorization: Bearer TOKEN' "
                           "(join with POST /api/participants)")
        found = await run_in_threadpool(store.by_token, self.engine, token)
        if found is None:
            raise Rejected(401, "unknown participant token; join with POST /api/participants")
        return found

    def admin(self, request: Request) -> None:
        """Refuse (403) unless the request carries the admin token."""
        if self.admin_token is None:
            raise Rejected(403, "the admin API is off: start the server with --admin-token")
        token = _bearer(request)
        if token is None or not hmac.compare_digest(token.encode(), self.admin_token.encode()):
            raise Rejected(403, "the admin API needs 'Authorization: Bearer ADMIN_TOKEN'")

    def plan_json(self, participant: Participant, answered: list[int]) -> dict[str, Any]:
        """``GET /api/plan``'s reply."""
        items = []
        for it in participant.plan.items:
            check = self.checks.get(it.check)
            items.append({"item": it.item, "stimulus": it.stimulus,
                          "url": f"/api/stimuli/{it.stimulus}.glb", "repeat": it.repeat,
                          "instruction": check.instruction if check else None,
                          "effectors": self.effectors[it.stimulus]})
        return {"participant": participant.public_id, "condition": participant.condition,
                "render": participant.plan.render, "seconds": self.study.seconds,
                "completed": participant.completed, "answered": answered, "items": items}


def _participant_routes(app: FastAPI, state: StudyState) -> None:
    study = state.study

    @app.get("/api/health")
    async def health() -> JSONResponse:
        return await state.health_json()

    @app.get("/api/study")
    async def study_info() -> dict[str, Any]:
        items = len(study.conditions[0].stimuli) * study.repeats + len(study.checks)
        return {"title": study.title, "consent": study.consent,
                "instructions": study.instructions, "seconds": study.seconds, "items": items,
                "questions": _question_json(study), "version": API_VERSION}

    @app.post("/api/participants", status_code=201)
    async def join(request: Request) -> dict[str, Any]:
        address = request.client.host if request.client else "unknown"
        wait = state.joins.take(address)
        if wait:
            raise Rejected(429, f"too many new participants from {address}; wait {wait:.0f} s")
        body = await read_json(request, study.limits.max_body_bytes)
        if not isinstance(body, dict) or set(body) != {"consent"} or body["consent"] is not True:
            raise Rejected(422, 'joining needs consent: send {"consent": true}')
        token, who = await run_in_threadpool(store.join, state.engine, study)
        state.health.wrote()
        return {"token": token, "participant": who.public_id, "condition": who.condition,
                "items": len(who.plan.items)}

    @app.get("/api/plan")
    async def plan(request: Request) -> dict[str, Any]:
        who = await state.participant(request)
        answered = await run_in_threadpool(store.answered_items, state.engine, who)
        return state.plan_json(who, answered)

    @app.get("/api/stimuli/{name}")
    async def stimulus(name: str) -> FileResponse:
        sid = name.removesuffix(".glb")
        if not name.endswith(".glb") or sid not in state.effectors:
            raise Rejected(404, f"no stimulus {name!r} in this study")
        return FileResponse(study.stimulus_path(sid), media_type="model/gltf-binary")

    @app.post("/api/responses")
    async def respond(request: Request) -> JSONResponse:
        who = await state.participant(request)
        wait = state.submits.take(who.public_id)
        if wait:
            return _error(429, f"more than {study.limits.submit_per_second:g} submissions a "
                          f"second; retry in {wait:.1f} s", {"Retry-After": f"{wait:.0f}"})
        key = request.headers.get("idempotency-key")
        if key is None or not KEY_PATTERN.match(key):
            raise Rejected(400, "send a new Idempotency-Key header per item: 8 to 128 letters, "
                           "digits, '_' or '-'")
        item, sid, answers, rt_ms = _submission(
            await read_json(request, study.limits.max_body_bytes))
        outcome, stored = await run_in_threadpool(store.submit, state.engine, study, who, key,
                                                  item, sid, answers, rt_ms)
        replayed = outcome is store.Outcome.REPLAYED
        if not replayed:
            state.health.wrote()
        return JSONResponse({"item": item, "stored": stored, "replayed": replayed},
                            status_code=200 if replayed else 201)

    @app.post("/api/complete")
    async def complete(request: Request) -> dict[str, str]:
        who = await state.participant(request)
        code = await run_in_threadpool(store.complete, state.engine, study, who)
        state.health.wrote()
        return {"completion_code": code}


def _admin_routes(app: FastAPI, state: StudyState) -> None:
    study = state.study

    @app.get("/api/admin/progress")
    async def progress(request: Request) -> dict[str, Any]:
        state.admin(request)
        return await run_in_threadpool(store.progress, state.engine, study)

    @app.get("/api/admin/participants")
    async def participants(request: Request) -> dict[str, Any]:
        state.admin(request)
        rows = await run_in_threadpool(store.participant_table, state.engine, study)
        return {"participants": rows}

    @app.post("/api/admin/exclusions")
    async def exclusions(request: Request) -> dict[str, Any]:
        state.admin(request)
        body = await read_json(request, study.limits.max_body_bytes)
        if (not isinstance(body, dict) or not isinstance(body.get("participant"), str)
                or not isinstance(body.get("excluded"), bool)
                or not isinstance(body.get("reason", ""), str)
                or set(body) - {"participant", "excluded", "reason"}):
            raise Rejected(422, 'send {"participant": ID, "excluded": true|false, '
                           '"reason": TEXT}')
        await run_in_threadpool(store.set_excluded, state.engine, body["participant"],
                                body["excluded"], body.get("reason", ""))
        state.health.wrote()
        return {"participant": body["participant"], "excluded": body["excluded"]}

    @app.get("/api/admin/export.csv")
    async def export(request: Request) -> Response:
        state.admin(request)
        text = await run_in_threadpool(export_csv, state.engine, study)
        return Response(text, media_type="text/csv; charset=utf-8",
                        headers={"Content-Disposition": 'attachment; filename="responses.csv"'})


def _error(status: int, message: str, headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status, headers=headers)


def _handlers(app: FastAPI, state: StudyState) -> None:
    @app.exception_handler(Rejected)
    async def rejected(_request: Request, exc: Rejected) -> JSONResponse:
        wait = None if exc.retry_after is None else {"Retry-After": f"{exc.retry_after:.0f}"}
        return _error(exc.status, str(exc), wait)

    @app.exception_handler(sa_exc.DBAPIError)
    @app.exception_handler(sa_exc.TimeoutError)
    async def storage(request: Request, exc: Exception) -> JSONResponse:
        fault = storage_fault(exc)
        if fault is None:
            raise exc  # a bug: the JSON 500 of the `headers` middleware, traceback logged
        state.health.failed(fault, f"{request.method} {request.url.path}")
        return _error(503, f"{fault.reason}; nothing was stored: send it again in "
                      f"{RETRY_AFTER_S} s", {"Retry-After": str(RETRY_AFTER_S)})

    @app.exception_handler(StarletteHTTPException)
    async def http_error(_request: Request, exc: StarletteHTTPException) -> JSONResponse:
        reason = {404: "no such page or API route", 405: "this route does not take that "
                  "method"}.get(exc.status_code, str(exc.detail))
        return _error(exc.status_code, reason)

    @app.middleware("http")
    async def headers(request: Request, call_next: Callable[[Request], Awaitable[Response]]
                      ) -> Response:
        try:
            reply = await call_next(request)
        except Exception:
            # A bug: its traceback in the log, a JSON 500 to the client, and the connection
            # kept (left to uvicorn, the reply would be plain text and the connection closed
            # under the client's next request).
            logger.exception("%s %s failed", request.method, request.url.path)
            reply = _error(500, "the server failed on this request; its log has the details")
        reply.headers.update(SECURITY_HEADERS)
        if request.url.path.startswith("/api/"):
            reply.headers["Cache-Control"] = "no-store"
        return reply


def create_app(folder: str | Path, db_url: str | None = None,
               admin_token: str | None = None) -> FastAPI:
    """The server of the study in ``folder``.

    Args:
        folder: the study folder (``study.toml`` and its stimuli).
        db_url: the database (default: SQLite at ``folder/study.db``).
        admin_token: the secret of the admin API, or ``None`` to leave it off.

    Raises:
        StudyConfigError: a bad ``study.toml`` or missing stimulus files.
        StudyError: a database that cannot be opened or was made for another design.
    """
    study = load_study(folder)
    engine = open_database(study.folder, db_url)
    store.check_design(engine, study)
    state = StudyState(study, engine, admin_token)
    app = FastAPI(title=f"emotive study: {study.title}", docs_url=None, redoc_url=None,
                  openapi_url=None)
    app.state.study = state
    _handlers(app, state)
    _participant_routes(app, state)
    _admin_routes(app, state)

    @app.get("/")
    async def page() -> FileResponse:
        return FileResponse(STUDY_STATIC / "index.html")

    @app.get("/admin")
    async def admin_page() -> FileResponse:
        return FileResponse(STUDY_STATIC / "admin.html")

    app.mount("/study-static", StaticFiles(directory=STUDY_STATIC, check_dir=False),
              name="study-static")
    app.mount("/static", StaticFiles(directory=SERVE_STATIC), name="static")
    return app
