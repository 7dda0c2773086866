"""The study server's HTTP API on SQLite and on PostgreSQL: joining, plans, idempotent
submissions, completion, admin routes, limits and the design lock."""

from __future__ import annotations

import csv
import io
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from study_client import ADMIN, admin_headers, answers_for, client_for, join

from emotive.study.app import create_app
from emotive.study.errors import StudyError
from emotive.study.testing import running_study_server


def _set_limits(folder: Path, **limits: float) -> None:
    text = (folder / "study.toml").read_text()
    for key, value in limits.items():
        head, _, tail = text.partition(f"\n{key} = ")
        text = f"{head}\n{key} = {value}{tail[tail.index(chr(10)):]}"
    (folder / "study.toml").write_text(text)


def test_a_whole_participant_is_stored_once_and_exported(study_folder, db_url):
    with running_study_server(study_folder, admin_token=ADMIN, db_url=db_url) as url, \
            client_for(url) as client:
        study = client.get("/api/study").json()
        questions = study["questions"]
        a, b = join(client), join(client)
        assert a.id != b.id and a.token != b.token
        assert len(a.plan["items"]) == study["items"] == 4
        assert [it["item"] for it in a.plan["items"]] == [0, 1, 2, 3]
        assert sum(it["instruction"] is not None for it in a.plan["items"]) == 1
        assert a.plan["items"][0]["effectors"], "effector joints of the stimulus"
        for it in a.plan["items"]:
            key = uuid.uuid4().hex
            first = a.submit(it["item"], answers_for(questions), key)
            assert first.status_code == 201 and first.json() == {
                "item": it["item"], "stored": len(questions), "replayed": False}
            again = a.submit(it["item"], answers_for(questions), key)
            assert again.status_code == 200 and again.json()["replayed"] is True
        other_key = a.submit(0, answers_for(questions))
        assert other_key.status_code == 409 and "already answered" in other_key.json()["error"]
        reused = b.submit(0, answers_for(questions, 5), key="shared-key-0001")
        assert reused.status_code == 201
        changed = b.submit(0, answers_for(questions, 4), key="shared-key-0001")
        assert changed.status_code == 409 and "another submission" in changed.json()["error"]
        early = client.post("/api/complete", headers=b.headers, json={})
        assert early.status_code == 409 and "unanswered" in early.json()["error"]
        code = client.post("/api/complete", headers=a.headers, json={})
        assert code.status_code == 200
        assert code.json()["completion_code"].startswith("EMO-")
        plan = client.get("/api/plan", headers=a.headers).json()
        assert plan["completed"] is True and plan["answered"] == [0, 1, 2, 3]
        assert client.get("/api/plan", headers=b.headers).json()["answered"] == [0]
        health = client.get("/api/health").json()
        assert health["database"] == ("sqlite" if db_url is None else "postgresql")
        assert health["responses"] == 5 * len(questions) and health["participants"] == 2
        progress = client.get("/api/admin/progress", headers=admin_headers()).json()
        assert progress["completed"] == 1 and progress["responses"] == 5 * len(questions)
        rows = list(csv.DictReader(io.StringIO(client.get(
            "/api/admin/export.csv", headers=admin_headers()).text)))
    assert len(rows) == 5 * len(questions)
    keys = {(r["participant"], r["item"], r["question"]) for r in rows}
    assert len(keys) == len(rows)
    assert {r["participant"] for r in rows} == {a.id, b.id}
    check_rows = [r for r in rows if r["check"]]
    assert len(check_rows) == len(questions) and check_rows[0]["check"] == "check-1"
    assert all(r["time"].endswith("Z") and r["rt_ms"] == "1500" for r in rows)


def test_concurrent_retries_of_one_submission_store_it_once(study_folder, db_url):
    _set_limits(study_folder, submit_burst=100)
    with running_study_server(study_folder, db_url=db_url) as url, client_for(url) as client:
        questions = client.get("/api/study").json()["questions"]
        p = join(client)
        with ThreadPoolExecutor(8) as pool:
            replies = list(pool.map(lambda _: p.submit(1, answers_for(questions), "same-key-1"),
                                    range(16)))
        codes = sorted(r.status_code for r in replies)
        assert codes.count(201) == 1 and codes.count(200) == 15, codes
        with ThreadPoolExecutor(8) as pool:
            replies = list(pool.map(lambda i: p.submit(2, answers_for(questions),
                                                       f"other-key-{i:04d}"), range(16)))
        codes = sorted(r.status_code for r in replies)
        assert codes.count(201) == 1 and codes.count(409) == 15, codes
        assert client.get("/api/health").json()["responses"] == 2 * len(questions)


