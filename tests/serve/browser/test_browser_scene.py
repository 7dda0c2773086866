"""The browser app against ``emotive serve --scene``, in real headless Chromium.

One server (an 8 m x 4 m room, two agents waiting by its west wall) and one page for the
module, used by the tests in order. What the page draws is read through its debug hook
(``window.emotive.sceneDrawn()``: the lines on the ground, read back from their geometry),
not from pixels; what the server accepted through ``/api/scene`` and ``/api/agents``.

Waits are on the app's state, with budgets in scene seconds (the scene time of the latest
frame the page got): on a busy machine the server skips ticks and software WebGL renders a
few frames a second. Wall time only bounds a hang.

Chromium or Playwright missing: the tests skip, naming what to install (a failure under
``EMOTIVE_REQUIRE_TOOLS=1``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import numpy as np
import pytest

pytest.importorskip("jupedsim", reason="the crowd extra is not installed")

from emotive.serve.testing import running_server
from tools import headless_chromium

VIEWPORT = {"width": 960, "height": 600}
SCENE = """
[area]
polygon = [[0, 0], [8, 0], [8, 4], [0, 4]]

[[groups]]
name = "waiting"
spawn = [[0.3, 0.3], [1.6, 0.3], [1.6, 1.6], [0.3, 1.6]]
count = 2
goal = { waypoints = [[1.0, 1.0]] }
emotion = "sad"
"""
#: The obstacle drawn by clicks: its corners, metres on the ground.
CORNERS = [(3.5, 1.2), (4.5, 1.2), (4.5, 2.4), (3.5, 2.4)]
#: The agent dropped by clicks: where it stands and its goal.
DROP_AT, DROP_GOAL = (2.5, 3.2), (6.5, 3.2)
#: Metres a click lands from the point aimed at (pixels are whole numbers).
CLICK_TOLERANCE = 0.05
#: Wall seconds without progress that count as a hang; Playwright's timeout of each action.
STALL_SECONDS = 120.0
#: Wall seconds any one wait may take in all (a hang guard, not a budget).
HANG_SECONDS = 300.0
#: Milliseconds between two polls of a wait.
POLL_MS = 200


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from headless_chromium(HANG_SECONDS)


@dataclass
class Page:
    """The app's page, the server's base URL, and the problems the page reported."""

    page: Any
    base: str
    problems: list[str] = field(default_factory=list)

    def hook(self, expression: str) -> Any:
        """Evaluate ``expression`` with ``e`` bound to ``window.emotive``."""
        return self.page.evaluate(f"() => {{ const e = window.emotive; return {expression}; }}")

    def api(self, path: str) -> Any:
        reply = httpx.get(f"{self.base}{path}", timeout=STALL_SECONDS)
        reply.raise_for_status()
        return reply.json()

    def agents(self) -> dict[int, dict[str, Any]]:
        return {a["id"]: a for a in self.api("/api/agents")["agents"]}

    def click(self, x: float, z: float, double: bool = False) -> None:
        """Click (or double-click) the ground point ``(x, z)``."""
        px, py = self.hook(f"e.toScreen({x}, {z})")
        (self.page.mouse.dblclick if double else self.page.mouse.click)(px, py)

    def until(self, check: Callable[[], Any], what: str, scene: float = 0.0) -> Any:
        """``check``'s first truthy result; fails once ``scene`` scene seconds passed (and
        the check still failed), or on a hang."""
        clock = "e.lastFrame ? e.lastFrame.time : 0"
        t0 = self.hook(clock)
        start = moved = time.monotonic()
        last = t0
        while True:
            t = self.hook(clock)
            result = check()
            if result:
                return result
            if t - t0 >= scene:
                pytest.fail(f"{what} (after {t - t0:.1f} scene s)")
            now = time.monotonic()
            if t != last:
                last, moved = t, now
            if now - moved > STALL_SECONDS or now - start > HANG_SECONDS:
                pytest.fail(f"no progress: {what} ({t - t0:.1f} scene s)")
            self.page.wait_for_timeout(POLL_MS)


@pytest.fixture(scope="module")
def app(browser, tmp_path_factory) -> Iterator[Page]:
    path = tmp_path_factory.mktemp("scene") / "room.toml"
    path.write_text(SCENE, encoding="utf-8")
    with running_server(scene=str(path), max_agents=5) as base:
        page = browser.new_page(viewport=VIEWPORT)
        page.set_default_timeout(STALL_SECONDS * 1000)
        app = Page(page, base)
        page.on("console", lambda m: app.problems.append(f"console {m.type}: {m.text}")
                if m.type == "error" else None)
        page.on("pageerror", lambda e: app.problems.append(f"page error: {e}"))
        page.goto(f"{base}/")
        page.wait_for_function(
            "() => window.emotive?.ready && window.emotive.scene !== null"
            " && window.emotive.agents().length >= 2",
            polling=POLL_MS, timeout=HANG_SECONDS * 1000)
        yield app
        page.close()


def test_the_area_and_the_groups_are_drawn(app):
    scene = app.api("/api/scene")
    assert app.hook("e.scene") == scene
    drawn = app.hook("e.sceneDrawn()")
    assert drawn["version"] == scene["version"]
    np.testing.assert_allclose(drawn["area"], scene["area"], atol=1e-6)
    assert drawn["obstacles"] == []
    np.testing.assert_allclose(drawn["spawns"], [g["spawn"] for g in scene["groups"]],
                               atol=1e-6)
    # The scene's tools replace path drawing.
    assert app.page.locator("#mode-draw").is_hidden()
    assert app.page.locator("#mode-obstacle").is_visible()
    assert app.page.locator("#mode-place").inner_text() == "Select"


def test_esc_cancels_an_obstacle(app):
    app.page.click("#mode-obstacle")
    assert app.hook("e.mouseMode") == "obstacle"
    for x, z in CORNERS[:2]:
        app.click(x, z)
    assert len(app.hook("e.draftObstacle")) == 2
    app.page.keyboard.press("Escape")
    assert app.hook("e.draftObstacle") == []


def test_an_obstacle_drawn_by_clicks_is_accepted_and_drawn(app):
    for x, z in CORNERS[:-1]:
        app.click(x, z)
    np.testing.assert_allclose(app.hook("e.draftObstacle"), CORNERS[:-1],
                               atol=CLICK_TOLERANCE)
    app.click(*CORNERS[-1], double=True)   # the last corner, and the close
    obstacles = app.until(lambda: app.api("/api/scene")["obstacles"],
                          "the server has no obstacle", scene=5)
    assert len(obstacles) == 1
    np.testing.assert_allclose(obstacles[0], CORNERS, atol=CLICK_TOLERANCE)
    drawn = app.until(lambda: app.hook("e.sceneDrawn()")["obstacles"],
                      "the page does not draw the obstacle", scene=5)
    np.testing.assert_allclose(drawn, obstacles, atol=1e-6)
    assert app.hook("e.draftObstacle") == []


def test_an_agent_dropped_by_clicks_walks_to_its_goal(app):
    before = set(app.agents())
    app.page.click("#mode-agent")
    assert app.hook("e.selected") is None
    for label in ("happy", "sad", "angry", "neutral"):
        app.page.press(f'#sliders input[data-label="{label}"]',
                       "End" if label == "happy" else "Home")
    assert app.hook("e.dropEmotion").startswith("happy=1.00")
    app.click(*DROP_AT)
    np.testing.assert_allclose(app.hook("e.dropStart"), DROP_AT, atol=CLICK_TOLERANCE)
    app.click(*DROP_GOAL)
    (agent,) = app.until(lambda: set(app.agents()) - before, "no agent was added", scene=5)
    state = app.agents()[agent]
    assert max(state["emotion"], key=state["emotion"].get) == "happy"
    np.testing.assert_allclose(state["goal"]["points"], [DROP_GOAL], atol=CLICK_TOLERANCE)
    assert app.hook("e.dropStart") is None

    def arrived() -> bool:
        here = app.hook(f"e.positions()[{agent}]")
        return here is not None and np.hypot(here[0] - DROP_GOAL[0],
                                             here[2] - DROP_GOAL[1]) < 0.6

    app.until(arrived, f"agent {agent} did not walk to its goal", scene=20)


def test_no_errors_in_the_session(app):
    assert app.problems == []
    assert app.hook("e.errors") == []


def test_a_refused_obstacle_shows_the_servers_reason(app):
    app.page.click("#mode-obstacle")
    for x, z in ((0.6, 0.6), (1.4, 0.6), (1.4, 1.4)):   # on the group's waypoint
        app.click(x, z)
    app.page.keyboard.press("Enter")
    app.page.locator(".toast").first.wait_for()
    (message,) = app.hook("e.errors")
    assert "covers a waypoint of group 'waiting'" in message
    assert len(app.api("/api/scene")["obstacles"]) == 1
    assert app.problems == []
