"""``emotive study simulate`` waiting for its server (:mod:`emotive.study.simulate_wait`).

It waits through a server that is not up yet, one restarted mid-run and a database that is
full for a while, then finishes with every acknowledged answer stored once; it gives up at
its deadline with one typed line. Servers start, stop and heal on observable events (the
failed tries a counting transport has seen, receipt lines), never after a fixed sleep;
wall time only bounds a hang.
"""

from __future__ import annotations

import asyncio
import json
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import httpx
import pytest
from storage_faults import DatabaseFault
from study_client import set_limits

from cli_helpers import run_main
from emotive.serve.server import bind
from emotive.study.app import create_app
from emotive.study.config import load_study
from emotive.study.errors import ServerUnavailable
from emotive.study.simulate import simulate
from emotive.study.simulate_raters import _rng
from emotive.study.simulate_wait import NOTICE_AFTER, Waits, backoff
from emotive.study.testing import serving

#: Wall seconds any one wait may take (a hang guard, not a budget), and the runs' deadline.
HANG_SECONDS = 120.0
#: Values one gaits submission stores.
VALUES = 5
#: Failed tries seen before the restarted server comes back (see the restart test).
TRIES_DOWN = 4 * 6 + 1


class Counting(httpx.AsyncBaseTransport):
    """The network, counting failed tries (no reply, 502, 503, 504); :meth:`arm` sets a
    callback for the ``n``-th failure from then on."""

    def __init__(self) -> None:
        self.inner = httpx.AsyncHTTPTransport()
        self.failures = 0
        self._at: tuple[int, Callable[[], None]] | None = None

    def arm(self, n: int, then: Callable[[], None]) -> None:
        self._at = (self.failures + n, then)

    def _failed(self) -> None:
        self.failures += 1
        if self._at is not None and self.failures == self._at[0]:
            self._at[1]()

    async def handle_async_request(self, request: httpx.Request) -> httpx.Response:
        try:
            reply = await self.inner.handle_async_request(request)
        except httpx.TransportError:
            self._failed()
            raise
        if reply.status_code in (502, 503, 504):
            self._failed()
        return reply

    async def aclose(self) -> None:
        await self.inner.aclose()


