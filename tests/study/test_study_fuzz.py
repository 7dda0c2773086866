"""Hostile input to the study server: 1,000 fuzzed submissions, each refused with a 4xx and
a one-line reason, and nothing stored.

The requests are drawn from a seeded generator over the kinds of attack a participant page
could send or a script could forge: wrong JSON types, unknown stimuli and questions, values
out of range, replayed idempotency keys with other bodies, answers for items already given,
other participants' and made-up tokens, missing or malformed headers, bodies that are not
JSON, NaN, deep nesting and oversized bodies.
"""

from __future__ import annotations

import json
import random
from collections import Counter
from collections.abc import Callable
from typing import Any

import httpx
from study_client import Participant, answers_for, client_for, join

from emotive.study.testing import running_study_server

#: Fuzzed submissions sent.
COUNT = 1000

Request = tuple[dict[str, Any], bytes]


def _body(item: Any, stimulus: Any, answers: Any, **extra: Any) -> bytes:
    return json.dumps({"item": item, "stimulus": stimulus, "answers": answers, "rt_ms": 900,
                       **extra}).encode()


def _makers(me: Participant,  # noqa: C901 - one closure per kind of attack
            other: Participant, questions: list[dict[str, Any]],
            used_key: str) -> list[Callable[[random.Random], Request]]:
    good = answers_for(questions)
    stim = me.plan["items"][1]["stimulus"]
    auth = dict(me.headers)

    def headers(rng: random.Random, token: dict[str, str] | None = None) -> dict[str, str]:
        return {**(auth if token is None else token), "Idempotency-Key": f"fz-{rng.random():.12f}",
                "Content-Type": "application/json"}

    def wrong_type(rng: random.Random) -> Request:
        field = rng.choice(["item", "stimulus", "answers", "rt_ms"])
        bad = rng.choice(["1", 1.5, None, [], {}, True, -1e300]) if field != "rt_ms" else \
            rng.choice(["fast", -5, 1.5, True, 10**12])
        body = {"item": 1, "stimulus": stim, "answers": good, "rt_ms": 10, field: bad}
        if field == "stimulus" and isinstance(bad, str):
            body["stimulus"] = 42
        return headers(rng), json.dumps(body).encode()

    def unknown_stimulus(rng: random.Random) -> Request:
        return headers(rng), _body(1, rng.choice(["s99", "../study", "", "S01 ", "happy"]), good)

    def bad_answer(rng: random.Random) -> Request:
        answers = dict(good)
        q = rng.choice(questions)
        answers[q["id"]] = rng.choice([0, 6, 99, -1, "3", 3.0, None, [3], {"v": 1}, True])
        if rng.random() < 0.3:
            answers = {**good, "mood": 3} if rng.random() < 0.5 else {
                k: v for k, v in good.items() if k != q["id"]}
        return headers(rng), _body(1, stim, answers)

    def replayed_key(rng: random.Random) -> Request:
        return ({**auth, "Idempotency-Key": used_key},
                _body(0, me.plan["items"][0]["stimulus"], answers_for(questions, 5)))

    def answered_item(rng: random.Random) -> Request:
        return headers(rng), _body(0, me.plan["items"][0]["stimulus"], good)

    def foreign_token(rng: random.Random) -> Request:
        token = rng.choice([{}, {"Authorization": "Bearer pt_" + "x" * 43},
                            {"Authorization": "Basic " + me.token},
                            {"Authorization": "Bearer"}, {"Authorization": me.token}])
        if rng.random() < 0.3:
            # Another participant's token with this participant's item and stimulus.
            item = next(i for i in other.plan["items"] if i["stimulus"] != stim)["item"]
            return headers(rng, other.headers), _body(item, stim, good)
        return headers(rng, token), _body(1, stim, good)

    def bad_header(rng: random.Random) -> Request:
        key = rng.choice([None, "", "short", "has space in it", "ü" * 10, "x" * 129, "a/b/c/d/e"])
        h: dict[str, Any] = dict(auth)
        if key is not None:
            h["Idempotency-Key"] = key.encode("utf-8")
        return h, _body(1, stim, good)

    def not_json(rng: random.Random) -> Request:
        raw = rng.choice([b"", b"{", b"[]", b"null", b"\xff\xfe", b'{"item": NaN}',
                          b'{"item": Infinity, "stimulus": "s01"}', b"[" * 5000 + b"]" * 5000,
                          b'{"item": 1, "item": "x"}', b"{\"item\": 1e999}"])
        return headers(rng), raw

    def oversized(rng: random.Random) -> Request:
        pad = "x" * rng.choice([17_000, 100_000, 1_000_000])
        return headers(rng), _body(1, stim, good, note=pad)

    def bad_item(rng: random.Random) -> Request:
        return headers(rng), _body(rng.choice([-1, 4, 10**9, 2**63]), stim, good)

    return [wrong_type, unknown_stimulus, bad_answer, replayed_key, answered_item,
            foreign_token, bad_header, not_json, oversized, bad_item]


def test_a_thousand_fuzzed_submissions_are_refused_and_store_nothing(study_folder):
    toml = study_folder / "study.toml"
    toml.write_text(toml.read_text().replace("submit_per_second = 5.0",
                                             "submit_per_second = 100000.0")
                    .replace("submit_burst = 20", "submit_burst = 100000"))
    rng = random.Random(20261204)
    with running_study_server(study_folder) as url, client_for(url) as client:
        questions = client.get("/api/study").json()["questions"]
        me, other = join(client), join(client)
        used_key = "fuzz-used-key-0"
        assert me.submit(0, answers_for(questions), used_key).status_code == 201
        stored = client.get("/api/health").json()["responses"]
        makers = _makers(me, other, questions, used_key)
        kinds: Counter[str] = Counter()
        for _ in range(COUNT):
            make = rng.choice(makers)
            headers, body = make(rng)
            reply = client.post("/api/responses", content=body, headers=headers)
            kinds[make.__name__] += 1
            assert 400 <= reply.status_code < 500, (make.__name__, body[:200], reply.text)
            reason = reply.json()["error"]
            assert isinstance(reason, str) and reason and "\n" not in reason, reply.text
        assert client.get("/api/health").json()["responses"] == stored
        assert client.get("/api/plan", headers=me.headers).json()["answered"] == [0]
        assert client.get("/api/plan", headers=other.headers).json()["answered"] == []
    assert len(kinds) == len(makers) and min(kinds.values()) > COUNT // len(makers) // 2


def test_joining_needs_consent_and_nothing_else(study_folder):
    with running_study_server(study_folder) as url, httpx.Client(base_url=url) as client:
        for body in ({}, {"consent": False}, {"consent": "yes"}, {"consent": True, "name": "x"},
                     [], None, 1):
            reply = client.post("/api/participants", content=json.dumps(body))
            assert reply.status_code == 422 and "consent" in reply.json()["error"]
        assert client.get("/api/health").json()["participants"] == 0
