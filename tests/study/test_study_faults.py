"""The study server when its database cannot store: full or read-only, SQLite and PostgreSQL.

A write the database refuses is answered ``503`` with a one-line JSON reason and
``Retry-After``; ``/api/health`` answers ``503 "degraded"`` with the reason; the log gets one
line, not a traceback per request. Once the database takes writes again (space freed: no
restart), health says ok, the refused submissions are stored under their own keys, and the
database holds every acknowledged answer exactly once. The faults are the database's own
(:mod:`storage_faults`; PostgreSQL's full disk is simulated).
"""

from __future__ import annotations

import logging
import sqlite3
import uuid
from collections import Counter

import httpx
import pytest
from sqlalchemy import exc as sa_exc
from sqlalchemy import select
from storage_faults import DatabaseFault
from study_client import answers_for, client_for, join, set_limits

from emotive.study import db, faults
from emotive.study.app import create_app
from emotive.study.faults import RETRY_AFTER_S, WriteHealth, storage_fault
from emotive.study.testing import serving

#: Participants joined before the fault; their submissions fill the database.
PEOPLE = 40
#: What the reason of each fault says.
WORDS = {"full": "full", "read-only": "read-only"}


def _assert_refused(reply: httpx.Response, kind: str) -> None:
    assert reply.status_code == 503, reply.text
    assert reply.headers["content-type"] == "application/json"
    assert reply.headers["retry-after"] == str(RETRY_AFTER_S)
    reason = reply.json()["error"]
    assert WORDS[kind] in reason and "nothing was stored" in reason, reason
    assert "\n" not in reason and "Traceback" not in reason and "sqlalchemy" not in reason


def _stored(engine) -> Counter:
    p, r = db.participants.c, db.responses.c
    with engine.connect() as conn:
        rows = conn.execute(select(p.public_id, r.item, r.question).select_from(
            db.responses.join(db.participants, r.participant_id == p.id)))
        return Counter((row.public_id, row.item, row.question) for row in rows)


@pytest.mark.parametrize("kind", ["full", "read-only"])
def test_a_database_that_cannot_store_answers_503_and_recovers_without_restart(
        study_folder, db_url, kind, caplog):
    set_limits(study_folder, submit_per_second=1000.0, submit_burst=1000,
               joins_per_minute=100000.0)
    caplog.set_level(logging.WARNING)
    app = create_app(study_folder, db_url=db_url)
    engine = app.state.study.engine
    fault = DatabaseFault(engine, kind)
    acknowledged: dict[str, tuple[str, int]] = {}  # key -> (participant, item)
    try:
        with serving(app) as url, client_for(url) as client:
            questions = client.get("/api/study").json()["questions"]
            people = [join(client) for _ in range(PEOPLE)]

            def submit(who, item: int, key: str) -> httpx.Response:
                reply = who.submit(item, answers_for(questions, 1 + item), key)
                if reply.status_code in (200, 201):
                    acknowledged[key] = (who.id, item)
                return reply

            assert submit(people[0], 0, "before-the-fault").status_code == 201
            health = client.get("/api/health")
            assert health.status_code == 200 and health.json()["status"] == "ok"
            assert health.json()["writable"] is True and health.json()["reason"] is None

            fault.fail()
            refused = None
            for item in range(4):
                for who in people[1:]:
                    key = uuid.uuid4().hex
                    reply = submit(who, item, key)
                    if reply.status_code == 503:
                        refused = (who, item, key, reply)
                        break
                    assert reply.status_code == 201, reply.text
                if refused:
                    break
            assert refused is not None, "the database never refused a write"
            who, item, key, reply = refused
            _assert_refused(reply, kind)
            _assert_refused(submit(who, item, key), kind)  # the same try again: still refused
            if (engine.dialect.name, kind) != ("sqlite", "full"):  # a join may fit a page
                _assert_refused(client.post("/api/participants", json={"consent": True}), kind)
            health = client.get("/api/health")
            assert health.status_code == 503 and health.headers["retry-after"] == str(RETRY_AFTER_S)
            body = health.json()
            assert body["status"] == "degraded" and body["writable"] is False
            assert WORDS[kind] in body["reason"] and body["responses"] == sum(
                len(questions) for _ in acknowledged)
            plan = client.get("/api/plan", headers=who.headers)
            assert plan.status_code == 200 and item not in plan.json()["answered"]

            fault.heal()  # space freed, the database writable again: no restart
            health = client.get("/api/health")
            assert health.status_code == 200, health.text
            assert health.json()["status"] == "ok" and health.json()["writable"] is True
            assert submit(who, item, key).status_code == 201  # stored now, under its key
            for old, (pid, it) in list(acknowledged.items())[:5]:
                again = next(p for p in people if p.id == pid).submit(
                    it, answers_for(questions, 1 + it), old)
                assert again.status_code == 200 and again.json()["replayed"] is True
        stored = _stored(engine)
    finally:
        fault.heal()
        fault.remove()
        engine.dispose()
    expected = Counter((pid, it, q["id"]) for pid, it in acknowledged.values()
                       for q in questions)
    assert stored == expected, "the database must hold every acknowledged answer, once"
    assert max(stored.values()) == 1
    # The log: one line when writes stopped, one when they came back; no traceback.
    lines = [r.getMessage() for r in caplog.records if r.name == "emotive.study"]
    assert len(lines) == 2, lines
    assert "takes no writes" in lines[0] and WORDS[kind] in lines[0]
    assert "takes writes again" in lines[1]
    assert not [r for r in caplog.records if r.exc_info], "a traceback in the log"