def _closed_port() -> socket.socket:
    """A socket bound on 127.0.0.1 and not listening: connecting is refused until a server
    starts on it (:func:`emotive.study.testing.serving` listens on it)."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    return sock


class _Simulation:
    """:func:`simulate` on its own thread, with a counting transport and notify lines."""

    def __init__(self, folder: Path, url: str, participants: int, concurrency: int,
                 receipts: Path | None = None, deadline: float = HANG_SECONDS) -> None:
        self.transport = Counting()
        self.lines: list[str] = []
        self.result: dict[str, Any] = {}
        study = load_study(folder)

        def run() -> None:
            try:
                self.result["summary"] = asyncio.run(simulate(
                    study, url, participants, concurrency, seed=5, careless=0.0,
                    receipts=receipts, progress=False, deadline=deadline,
                    notify=self.lines.append, transport=self.transport))
            except BaseException as exc:  # reported by summary()
                self.result["error"] = exc

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()

    def summary(self) -> dict[str, Any]:
        self.thread.join(HANG_SECONDS)
        assert not self.thread.is_alive(), "the simulation hangs"
        if "error" in self.result:
            raise self.result["error"]
        return self.result["summary"]


def _receipts(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def _assert_stored_once(app: Any, receipts: list[dict[str, Any]], summary: dict) -> None:
    from emotive.study.store import export_rows

    state = app.state.study
    exported: dict[tuple[str, int, str], int] = {}
    for row in export_rows(state.engine, state.study):
        key = (row["participant"], int(row["item"]), row["question"])
        exported[key] = exported.get(key, 0) + 1
    assert len({r["key"] for r in receipts}) == len(receipts) == summary["submissions"]
    acknowledged = [(r["participant"], r["item"], name) for r in receipts for name in r["values"]]
    assert len(acknowledged) == summary["acknowledged"]
    assert sorted(acknowledged) == sorted(exported), "stored = acknowledged, each once"
    assert set(exported.values()) == {1}


def test_it_waits_for_a_server_that_is_not_up_yet(study_folder):
    sock = _closed_port()
    started = threading.Event()
    url = f"http://127.0.0.1:{sock.getsockname()[1]}"
    run = _Simulation(study_folder, url, 2, 2)
    run.transport.arm(4, started.set)  # the server starts after the 4th refused try
    assert started.wait(HANG_SECONDS), "no tries"
    app = create_app(study_folder)
    try:
        with serving(app, sock):
            summary = run.summary()
    finally:
        app.state.study.engine.dispose()
    assert summary["completed"] == 2 and summary["server_gone"] is False
    assert summary["gave_up"] is None and summary["deadline_s"] == HANG_SECONDS
    assert run.transport.failures >= 4
    wait = summary["waits"][0]
    assert wait["for"].startswith("GET /api/study: no reply (ConnectError") and wait["seconds"] > 0
    assert run.lines[0].startswith(f"waiting for the study server at {url}: no reply")
    assert run.lines[-1].startswith(f"the study server at {url} answers after")


def test_it_waits_through_a_server_restart_and_stores_each_answer_once(study_folder,
                                                                        tmp_path):
    receipts = tmp_path / "receipts.jsonl"
    first = bind("127.0.0.1", 0)
    port = first.getsockname()[1]
    url = f"http://127.0.0.1:{port}"
    app = create_app(study_folder)
    with serving(app, first):
        run = _Simulation(study_folder, url, 12, 4, receipts)
        deadline = time.monotonic() + HANG_SECONDS
        while len(_receipts(receipts)) < 8 and run.thread.is_alive():
            assert time.monotonic() < deadline, "nothing acknowledged"
            run.thread.join(0.01)  # poll the receipts; returns at once when the run ends
        assert run.thread.is_alive(), "the run ended before the restart"
        down = threading.Event()
        # 4 workers, one failing request each: the 25th failure is some request's 7th try,
        # after 6 backoffs of at least 1.575 s in all, so the wait is one to report.
        run.transport.arm(TRIES_DOWN, down.set)
    app.state.study.engine.dispose()  # stopped, as a restart does
    assert down.wait(HANG_SECONDS), "no failed tries while the server was down"
    app = create_app(study_folder)
    try:
        with serving(app, bind("127.0.0.1", port)):
            summary = run.summary()
        lines = _receipts(receipts)
        _assert_stored_once(app, lines, summary)
    finally:
        app.state.study.engine.dispose()
    assert summary["completed"] == 12 and summary["server_gone"] is False
    assert summary["rejected"] == 0 and summary["acknowledged"] == 12 * 4 * VALUES
    assert summary["retries"] >= TRIES_DOWN
    assert any("no reply" in w["for"] for w in summary["waits"]), summary["waits"]


def test_it_waits_through_a_full_database_and_stores_each_answer_once(study_folder,
                                                                      tmp_path):
    receipts = tmp_path / "receipts.jsonl"
    set_limits(study_folder, submit_per_second=1000.0, submit_burst=1000)
    app = create_app(study_folder)
    fault = DatabaseFault(app.state.study.engine, "full")
    fault.fail()  # a full database from the start: the first joins still fit its pages
    try:
        with serving(app) as url:
            run = _Simulation(study_folder, url, 30, 4, receipts)
            run.transport.arm(3, fault.heal)  # space freed after the 3rd refusal (503)
            summary = run.summary()
        _assert_stored_once(app, _receipts(receipts), summary)
    finally:
        fault.heal()
        fault.remove()
        app.state.study.engine.dispose()
    assert run.transport.failures >= 3, "the database never filled"
    assert summary["completed"] == 30 and summary["server_gone"] is False
    assert summary["rejected"] == 0 and summary["acknowledged"] == 30 * 4 * VALUES
    full = [w for w in summary["waits"] if "503 the study database is full" in w["for"]]
    assert full and full[0]["seconds"] >= NOTICE_AFTER, summary["waits"]


def test_it_gives_up_at_its_deadline_in_one_typed_line(study_folder):
    sock = _closed_port()
    url = f"http://127.0.0.1:{sock.getsockname()[1]}"
    run = _Simulation(study_folder, url, 2, 1, deadline=0.3)
    with pytest.raises(ServerUnavailable) as caught:
        run.summary()
    sock.close()
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"no study server at {url} within "
                                                      "--deadline 0.3 s (")
    assert "the last: no reply (ConnectError" in message and "emotive study serve" in message
    assert f"({run.transport.failures} tries, the last" in message


def test_a_database_that_stays_read_only_makes_the_cli_give_up(study_folder, monkeypatch,
                                                              capsys):
    app = create_app(study_folder)
    fault = DatabaseFault(app.state.study.engine, "read-only")
    fault.fail()
    try:
        with serving(app) as url:
            code, out, err = run_main(monkeypatch, capsys, "study", "simulate", study_folder,
                                      "--url", url, "--participants", "2", "--deadline",
                                      "0.5")
    finally:
        fault.heal()
        fault.remove()
        app.state.study.engine.dispose()
    assert code == 2
    summary = json.loads(out.strip().splitlines()[-1])
    assert summary["server_gone"] is True and summary["acknowledged"] == 0
    assert "POST /api/participants: 503 the study database is read-only" in summary["gave_up"]
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "--deadline" in errors[0] and "read-only" in errors[0]
    assert "Traceback" not in err


def test_the_backoff_doubles_to_its_cap_and_the_same_seed_jitters_alike():
    first = [backoff(n, _rng(3, 7, 1)) for n in range(12)]
    again = [backoff(n, _rng(3, 7, 1)) for n in range(12)]
    other = [backoff(n, _rng(4, 7, 1)) for n in range(12)]
    assert first == again and first != other
    for n, pause in enumerate(first):
        base = min(0.05 * 2**n, 2.0)
        assert base / 2 <= pause <= base
    waits = Waits("http://h", 5.0, None)
    assert not waits.expired()
    waits.failed("a", "POST /x: no reply")
    waits.answered("a")
    assert waits.done == [], "a wait under a second is not reported"