def test_tokens_keep_participants_and_admins_apart(study_folder):
    with running_study_server(study_folder, admin_token=ADMIN) as url, \
            client_for(url) as client:
        p = join(client)
        assert client.get("/api/plan").status_code == 401
        wrong = client.get("/api/plan", headers={"Authorization": "Bearer pt_nobody"})
        assert wrong.status_code == 401 and "unknown participant token" in wrong.json()["error"]
        as_admin = client.get("/api/plan", headers=admin_headers())
        assert as_admin.status_code == 401
        for route in ("/api/admin/progress", "/api/admin/participants",
                      "/api/admin/export.csv"):
            assert client.get(route, headers=p.headers).status_code == 403
            assert client.get(route).status_code == 403
        assert client.post("/api/admin/exclusions", headers=p.headers,
                           json={"participant": p.id, "excluded": True}).status_code == 403
        excluded = client.post("/api/admin/exclusions", headers=admin_headers(),
                               json={"participant": p.id, "excluded": True, "reason": "test"})
        assert excluded.status_code == 200
        table = client.get("/api/admin/participants", headers=admin_headers()).json()
        assert table["participants"][0]["excluded"] is True
        assert "set-cookie" not in {k.lower() for k in client.get("/api/plan",
                                                                  headers=p.headers).headers}


def test_the_admin_api_is_off_without_an_admin_token(study_folder):
    with running_study_server(study_folder) as url, client_for(url) as client:
        reply = client.get("/api/admin/progress", headers=admin_headers())
        assert reply.status_code == 403 and "--admin-token" in reply.json()["error"]


def test_rate_limits_answer_429_with_a_wait(study_folder):
    _set_limits(study_folder, submit_per_second=1.0, submit_burst=2, joins_per_minute=3.0)
    with running_study_server(study_folder) as url, client_for(url) as client:
        questions = client.get("/api/study").json()["questions"]
        p = join(client)
        codes = [p.submit(i, answers_for(questions)).status_code for i in range(4)]
        assert codes[:2] == [201, 201] and 429 in codes[2:], codes
        limited = next(r for r in (p.submit(3, answers_for(questions)) for _ in range(3))
                       if r.status_code == 429)
        assert "Retry-After" in limited.headers and "second" in limited.json()["error"]
        joins = [client.post("/api/participants", json={"consent": True}).status_code
                 for _ in range(4)]
        assert joins.count(201) == 2 and joins[-1] == 429, joins


def test_a_changed_design_is_refused_once_participants_answered(study_folder):
    with running_study_server(study_folder) as url, client_for(url) as client:
        join(client)
    toml = study_folder / "study.toml"
    toml.write_text(toml.read_text().replace("seed = 1", "seed = 2"))
    with pytest.raises(StudyError, match="another design"):
        create_app(study_folder)
    toml.write_text(toml.read_text().replace("seed = 2", "seed = 1"))
    create_app(study_folder).state.study.engine.dispose()


def test_pages_and_stimuli_are_served_without_anything_off_the_host(study_folder):
    with running_study_server(study_folder) as url, client_for(url) as client:
        page = client.get("/")
        assert page.status_code == 200 and "text/html" in page.headers["content-type"]
        assert "default-src 'self'" in page.headers["content-security-policy"]
        assert client.get("/admin").status_code == 200
        glb = client.get("/api/stimuli/s01.glb")
        assert glb.status_code == 200 and glb.content[:4] == b"glTF"
        missing = client.get("/api/stimuli/../study.toml")
        assert missing.status_code == 404
        assert client.get("/api/stimuli/s99.glb").status_code == 404
        assert client.get("/static/vendor/three/three.module.js").status_code == 200
