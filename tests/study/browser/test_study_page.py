"""The participant and admin pages of ``emotive study serve`` in real headless Chromium.

Debian's ``chromium`` is driven by Playwright's bundled driver (no browser download), with
WebGL on SwiftShader, against a study server started in-process on a copy of the session's
small ``gaits`` study (3 stimuli of 3 s and an attention check: 4 items), with a choice and a
5 x 5 affect-grid question added to its five likert ones. Each participant run gets its own
server and study folder (the render is the study's), so the runs do not depend on each other:

* ``mannequin`` on a desktop, ``sticks`` on a phone (390 x 844, touch), ``effectors`` on a
  desktop: consent, instructions, every item (the first answered by keyboard only, the others
  by clicks or taps), the completion code; the export then holds exactly the answers given.
* The phone run also loses a reply (the retry carries the same Idempotency-Key and is stored
  once), reloads between items (the page resumes), meets a 422 (its one-line reason is
  shown), and reloads while the network is down with a submission pending (the reloaded page
  sends it again with the same key).
* The admin page: the token, progress and participant tables, an exclusion toggle, and the
  CSV download (fetched with the token), equal to ``GET /api/admin/export.csv``.

Every request the pages make must go to the study server. Waits are on the page's state,
read through its read-only debug hooks ``window.study`` and ``window.studyAdmin``; wall time
only bounds a hang. Screenshots of each render's item screen are written to
``$EMOTIVE_STUDY_SCREENSHOTS`` when set (else the test's temporary folder) and checked: the
figure is drawn, inside the view, and moves.

Chromium or Playwright missing: the tests skip, naming what to install; CI sets
``EMOTIVE_REQUIRE_TOOLS=1``, which turns a skip into a failure.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import httpx
import numpy as np
import pytest
from study_client import ADMIN, admin_headers, answers_for, client_for, join

from emotive.study.config import StudyConfig, load_study, stored_values
from emotive.study.testing import running_study_server
from tools import headless_chromium

DESKTOP = {"viewport": {"width": 1280, "height": 800}}
PHONE = {"viewport": {"width": 390, "height": 844}, "has_touch": True, "is_mobile": True}
#: Questions added to the gaits template's five likert scales.
EXTRA_QUESTIONS = """
[[questions]]
id = "emotion"
kind = "choice"
prompt = "Which emotion fits best?"
options = ["happy", "sad", "angry", "neutral"]

[[questions]]
id = "affect"
kind = "grid"
prompt = "How does the figure feel? Pick the cell that fits best."
size = 5
anchors = ["unpleasant", "pleasant", "calm", "excited"]
"""
#: Wall seconds any one wait may take (a hang guard, not a budget); Playwright's action timeout.
HANG_SECONDS = 180.0
#: Milliseconds between two polls of a wait.
POLL_MS = 100
#: Frames of a stimulus drawn before its screenshot is taken.
SETTLE_FRAMES = 3
#: A pixel of the view darker than this (0-255 luma) is the figure: the background, ground and
#: grid are lighter.
FIGURE_LUMA = 150
#: Figure pixels a screenshot of the view must hold.
MIN_FIGURE_PIXELS = 40


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless Chromium, launched once for the module."""
    yield from headless_chromium(HANG_SECONDS)


def make_study(template: Path, folder: Path, render: str) -> StudyConfig:
    """A copy of the gaits study with the extra questions, drawn in ``render``."""
    shutil.copytree(template, folder)
    toml = folder / "study.toml"
    text = toml.read_text(encoding="utf-8").replace('render = "mannequin"',
                                                    f'render = "{render}"')
    toml.write_text(text + EXTRA_QUESTIONS, encoding="utf-8")
    study = load_study(folder)
    assert study.render == render and len(study.questions) == 7
    return study


@pytest.fixture
def shots(tmp_path: Path) -> Path:
    folder = Path(os.environ.get("EMOTIVE_STUDY_SCREENSHOTS") or tmp_path / "shots")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@dataclass
