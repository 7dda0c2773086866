"""What the study server does to its database: join, answer, complete, report, export.

Every function takes the engine and runs its own transaction, so it can be called from any
thread. A submission is stored in one transaction with all its values; the unique constraints
of :mod:`emotive.study.db` make a retried or concurrent duplicate fail instead of doubling a
row, and :func:`submit` turns that into the replay or conflict answer of the protocol.
"""

from __future__ import annotations

import hashlib
import json
import secrets
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from datetime import datetime
from enum import Enum
from typing import Any

from sqlalchemy import func, insert, select, update
from sqlalchemy.engine import Engine
from sqlalchemy.exc import IntegrityError

from emotive.study import db
from emotive.study.config import StudyConfig, check_answer, stored_values
from emotive.study.design import Plan, PlanItem, plan_for
from emotive.study.errors import StudyError

#: Attempts at taking the next join order when concurrent joins collide.
JOIN_ATTEMPTS = 20
#: Columns of the export, in order (one row per stored value).
EXPORT_COLUMNS = ("participant", "condition", "stimulus", "question", "value", "time", "item",
                  "repeat", "check", "source", "intended", "rt_ms", "excluded")


class Rejected(StudyError):
    """A request the protocol refuses; ``status`` is its HTTP status.

    Args:
        status: the HTTP status.
        message: the one-line reason.
        retry_after: seconds to send in ``Retry-After`` (a 503 that may succeed later).
    """

    def __init__(self, status: int, message: str, retry_after: float | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.retry_after = retry_after


class Outcome(Enum):
    """What :func:`submit` did."""

    STORED = "stored"
    REPLAYED = "replayed"


@dataclass(frozen=True)
class Participant:
    """A participant as the server sees them."""

    id: int
    public_id: str
    join_index: int
    condition: str
    plan: Plan
    completed: bool


def hash_token(token: str) -> str:
    """SHA-256 hex digest of a token (only this is stored)."""
    return hashlib.sha256(token.encode()).hexdigest()


def _plan_json(plan: Plan) -> str:
    return json.dumps({"index": plan.index, "condition": plan.condition, "render": plan.render,
                       "items": [[i.stimulus, i.repeat, i.check] for i in plan.items]})


def _plan_from(text: str) -> Plan:
    raw = json.loads(text)
    items = tuple(PlanItem(n, s, r, c) for n, (s, r, c) in enumerate(raw["items"]))
    return Plan(raw["index"], raw["condition"], raw["render"], items)


def check_design(engine: Engine, study: StudyConfig) -> None:
    """Record the study's design fingerprint, or refuse a design changed since the first run.

    Raises:
        StudyError: the database was made for another design.
    """
    fingerprint = study.design_fingerprint
    with engine.begin() as conn:
        stored = conn.execute(select(db.study_meta.c.value).where(
            db.study_meta.c.key == "design")).scalar_one_or_none()
        if stored is None:
            conn.execute(insert(db.study_meta).values(key="design", value=fingerprint))
            return
    if stored != fingerprint:
        raise StudyError(
            f"the database of {study.folder} holds responses to another design of the study "
            "(study.toml's stimuli, conditions, questions, checks, seed or repeats changed); "
            "undo the change, or start a new study folder (or --db) for the new design")


def join(engine: Engine, study: StudyConfig) -> tuple[str, Participant]:
    """Admit a new participant: a token, the next join order and its plan.

    Returns:
        The token (shown to the participant once, stored only hashed) and the participant.
    """
    token = "pt_" + secrets.token_urlsafe(32)
    public_id = "p-" + secrets.token_hex(5)
    for _ in range(JOIN_ATTEMPTS):
        try:
            with engine.begin() as conn:
                index = conn.execute(select(func.coalesce(
                    func.max(db.participants.c.join_index) + 1, 0))).scalar_one()
                plan = plan_for(study, index)
                row = conn.execute(insert(db.participants).values(
                    public_id=public_id, token_hash=hash_token(token), join_index=index,
                    condition=plan.condition, plan=_plan_json(plan), joined_at=db.now(),
                    excluded=False, exclusion_reason="").returning(db.participants.c.id))
                pid = row.scalar_one()
            return token, Participant(pid, public_id, index, plan.condition, plan, False)
        except IntegrityError:
            continue
    raise Rejected(503, "the server is admitting many participants at once; try again in "
                   "1 s", retry_after=1)


def by_token(engine: Engine, token: str) -> Participant | None:
    """The participant holding ``token``, or ``None``."""
    p = db.participants.c
    with engine.connect() as conn:
        row = conn.execute(select(p.id, p.public_id, p.join_index, p.condition, p.plan,
                                  p.completed_at).where(
            p.token_hash == hash_token(token))).one_or_none()
    if row is None:
        return None
    return Participant(row.id, row.public_id, row.join_index, row.condition,
                       _plan_from(row.plan), row.completed_at is not None)


def answered_items(engine: Engine, participant: Participant) -> list[int]:
    """Items the participant has answered, ascending."""
    s = db.submissions.c
    with engine.connect() as conn:
        rows = conn.execute(select(s.item).where(s.participant_id == participant.id)
                            .order_by(s.item))
        return [r.item for r in rows]


def body_hash(item: int, stimulus: str, answers: Mapping[str, Any], rt_ms: int | None) -> str:
    """A digest of a submission's content (what a replay must repeat)."""
    text = json.dumps({"item": item, "stimulus": stimulus, "answers": answers, "rt_ms": rt_ms},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def check_submission(study: StudyConfig, participant: Participant, item: int, stimulus: str,
                     answers: Mapping[str, Any]) -> dict[str, float | str]:
    """The values a valid submission stores, or :class:`Rejected` naming what is wrong."""
    if not 0 <= item < len(participant.plan.items):
        raise Rejected(404, f"item {item} is not in your plan (items 0 to "
                       f"{len(participant.plan.items) - 1})")
    shown = participant.plan.items[item].stimulus
    if stimulus != shown:
        raise Rejected(422, f"item {item} shows stimulus {shown!r}, not {stimulus!r}")
    expected = [q.id for q in study.questions]
    missing = [q for q in expected if q not in answers]
    unknown = sorted(set(answers) - set(expected))
    if unknown:
        raise Rejected(422, f"unknown question(s) {unknown}; the study asks {expected}")
    if missing:
        raise Rejected(422, f"missing answer(s) to {missing}; answer every question once")
    values: dict[str, float | str] = {}
    for question in study.questions:
        problem = check_answer(question, answers[question.id])
        if problem:
            raise Rejected(422, problem)
        values.update(stored_values(question, answers[question.id]))
    return values


def _existing(conn: Any, participant: Participant, key: str) -> Any:
    s = db.submissions.c
    return conn.execute(select(s.item, s.body_hash).where(
        s.participant_id == participant.id, s.idempotency_key == key)).one_or_none()


def _replay(participant: Participant, engine: Engine, key: str, digest: str, item: int,
            values: Mapping[str, Any]) -> tuple[Outcome, int]:
    with engine.connect() as conn:
        prior = _existing(conn, participant, key)
    if prior is None:
        raise Rejected(409, f"item {item} is already answered; each item takes one answer")
    if prior.body_hash != digest or prior.item != item:
        raise Rejected(409, "this Idempotency-Key was used for another submission; use a new "
                       "key for each item")
    return Outcome.REPLAYED, len(values)


def submit(engine: Engine, study: StudyConfig, participant: Participant, key: str, item: int,
           stimulus: str, answers: Mapping[str, Any], rt_ms: int | None
           ) -> tuple[Outcome, int]:
    """Store one item's answers once.

    Returns:
        What happened and how many values the submission holds.

    Raises:
        Rejected: an invalid submission (404/422), an answered item or a reused key (409).
    """
    values = check_submission(study, participant, item, stimulus, answers)
    digest = body_hash(item, stimulus, answers, rt_ms)
    with engine.connect() as conn:
        prior = _existing(conn, participant, key)
    if prior is not None:
        return _replay(participant, engine, key, digest, item, values)
    try:
        with engine.begin() as conn:
            sub_id = conn.execute(insert(db.submissions).values(
                participant_id=participant.id, item=item, idempotency_key=key,
                body_hash=digest, rt_ms=rt_ms, created_at=db.now(),
            ).returning(db.submissions.c.id)).scalar_one()
            conn.execute(insert(db.responses), [
                {"submission_id": sub_id, "participant_id": participant.id, "item": item,
                 "stimulus": stimulus, "question": name,
                 "value_num": value if isinstance(value, float) else None,
                 "value_text": value if isinstance(value, str) else None}
                for name, value in values.items()])
    except IntegrityError:
        return _replay(participant, engine, key, digest, item, values)
    return Outcome.STORED, len(values)


def complete(engine: Engine, study: StudyConfig, participant: Participant) -> str:
    """Mark the participant complete and give the completion code.

    Raises:
        Rejected: items are still unanswered (409).
    """
    done = answered_items(engine, participant)
    left = len(participant.plan.items) - len(done)
    if left:
        raise Rejected(409, f"{left} item(s) are still unanswered; answer every item first")
    p = db.participants.c
    with engine.begin() as conn:
        conn.execute(update(db.participants).where(p.id == participant.id,
                                                   p.completed_at.is_(None))
                     .values(completed_at=db.now()))
    return study.completion_code


def counts(engine: Engine) -> tuple[int, int]:
    """Participants and stored values in the database."""
    with engine.connect() as conn:
        joined = conn.execute(select(func.count()).select_from(db.participants)).scalar_one()
        stored = conn.execute(select(func.count()).select_from(db.responses)).scalar_one()
    return int(joined), int(stored)


def _failed_checks(study: StudyConfig, plan: Plan, given: Mapping[tuple[int, str], Any]) -> int:
    checks = {c.id: c for c in study.checks}
    failed = 0
    for it in plan.items:
        if not it.check:
            continue
        expect = checks[it.check].expect
        for qid, value in expect.items():
            question = study.question(qid)
            if question.kind == "grid" and isinstance(value, list):
                value = dict(zip(("valence", "arousal"), value, strict=True))
            wanted = stored_values(question, value)
            got = {name: given.get((it.item, name)) for name in wanted}
            if any(got[name] is None for name in wanted):
                continue
            if any(got[name] != wanted[name] for name in wanted):
                failed += 1
                break
    return failed


def participant_table(engine: Engine, study: StudyConfig) -> list[dict[str, Any]]:
    """One row per participant for the admin page (see the protocol's admin routes)."""
    p, r = db.participants.c, db.responses.c
    with engine.connect() as conn:
        people = conn.execute(select(p.id, p.public_id, p.condition, p.plan, p.joined_at,
                                     p.completed_at, p.excluded, p.exclusion_reason)
                              .order_by(p.join_index)).all()
        values: dict[int, dict[tuple[int, str], Any]] = {}
        for row in conn.execute(select(r.participant_id, r.item, r.question, r.value_num,
                                       r.value_text)):
            values.setdefault(row.participant_id, {})[(row.item, row.question)] = (
                row.value_num if row.value_num is not None else row.value_text)
    out = []
    for row in people:
        plan = _plan_from(row.plan)
        given = values.get(row.id, {})
        out.append({
            "participant": row.public_id, "condition": row.condition,
            "joined": db.as_utc(row.joined_at).isoformat(),
            "completed": row.completed_at is not None,
            "answered": len({item for item, _ in given}), "items": len(plan.items),
            "failed_checks": _failed_checks(study, plan, given),
            "excluded": bool(row.excluded), "reason": row.exclusion_reason,
        })
    return out


def progress(engine: Engine, study: StudyConfig) -> dict[str, Any]:
    """Participants, completions and stored values, in all and per condition."""
    p, r = db.participants.c, db.responses.c
    per = {c.name: {"joined": 0, "completed": 0, "responses": 0} for c in study.conditions}
    with engine.connect() as conn:
        for row in conn.execute(select(p.condition, func.count(), func.count(p.completed_at))
                                .group_by(p.condition)):
            entry = per.setdefault(row[0], {"joined": 0, "completed": 0, "responses": 0})
            entry["joined"], entry["completed"] = int(row[1]), int(row[2])
        for row in conn.execute(select(p.condition, func.count()).select_from(
                db.responses.join(db.participants, r.participant_id == p.id))
                .group_by(p.condition)):
            per[row[0]]["responses"] = int(row[1])
    return {"participants": sum(e["joined"] for e in per.values()),
            "completed": sum(e["completed"] for e in per.values()),
            "responses": sum(e["responses"] for e in per.values()), "conditions": per}


def set_excluded(engine: Engine, public_id: str, excluded: bool, reason: str) -> None:
    """Exclude a participant from the analysis (or take the exclusion back).

    Raises:
        Rejected: no participant of that id (404).
    """
    p = db.participants.c
    with engine.begin() as conn:
        done = conn.execute(update(db.participants).where(p.public_id == public_id)
                            .values(excluded=excluded, exclusion_reason=reason[:500]))
    if done.rowcount == 0:
        raise Rejected(404, f"no participant {public_id!r}")


def _time(moment: datetime) -> str:
    return db.as_utc(moment).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def export_rows(engine: Engine, study: StudyConfig) -> Iterator[dict[str, str]]:
    """Every stored value as one row of :data:`EXPORT_COLUMNS`, in participant and item order."""
    p, s, r = db.participants.c, db.submissions.c, db.responses.c
    stimuli = {st.id: st for st in study.stimuli}
    query = (select(p.public_id, p.condition, p.plan, p.excluded, r.item, r.stimulus,
                    r.question, r.value_num, r.value_text, s.created_at, s.rt_ms)
             .select_from(db.responses.join(db.submissions, r.submission_id == s.id)
                          .join(db.participants, r.participant_id == p.id))
             .order_by(p.join_index, r.item, r.id))
    plans: dict[str, Plan] = {}
    with engine.connect() as conn:
        for row in conn.execute(query):
            plan = plans.get(row.public_id) or plans.setdefault(row.public_id,
                                                                _plan_from(row.plan))
            item = plan.items[row.item]
            stimulus = stimuli.get(row.stimulus)
            value = _number(row.value_num) if row.value_num is not None else row.value_text
            yield {
                "participant": row.public_id, "condition": row.condition,
                "stimulus": row.stimulus, "question": row.question, "value": value,
                "time": _time(row.created_at), "item": str(row.item),
                "repeat": str(item.repeat), "check": item.check,
                "source": stimulus.source if stimulus else "",
                "intended": stimulus.intended if stimulus else "",
                "rt_ms": "" if row.rt_ms is None else str(row.rt_ms),
                "excluded": "1" if row.excluded else "0",
            }
