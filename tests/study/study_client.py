"""A small synchronous client of the study API for the tests (``docs/study-protocol.md``)."""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

#: Seconds an HTTP request may take (a hang guard, not a budget).
REQUEST_SECONDS = 60.0
#: The admin token of the test servers.
ADMIN = "admin-token-for-tests"


def answers_for(questions: list[dict[str, Any]], value: int = 3) -> dict[str, Any]:
    """A valid answer to every question (likert ``value`` clipped, first option, centre cell)."""
    out: dict[str, Any] = {}
    for q in questions:
        if q["kind"] == "likert":
            out[q["id"]] = min(max(value, q["min"]), q["max"])
        elif q["kind"] == "choice":
            out[q["id"]] = q["options"][0]
        else:
            centre = (q["size"] + 1) // 2
            out[q["id"]] = {"valence": centre, "arousal": centre}
    return out


@dataclass
class Participant:
    """One joined participant."""

    client: httpx.Client
    token: str
    id: str
    plan: dict[str, Any]

    @property
    def headers(self) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.token}"}

    def submit(self, item: int, answers: dict[str, Any], key: str | None = None,
               stimulus: str | None = None) -> httpx.Response:
        body = {"item": item, "answers": answers, "rt_ms": 1500,
                "stimulus": stimulus or self.plan["items"][item]["stimulus"]}
        return self.client.post("/api/responses", json=body, headers={
            **self.headers, "Idempotency-Key": key or uuid.uuid4().hex})


def join(client: httpx.Client) -> Participant:
    reply = client.post("/api/participants", json={"consent": True})
    assert reply.status_code == 201, reply.text
    body = reply.json()
    plan = client.get("/api/plan", headers={"Authorization": f"Bearer {body['token']}"})
    assert plan.status_code == 200, plan.text
    return Participant(client, body["token"], body["participant"], plan.json())


def client_for(url: str) -> httpx.Client:
    return httpx.Client(base_url=url, timeout=REQUEST_SECONDS)


def admin_headers() -> dict[str, str]:
    return {"Authorization": f"Bearer {ADMIN}"}


def set_limits(folder: Path, **limits: float) -> None:
    """Set ``[limits]`` keys of the study folder's ``study.toml`` (before its server starts)."""
    text = (folder / "study.toml").read_text()
    for key, value in limits.items():
        head, _, tail = text.partition(f"\n{key} = ")
        assert tail, f"no {key} in study.toml"
        text = f"{head}\n{key} = {value}{tail[tail.index(chr(10)):]}"
    (folder / "study.toml").write_text(text)