class Page:
    """A page of the study server, with the requests it made and the problems it reported."""

    page: Any
    base: str
    problems: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)
    keys: list[tuple[int, str]] = field(default_factory=list)

    def hook(self, expression: str = "s") -> Any:
        """Evaluate ``expression`` with ``s`` bound to ``window.study``."""
        return self.page.evaluate(f"() => {{ const s = window.study; return {expression}; }}")

    def wait(self, condition: str, what: str) -> None:
        """Wait until ``condition`` (JS, ``s`` is ``window.study``) holds; fail naming ``what``."""
        try:
            self.page.wait_for_function(
                f"() => {{ const s = window.study; return Boolean(s && ({condition})); }}",
                polling=POLL_MS, timeout=HANG_SECONDS * 1000)
        except Exception as exc:  # Playwright's TimeoutError, or the page went away
            state = self.page.evaluate("() => JSON.stringify(window.study ?? null)")
            pytest.fail(f"{what}: not within {HANG_SECONDS:.0f} s ({exc.__class__.__name__}); "
                        f"page state {state}; problems {self.problems}")

    def real_problems(self) -> list[str]:
        """The problems but the browser's reports of requests refused or failed on purpose."""
        return [m for m in self.problems if "Failed to load resource" not in m]

    def foreign(self) -> list[str]:
        """Requests that went anywhere but the study server."""
        host = urlsplit(self.base).netloc
        return [u for u in self.requests
                if urlsplit(u).scheme not in ("data", "blob") and urlsplit(u).netloc != host]


def open_page(browser: Any, base: str, device: dict[str, Any], path: str = "/",
              permissions: tuple[str, ...] = ()) -> Page:
    context = browser.new_context(**device)
    if permissions:
        context.grant_permissions(list(permissions), origin=base)
    page = context.new_page()
    page.set_default_timeout(HANG_SECONDS * 1000)
    p = Page(page, base)
    page.on("console", lambda m: p.problems.append(f"console {m.type}: {m.text}")
            if m.type == "error" else None)
    page.on("pageerror", lambda e: p.problems.append(f"page error: {e}"))

    def request(r: Any) -> None:
        p.requests.append(r.url)
        if r.url.endswith("/api/responses") and r.method == "POST":
            p.keys.append((r.post_data_json["item"], r.headers.get("idempotency-key", "")))

    page.on("request", request)
    page.goto(f"{base}{path}")
    return p


# --- answering ------------------------------------------------------------------------------


def answers_to_give(study: StudyConfig, index: int, instruction: str | None) -> dict[str, Any]:
    """The answers for the ``index``-th item shown: the check's expected ones where asked."""
    out: dict[str, Any] = {}
    for i, q in enumerate(study.questions):
        if q.kind == "likert":
            out[q.id] = q.min + (index + 2 * i) % (q.max - q.min + 1)
        elif q.kind == "choice":
            out[q.id] = q.options[(index + i) % len(q.options)]
        else:
            out[q.id] = {"valence": 1 + (index * 2) % q.size, "arousal": 1 + (index + 3) % q.size}
    if instruction is not None:
        check = next(c for c in study.checks if c.instruction == instruction)
        out.update(check.expect)
    return out


def answer_by_keyboard(p: Page, study: StudyConfig, answers: dict[str, Any]) -> None:
    """Keys only: the page focuses the first question; digits, arrows, Tab, Enter."""
    kb = p.page.keyboard
    p.wait("document.activeElement?.closest('fieldset')?.dataset.question === "
           f"'{study.questions[0].id}'", "the first question has the focus")
    likerts = 0
    for q in study.questions:
        value = answers[q.id]
        if q.kind == "likert":
            likerts += 1
            if likerts == 2 and value > q.min:
                # The arrow keys move from a value picked by its digit.
                kb.press(str(q.min))
                for _ in range(value - q.min):
                    kb.press("ArrowRight")
            else:
                kb.press(str(value))
        elif q.kind == "choice":
            kb.press(str(q.options.index(value) + 1))
        else:
            centre = (q.size + 1) // 2
            for _ in range(abs(value["valence"] - centre)):
                kb.press("ArrowRight" if value["valence"] > centre else "ArrowLeft")
            for _ in range(abs(value["arousal"] - centre)):
                kb.press("ArrowUp" if value["arousal"] > centre else "ArrowDown")
            kb.press("Enter")
        assert p.hook(f"s.answers[{q.id!r}]") == value, q.id
        kb.press("Tab")
    assert p.hook("s.canSubmit") is True
    assert p.page.evaluate("() => document.activeElement.id") == "next"
    kb.press("Enter")


