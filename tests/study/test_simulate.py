"""``emotive study simulate`` (:mod:`emotive.study.simulate`) against real study servers.

Simulated participants go through the HTTP API; the server's own counts (``/api/health``, the
admin participant table, the export) must agree with what the simulation says it got
acknowledged. Waits are on observable state (receipt lines, thread exits); wall time only
bounds a hang.
"""

from __future__ import annotations

import asyncio
import dataclasses
import json
import shutil
import socket
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
from study_client import ADMIN, admin_headers

from emotive.study.config import check_answer, load_study, parse_study
from emotive.study.design import plan_for
from emotive.study.errors import StudyError
from emotive.study.simulate import base_url, run_simulation, simulate
from emotive.study.simulate_raters import (
    Reading,
    check_items,
    draw_answers,
    find_check,
    rater_for,
    stimulus_reading,
)
from emotive.study.stimuli import load_readings
from emotive.study.testing import running_study_server

#: Wall seconds any one wait may take (a hang guard, not a budget).
HANG_SECONDS = 120.0
#: Values one gaits submission stores (four emotion scales and naturalness).
VALUES = 5


def _receipts(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def _exported(folder: Path, db_url: str | None) -> Counter:
    from emotive.study.db import open_database
    from emotive.study.store import export_rows

    study = load_study(folder)
    engine = open_database(study.folder, db_url)
    try:
        return Counter((r["participant"], int(r["item"]), r["question"])
                       for r in export_rows(engine, study))
    finally:
        engine.dispose()


def _assert_receipts_stored_once(receipts: list[dict[str, Any]], exported: Counter) -> None:
    assert len({r["key"] for r in receipts}) == len(receipts), "a key acknowledged twice"
    for r in receipts:
        for name in r["values"]:
            assert exported[(r["participant"], r["item"], name)] == 1, (r, name)


def test_six_participants_are_acknowledged_exactly_as_stored(study_folder, db_url, tmp_path):
    study = load_study(study_folder)
    receipts = tmp_path / "receipts.jsonl"
    with running_study_server(study_folder, admin_token=ADMIN, db_url=db_url) as url:
        summary = run_simulation(study, url, 6, 3, seed=3, careless=0.5,
                                 readings=load_readings(study.folder), receipts=receipts,
                                 progress=False)
        health = httpx.get(f"{url}/api/health", timeout=HANG_SECONDS).json()
        table = httpx.get(f"{url}/api/admin/participants", headers=admin_headers(),
                          timeout=HANG_SECONDS).json()["participants"]
    assert summary["server_gone"] is False
    assert summary["participants"] == summary["completed"] == 6
    assert summary["rejected"] == 0 and summary["first_rejection"] is None
    assert summary["submissions"] == 6 * 4
    assert summary["acknowledged"] == health["responses"] == 6 * 4 * VALUES
    assert 0 < summary["p50_ms"] <= summary["p99_ms"] and summary["responses_per_s"] > 0
    # Careless raters were drawn (seed 3: some, not all) and every one failed the check.
    careless = set(summary["careless"])
    assert 0 < len(careless) < 6
    failed = {row["participant"]: row["failed_checks"] for row in table}
    assert set(failed) >= careless
    assert all(failed[p] >= 1 for p in careless), failed
    assert all(n == 0 for p, n in failed.items() if p not in careless), failed
    # One receipt per acknowledged submission; the export holds each value exactly once.
    lines = _receipts(receipts)
    assert len(lines) == summary["submissions"]
    assert sum(len(r["values"]) for r in lines) == summary["acknowledged"]
    exported = _exported(study_folder, db_url)
    assert sum(exported.values()) == summary["acknowledged"]
    _assert_receipts_stored_once(lines, exported)


def test_the_same_seed_gives_the_same_answers(study_template, tmp_path):
    runs = []
    for name in ("one", "two"):
        folder = tmp_path / name
        shutil.copytree(study_template, folder)
        study = load_study(folder)
        receipts = tmp_path / f"{name}.jsonl"
        with running_study_server(folder) as url:
            # One at a time: the server admits them in the simulation's order.
            summary = run_simulation(study, url, 4, 1, seed=7, careless=0.5,
                                     readings=load_readings(folder), receipts=receipts,
                                     progress=False)
        assert summary["completed"] == 4
        runs.append([(r["index"], r["item"], r["stimulus"], r["values"])
                     for r in _receipts(receipts)])
    assert runs[0] == runs[1]
    assert len(runs[0]) == 4 * 4


def _study(folder: Path, questions: list[dict], expect: dict) -> Any:
    return parse_study(folder, {
        "title": "Kinds", "completion_code": "EMO-TEST", "consent": "ok",
        "questions": questions,
        "stimuli": [{"id": "s01", "file": "stimuli/s01.glb", "intended": "happy"},
                    {"id": "s02", "file": "stimuli/s02.glb", "intended": "sad"},
                    {"id": "s03", "file": "stimuli/s03.glb"}],
        "attention_checks": [{"id": "check-1", "stimulus": "s01", "position": 1,
                              "instruction": "answer as told", "expect": expect}],
    }, folder / "study.toml")


def _likert(qid: str, high: int = 5) -> dict:
    return {"id": qid, "kind": "likert", "prompt": qid, "min": 1, "max": high}


def _check_answers(study: Any, reading: Reading, expect: dict) -> list[dict]:
    """Careful raters' answers to a rated item; every rater's answers to the check."""
    careful = [rater_for(0, k, 0.0) for k in range(40)]
    answers = [draw_answers(study, r, 0, 2, reading)[0] for r in careful]
    for a in answers:
        assert all(check_answer(study.question(q), v) is None for q, v in a.items()), a
    # The same (seed, participant, item) gives the same answers; another seed others.
    assert [draw_answers(study, r, 0, 2, reading) for r in careful[:5]] == [
        draw_answers(study, r, 0, 2, reading) for r in careful[:5]]
    assert [draw_answers(study, r, 0, 2, reading) for r in careful] != [
        draw_answers(study, r, 1, 2, reading) for r in careful]
    check = study.checks[0]
    for r in careful[:10]:
        a, rt_ms = draw_answers(study, r, 0, 1, reading, check)
        assert {k: a[k] for k in expect} == expect and rt_ms >= 3000
    careless = [r for r in (rater_for(0, k, 0.5) for k in range(40)) if r.careless]
    assert 10 < len(careless) < 30
    for r in careless:
        a, rt_ms = draw_answers(study, r, 0, 1, reading, check)
        assert all(check_answer(study.question(q), v) is None for q, v in a.items()), a
        assert {k: a[k] for k in expect} != expect and rt_ms < 1500
    return answers


def test_answers_follow_the_reading_and_the_checks(tmp_path):
    study = _study(tmp_path, [
        _likert("happy"), _likert("sad"), _likert("naturalness"), _likert("confidence"),
        _likert("valence", 7), _likert("arousal", 7),
        {"id": "emotion", "kind": "choice", "prompt": "p",
         "options": ["happy", "sad", "angry", "neutral"]},
        {"id": "source", "kind": "choice", "prompt": "p", "options": ["a", "b"]},
    ], {"emotion": "sad", "valence": 1, "happy": 1})
    happy = stimulus_reading(study, None, "s01")  # from the intended emotion
    assert happy.probabilities["happy"] == pytest.approx(1.0) and happy.valence > 0.5
    assert set(stimulus_reading(study, None, "s03").probabilities.values()) == {0.25}
    read = stimulus_reading(study, {"stimuli": {"s03": {
        "probabilities": {"happy": 0.0, "sad": 0.0, "angry": 2.0, "neutral": 0.0},
        "valence": -0.6, "arousal": 0.8, "unsure": False}}}, "s03")
    assert read == Reading({"happy": 0.0, "sad": 0.0, "angry": 1.0, "neutral": 0.0}, -0.6, 0.8)

    answers = _check_answers(study, happy, {"emotion": "sad", "valence": 1, "happy": 1})
    assert np.mean([a["happy"] for a in answers]) > 4 > 2 > np.mean([a["sad"] for a in answers])
    assert Counter(a["emotion"] for a in answers).most_common(1)[0][0] == "happy"
    assert {a["source"] for a in answers} == {"a", "b"}
    assert all(3 <= a["confidence"] <= 5 for a in answers)
    assert np.mean([a["valence"] for a in answers]) > 5
    assert round(np.mean([a["naturalness"] for a in answers])) == 4


def test_grid_answers_follow_valence_and_arousal(tmp_path):
    study = _study(tmp_path, [{"id": "affect", "kind": "grid", "prompt": "p", "size": 9}],
                   {"affect": [5, 5]})
    sad = stimulus_reading(study, {"stimuli": {"s02": {
        "probabilities": {"sad": 1.0}, "valence": -0.8, "arousal": -0.8}}}, "s02")
    answers = _check_answers(study, sad, {"affect": {"valence": 5, "arousal": 5}})
    assert np.mean([a["affect"]["valence"] for a in answers]) < 2.5
    assert np.mean([a["affect"]["arousal"] for a in answers]) < 2.5


def test_attention_checks_are_found_where_the_plans_place_them(study_template):
    study = load_study(study_template)
    for index in range(6):
        plan = plan_for(study, index)
        at = check_items(study, plan.condition)
        for it in plan.items:
            check = study.checks[0] if it.check else None
            item = {"item": it.item, "stimulus": it.stimulus,
                    "instruction": check.instruction if check else None}
            assert find_check(study, at, item) == check
            assert (at.get(it.item) is not None) == bool(it.check)


def test_a_lost_reply_is_retried_with_the_same_key_and_counted_once(study_folder, tmp_path):
    from emotive.study.app import create_app
    from emotive.study.store import counts

    class Flaky(httpx.AsyncBaseTransport):
        """Answers the first submission 429, stores the second and loses its reply."""

        def __init__(self, inner: httpx.AsyncBaseTransport) -> None:
            self.inner = inner
            self.submissions: list[tuple[str, int]] = []  # (key, status; -1: reply lost)

        async def handle_async_request(self, request: httpx.Request) -> httpx.Response:
            if request.url.path != "/api/responses":
                return await self.inner.handle_async_request(request)
            key, n = request.headers["idempotency-key"], len(self.submissions)
            if n == 0:
                self.submissions.append((key, 429))
                return httpx.Response(429, headers={"Retry-After": "0"},
                                      json={"error": "slow down"})
            reply = await self.inner.handle_async_request(request)
            await reply.aread()
            self.submissions.append((key, -1 if n == 1 else reply.status_code))
            if n == 1:
                raise httpx.ReadError("the reply was lost", request=request)
            return reply

    app = create_app(study_folder)
    flaky = Flaky(httpx.ASGITransport(app=app))
    study = load_study(study_folder)
    receipts = tmp_path / "receipts.jsonl"
    try:
        summary = asyncio.run(simulate(study, "http://study.test", 2, 1, seed=1, careless=0.0,
                                       receipts=receipts, progress=False, transport=flaky))
        stored = counts(app.state.study.engine)[1]
    finally:
        app.state.study.engine.dispose()
    first = flaky.submissions[0][0]
    assert flaky.submissions[:3] == [(first, 429), (first, -1), (first, 200)]  # 200: replayed
    assert summary["retries"] == 2 and summary["rejected"] == 0
    assert summary["submissions"] == 2 * 4 and summary["completed"] == 2
    assert summary["acknowledged"] == stored == 2 * 4 * VALUES
    lines = _receipts(receipts)
    assert [r["key"] for r in lines].count(first) == 1
    assert len({r["key"] for r in lines}) == len(lines) == summary["submissions"]


def test_a_server_that_goes_away_stops_the_run_cleanly(study_folder, tmp_path):
    study = load_study(study_folder)
    receipts = tmp_path / "receipts.jsonl"
    result: dict[str, Any] = {}
    with running_study_server(study_folder) as url:
        def run() -> None:
            try:
                result["summary"] = run_simulation(study, url, 400, 4, seed=2, receipts=receipts,
                                                   progress=False, deadline=1.0)
            except BaseException as exc:  # reported below
                result["error"] = exc

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        deadline = time.monotonic() + HANG_SECONDS
        while len(_receipts(receipts)) < 24 and thread.is_alive():
            assert time.monotonic() < deadline, "nothing acknowledged"
            thread.join(0.01)  # poll the receipts; returns at once when the run ends
    thread.join(HANG_SECONDS)
    assert not thread.is_alive() and "error" not in result, result
    summary = result["summary"]
    assert summary["server_gone"] is True and summary["deadline_s"] == 1.0
    assert "no reply" in summary["gave_up"] and summary["gave_up"].endswith("for 1 s")
    assert summary["submissions"] >= 24 and 0 < summary["completed"] < 400
    lines = _receipts(receipts)
    assert len(lines) == summary["submissions"]
    assert summary["acknowledged"] == sum(len(r["values"]) for r in lines)
    exported = _exported(study_folder, None)
    _assert_receipts_stored_once(lines, exported)
    # At most the submissions in flight when it stopped were stored without a receipt.
    assert sum(exported.values()) - summary["acknowledged"] <= 4 * VALUES


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_no_server_a_bad_url_another_study_or_bad_receipts_are_study_errors(study_folder):
    study = load_study(study_folder)
    url = f"http://127.0.0.1:{_free_port()}"
    with pytest.raises(StudyError, match=r"no study server at .*emotive study serve"):
        run_simulation(study, url, 2, 1, seed=0, progress=False, deadline=0.2)
    for bad in ("127.0.0.1:8000", "ftp://127.0.0.1", "http://", "http://h/?a=1"):
        with pytest.raises(StudyError, match="--url"):
            run_simulation(study, bad, 2, 1, seed=0, progress=False)
    assert base_url("http://127.0.0.1:8000/") == "http://127.0.0.1:8000"
    with running_study_server(study_folder) as url:
        other = dataclasses.replace(study, title="Another study")
        with pytest.raises(StudyError, match="serves the study"):
            run_simulation(other, url, 2, 1, seed=0, progress=False)
        with pytest.raises(StudyError, match="--receipts"):
            run_simulation(study, url, 2, 1, seed=0, progress=False,
                           receipts=study_folder / "no-such-folder" / "r.jsonl")
        stored = httpx.get(f"{url}/api/health", timeout=HANG_SECONDS).json()
    assert stored["participants"] == 0, "nobody joined a study that is not theirs"