def test_a_bug_is_a_json_500_and_the_connection_stays(study_folder, monkeypatch):
    from emotive.study import store

    def broken(*_args):
        raise sa_exc.ProgrammingError("SELECT", {}, sqlite3.ProgrammingError("no such column"))

    app = create_app(study_folder)
    try:
        with serving(app) as url, client_for(url) as client:
            who = join(client)
            with monkeypatch.context() as patch:
                patch.setattr(store, "answered_items", broken)
                reply = client.get("/api/plan", headers=who.headers)
            after = client.get("/api/plan", headers=who.headers)  # the same connection
    finally:
        app.state.study.engine.dispose()
    assert reply.status_code == 500
    assert reply.json() == {"error": "the server failed on this request; its log has the "
                                     "details"}
    assert reply.headers["x-content-type-options"] == "nosniff"
    assert after.status_code == 200


def _wrapped(error: Exception, kind: type = sa_exc.OperationalError) -> Exception:
    return kind("INSERT INTO responses ...", {}, error)


def test_storage_faults_are_told_from_bugs():
    import psycopg.errors

    cases = [
        (sqlite3.OperationalError("database or disk is full"), "full"),
        (sqlite3.OperationalError("attempt to write a readonly database"), "read-only"),
        (sqlite3.OperationalError("unable to open database file"), "unreachable"),
        (sqlite3.OperationalError("database is locked"), "busy"),
        (sqlite3.OperationalError("disk I/O error"), "failing"),
        (psycopg.errors.DiskFull("could not extend file"), "full"),
        (psycopg.OperationalError("connection failed: Connection refused\nIs the server "
                                  "running?"), "unreachable"),
        (psycopg.errors.AdminShutdown("terminating connection"), "unreachable"),
    ]
    for error, kind in cases:
        fault = storage_fault(_wrapped(error))
        assert fault is not None and fault.kind == kind, (error, fault)
        assert "\n" not in fault.detail and "\n" not in fault.reason
    read_only = _wrapped(psycopg.errors.ReadOnlySqlTransaction("cannot execute INSERT in a "
                                                               "read-only transaction"),
                         sa_exc.InternalError)
    assert storage_fault(read_only).kind == "read-only"
    assert storage_fault(sa_exc.TimeoutError("QueuePool limit reached")).kind == "busy"
    for bug in (_wrapped(sqlite3.IntegrityError("UNIQUE"), sa_exc.IntegrityError),
                _wrapped(sqlite3.ProgrammingError("no such column"), sa_exc.ProgrammingError),
                ValueError("not a database error")):
        assert storage_fault(bug) is None, bug


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_write_health_logs_once_a_minute_and_probes_only_when_due(caplog):
    caplog.set_level(logging.WARNING, logger="emotive.study")
    clock = _Clock()
    health = WriteHealth(clock)
    assert health.writable and health.probe_due()  # nothing written yet
    health.wrote()
    clock.now += faults.PROBE_INTERVAL_S - 1
    assert not health.probe_due()
    clock.now += 1
    assert health.probe_due()
    health.wrote()
    full = faults.StorageFault("full", "database or disk is full")
    for _ in range(100):
        health.failed(full, "POST /api/responses")
        clock.now += 1.0
    assert not health.writable and health.probe_due() and health.refused == 100
    lines = [r.getMessage() for r in caplog.records]
    # The first failure, then one line a minute: at 60 s (60 refused since the first).
    assert len(lines) == 2, lines
    assert "takes no writes (the study database is full" in lines[0]
    assert "still takes no writes" in lines[1] and "60 request(s)" in lines[1]
    health.failed(faults.StorageFault("read-only", "attempt to write a readonly database"),
                  "the health check's test write", refused=False)
    assert len(caplog.records) == 3 and health.refused == 100  # another kind: logged at once
    health.wrote()
    assert health.writable and "takes writes again after 100.0 s" in caplog.records[-1].getMessage()