def answer_by_pointer(p: Page, study: StudyConfig, answers: dict[str, Any], touch: bool
                      ) -> None:
    """Clicks (or taps) on each answer, then on Next (enabled only at the end)."""
    act = (lambda sel: p.page.tap(sel)) if touch else (lambda sel: p.page.click(sel))
    for q in study.questions:
        assert p.hook("s.canSubmit") is False
        value = answers[q.id]
        scope = f'fieldset[data-question="{q.id}"]'
        if q.kind == "grid":
            act(f'{scope} .cell[data-col="{value["valence"]}"][data-row="{value["arousal"]}"]')
        else:
            act(f'{scope} label.option[data-value="{value}"]')
        assert p.hook(f"s.answers[{q.id!r}]") == value, q.id
    assert p.hook("s.canSubmit") is True
    act("#next")


def answer_through_a_busy_server(p: Page, study: StudyConfig, item: int,
                                 answers: dict[str, Any]) -> None:
    """A 503, then a 429 to the submission: both retried, after a backoff, with the same key."""
    busy = [503, 429]

    def reply(route: Any) -> None:
        if busy:
            route.fulfill(status=busy.pop(0), json={"error": "busy"},
                          headers={"Retry-After": "1"})
        else:
            route.continue_()

    p.page.route("**/api/responses", reply)
    answer_by_pointer(p, study, answers, touch=False)
    p.wait(f"s.answered.includes({item})", "the item stored after retries")
    p.page.unroute("**/api/responses")
    assert busy == [] and "saving... (retrying)" in p.hook("s.statuses")
    keys = [key for it, key in p.keys if it == item]
    assert len(keys) == 3 and len(set(keys)) == 1


def item_shown(p: Page, index: int, total: int) -> dict[str, Any]:
    """Wait for the ``index``-th item's stimulus to be drawn; its hook entry."""
    p.wait(f"s.screen === 'item' && s.item?.index === {index} && s.loaded "
           f"&& s.stimulusFrames >= {SETTLE_FRAMES}", f"item {index} drawn")
    assert p.page.inner_text("#progress") == f"Item {index} of {total}"
    item = p.hook("s.item")
    instruction = p.page.locator("#instruction")
    if item["instruction"] is None:
        assert instruction.is_hidden()
    else:
        assert instruction.is_visible() and instruction.inner_text() == item["instruction"]
    return item


def figure_pixels(png: bytes) -> np.ndarray:
    """The (H, W) mask of figure pixels of a screenshot of the view."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(float)
    return rgb @ np.array([0.299, 0.587, 0.114]) < FIGURE_LUMA


def check_view(p: Page, shots: Path, name: str, seconds: float) -> None:
    """The figure is drawn whole inside the view, and moves; screenshots kept in ``shots``."""
    x0, y0, x1, y1 = p.hook("s.framing")
    assert -1 < x0 < x1 < 1 and -1 < y0 < y1 < 1, "the walk leaves the view"
    assert max(x1 - x0, y1 - y0) > 1.0, "the walk fills too little of the view"
    p.page.screenshot(path=str(shots / f"{name}-page.png"))
    stage = p.page.locator("#stage")
    first = stage.screenshot(path=str(shots / f"{name}-view.png"))
    mask = figure_pixels(first)
    assert mask.sum() >= MIN_FIGURE_PIXELS, f"no figure drawn ({mask.sum()} dark pixels)"
    rows, cols = np.nonzero(mask)
    border = 3  # the frame's own outline is drawn in the page's line colour, lighter
    assert rows.min() > border and cols.min() > border, "the figure touches the view's edge"
    assert rows.max() < mask.shape[0] - border and cols.max() < mask.shape[1] - border
    t0, frames = p.hook("[s.time, s.stimulusFrames]")
    assert 0 <= t0 < seconds, "the loop is the study's seconds long"
    p.wait(f"s.stimulusFrames >= {frames + 2} && Math.abs(s.time - {t0}) > 0.25",
           "the loop advances")
    later = figure_pixels(stage.screenshot(path=str(shots / f"{name}-view-later.png")))
    assert (later != mask).sum() > 20, "the figure does not move"


def check_accessible_names(p: Page, study: StudyConfig) -> None:
    """Every control of the item has a name a screen reader reads."""
    page = p.page
    for q in study.questions:
        group = page.get_by_role("group", name=q.prompt)
        assert group.count() == 1, q.prompt
        if q.kind == "likert":
            low, high = q.anchors
            assert group.get_by_role("radio", name=f"{q.min}, {low}", exact=True).count() == 1
            assert group.get_by_role("radio", name=f"{q.max}, {high}", exact=True).count() == 1
            assert group.get_by_role("radio").count() == q.max - q.min + 1
        elif q.kind == "choice":
            assert group.get_by_role("radio").count() == len(q.options)
        else:
            cells = group.get_by_role("radio")
            assert cells.count() == q.size ** 2
            assert group.get_by_role("radio", name=f"{q.anchors[0]} to {q.anchors[1]} 1 of "
                                     f"{q.size}, {q.anchors[2]} to {q.anchors[3]} {q.size} of "
                                     f"{q.size}").count() == 1
    assert page.get_by_role("button", name="Next").count() == 1
    assert page.get_by_role("img", name="animation of a figure, looping").count() == 1


def consent_and_start(p: Page, touch: bool) -> None:
    act = (lambda sel: p.page.tap(sel)) if touch else (lambda sel: p.page.click(sel))
    p.wait("s.ready && s.screen === 'consent'", "the consent screen")
    assert "voluntary" in p.page.inner_text("#consent-text")
    act("#agree")
    p.wait("s.screen === 'instructions'", "the instructions after consent")
    act("#start")


def check_export(base: str, study: StudyConfig, participant: str,
                 given: dict[int, dict[str, Any]]) -> list[dict[str, str]]:
    """The export holds exactly the answers ``given`` (item -> answers) by the participant."""
    reply = httpx.get(f"{base}/api/admin/export.csv", headers=admin_headers(), timeout=60)
    assert reply.status_code == 200
    rows = [r for r in csv.DictReader(io.StringIO(reply.text)) if r["participant"] == participant]
    expected: dict[tuple[str, str], float | str] = {}
    for item, answers in given.items():
        for qid, value in answers.items():
            for name, stored in stored_values(study.question(qid), value).items():
                expected[(str(item), name)] = stored
    got = {(r["item"], r["question"]): r["value"] for r in rows}
    assert len(rows) == len(got) == len(given) * 8
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        if isinstance(value, str):
            assert got[key] == value, key
        else:
            assert float(got[key]) == pytest.approx(value), key
    assert all(int(r["rt_ms"]) > 0 for r in rows)
    return rows


def finish(p: Page, study: StudyConfig) -> None:
    p.wait("s.screen === 'done'", "the completion screen")
    assert p.hook("s.completionCode") == study.completion_code
    assert p.page.inner_text("#code") == study.completion_code


# --- participants ---------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("render", ["mannequin", "effectors"])
def test_a_desktop_participant_completes_the_study(browser, study_template, tmp_path, shots,
                                                  render):
    study = make_study(study_template, tmp_path / "study", render)
    with running_study_server(study.folder, admin_token=ADMIN) as base:
        p = open_page(browser, base, DESKTOP, permissions=("clipboard-read", "clipboard-write"))
        consent_and_start(p, touch=False)
        total = p.hook("s.items")
        assert total == 4 and p.hook("s.render") == render
        given: dict[int, dict[str, Any]] = {}
        for index in range(1, total + 1):
            item = item_shown(p, index, total)
            answers = answers_to_give(study, index, item["instruction"])
            check_view(p, shots, f"{render}-{index}-{item['stimulus']}", study.seconds)
            if index == 1:
                check_accessible_names(p, study)
                answer_by_keyboard(p, study, answers)
            elif index == 3:
                answer_through_a_busy_server(p, study, item["item"], answers)
            else:
                answer_by_pointer(p, study, answers, touch=False)
            given[item["item"]] = answers
            p.wait(f"s.answered.includes({item['item']})", f"item {index} stored")
        finish(p, study)
        p.page.click("#copy")
        p.page.wait_for_function("() => document.getElementById('copy-status').textContent",
                                 polling=POLL_MS)
        assert p.page.inner_text("#copy-status") == "Copied."
        assert p.page.evaluate("() => navigator.clipboard.readText()") == study.completion_code
        rows = check_export(base, study, p.hook("s.participant"), given)
        assert sum(1 for r in rows if r["check"]) == 8, "one attention check"
        # Each item was sent with its own key (item 3 three times).
        assert sorted({item for item, _ in p.keys}) == sorted(given)
        assert len(p.keys) == len(given) + 2 and len({key for _, key in p.keys}) == len(given)
        assert p.foreign() == [] and p.real_problems() == [] and p.hook("s.errors") == []
        p.page.context.close()


@pytest.mark.slow
def test_a_phone_participant_survives_lost_replies_refusals_and_reloads(
        browser, study_template, tmp_path, shots):
    study = make_study(study_template, tmp_path / "study", "sticks")
    with running_study_server(study.folder, admin_token=ADMIN) as base:
        p = open_page(browser, base, PHONE)
        consent_and_start(p, touch=True)
        total = p.hook("s.items")
        assert p.hook("s.render") == "sticks"
        participant = p.hook("s.participant")
        given: dict[int, dict[str, Any]] = {}

        def show(index: int) -> tuple[dict[str, Any], dict[str, Any]]:
            item = item_shown(p, index, total)
            answers = answers_to_give(study, index, item["instruction"])
            given[item["item"]] = answers
            return item, answers

        # 1: keyboard only; the view is checked.
        item, answers = show(1)
        check_view(p, shots, "sticks", study.seconds)
        width = PHONE["viewport"]["width"]
        assert p.page.evaluate("() => document.documentElement.scrollWidth") <= width, \
            "the page is wider than the phone"
        answer_by_keyboard(p, study, answers)
        p.wait(f"s.answered.includes({item['item']})", "item 1 stored")

        # 2: the server stores the submission but its reply is lost: the page retries with the
        # same key and is told it was replayed.
        item, answers = show(2)
        lost: list[int] = []

        def lose_reply(route: Any) -> None:
            if lost:
                route.continue_()
                return
            lost.append(route.fetch().status)
            route.abort("failed")

        p.page.route("**/api/responses", lose_reply)
        answer_by_pointer(p, study, answers, touch=True)
        p.wait(f"s.answered.includes({item['item']})", "item 2 stored after a retry")
        p.page.unroute("**/api/responses")
        assert lost == [201]
        assert "saving... (retrying)" in p.hook("s.statuses")
        keys = [key for it, key in p.keys if it == item["item"]]
        assert len(keys) == 2 and keys[0] == keys[1]

        # A reload resumes at item 3, with the same participant.
        p.page.reload()
        p.wait("s.ready", "the page after a reload")
        item, answers = show(3)
        assert p.hook("s.participant") == participant

        # 3: a refusal shows its one-line reason; Next sends again.
        refused: list[str] = []

        def refuse_once(route: Any) -> None:
            if refused:
                route.continue_()
                return
            refused.append(route.request.headers["idempotency-key"])
            route.fulfill(status=422, json={"error": "test: this answer was refused"})

        p.page.route("**/api/responses", refuse_once)
        answer_by_pointer(p, study, answers, touch=True)
        p.wait("s.status === 'test: this answer was refused' && s.canSubmit",
               "the refusal's reason")
        assert p.page.inner_text("#save-status") == "test: this answer was refused"
        assert p.hook("s.errors") == ["test: this answer was refused"]
        p.page.tap("#next")
        p.wait(f"s.answered.includes({item['item']})", "item 3 stored after the refusal")
        p.page.unroute("**/api/responses")

        # 4: the network is down: the page keeps retrying; a reload sends the pending
        # submission again with its key, and the study completes.
        item, answers = show(4)
        p.page.route("**/api/responses", lambda route: route.abort("internetdisconnected"))
        answer_by_pointer(p, study, answers, touch=True)
        p.wait("s.retrying && s.status === 'saving... (retrying)'", "retrying while offline")
        assert p.page.inner_text("#save-status") == "saving... (retrying)"
        p.page.reload()
        p.wait("s.ready && s.retrying && s.status === 'saving... (retrying)'",
               "the reloaded page sending the pending submission")
        assert p.hook("s.answered").count(item["item"]) == 0
        p.page.unroute("**/api/responses")
        finish(p, study)
        p.page.screenshot(path=str(shots / "sticks-done.png"))
        keys = [key for it, key in p.keys if it == item["item"]]
        assert len(keys) >= 2 and len(set(keys)) == 1, keys

        check_export(base, study, participant, given)
        assert p.foreign() == [] and p.real_problems() == []
        p.page.context.close()


# --- admin ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_the_admin_page_shows_progress_excludes_and_downloads(browser, study_template,
                                                              tmp_path, shots):
    study = make_study(study_template, tmp_path / "study", "mannequin")
    with running_study_server(study.folder, admin_token=ADMIN) as base, \
            client_for(base) as client:
        questions = client.get("/api/study").json()["questions"]
        done, half = join(client), join(client)
        for it in done.plan["items"]:
            assert done.submit(it["item"], answers_for(questions)).status_code == 201
        assert client.post("/api/complete", headers=done.headers, json={}).status_code == 200
        assert half.submit(0, answers_for(questions, 2)).status_code == 201

        p = open_page(browser, base, DESKTOP, path="/admin")
        page = p.page
        page.wait_for_function("() => window.studyAdmin?.ready", polling=POLL_MS)
        page.fill("#token", "wrong-token")
        page.click("#login button[type=submit]")
        page.wait_for_function("() => window.studyAdmin.errors.length > 0", polling=POLL_MS)
        assert "refused the token" in page.inner_text("#admin-status")
        page.fill("#token", ADMIN)
        page.click("#login button[type=submit]")
        page.wait_for_function("() => window.studyAdmin.rows === 2", polling=POLL_MS)
        assert page.evaluate("() => sessionStorage.getItem('emotive-study-admin-token')") == ADMIN
        totals = page.inner_text("#totals")
        assert "2\nparticipants" in totals and "1\ncompleted" in totals
        rows = {r.split("\t")[0]: r for r in
                page.locator("#participants tbody tr").all_inner_texts()}
        assert set(rows) == {done.id, half.id}
        assert "yes" in rows[done.id] and "4 / 4" in rows[done.id]
        assert "1 / 4" in rows[half.id]

        # Exclude one participant, with a reason; the server has it.
        row = page.locator(f'#participants tr[data-participant="{half.id}"]')
        row.get_by_role("textbox", name=f"reason to exclude {half.id}").fill("left early")
        row.get_by_role("checkbox", name=f"exclude {half.id}").check()
        page.wait_for_function(
            f"() => document.querySelector('tr[data-participant=\"{half.id}\"]')"
            ".dataset.excluded === 'true'", polling=POLL_MS)
        table = client.get("/api/admin/participants", headers=admin_headers()).json()
        state = {r["participant"]: (r["excluded"], r["reason"]) for r in table["participants"]}
        assert state == {done.id: (False, ""), half.id: (True, "left early")}
        page.screenshot(path=str(shots / "admin.png"))

        # The download is the export, fetched with the token.
        with page.expect_download() as info:
            page.click("#download")
        saved = tmp_path / "downloaded.csv"
        info.value.save_as(saved)
        export = client.get("/api/admin/export.csv", headers=admin_headers()).text
        assert info.value.suggested_filename == "responses.csv"
        assert saved.read_text(encoding="utf-8") == export
        assert len(export.strip().splitlines()) == 1 + 5 * 8

        # A new participant shows up without a click (the page refreshes by itself).
        join(client)
        page.wait_for_function("() => window.studyAdmin.rows === 3", polling=POLL_MS,
                               timeout=HANG_SECONDS * 1000)
        assert p.foreign() == [] and p.real_problems() == []
        page.context.close()
