"""The served app's panel and figure colours at two window sizes, in real headless Chromium.

At 1280x800 and 800x600 (the second narrow: the panel starts collapsed there): the panel
never covers the centre of the view, each of its controls (the Recording and the AR/VR
buttons too) can be scrolled into sight inside it, its button collapses and expands it (and
so does the P key), and the state outlives a reload. The colours the app really draws, read
through its debug hook ``window.emotive.colors()`` and from a screenshot of the ground, are
at least 4.5:1 apart (WCAG 2; ``tests/serve/test_app_contrast.py`` checks the shipped
colours). Screenshots of each size, panel expanded and collapsed, go to a temporary folder.

One server for the module; a page per size, each in a fresh browser context (its own
localStorage), used by the tests in order. The page reports WebXR sessions as supported, so
that its AR and VR buttons exist. Waits are on the page's state; wall time only bounds a
hang. Chromium or Playwright missing: the tests skip, naming what to install (a failure
under ``EMOTIVE_REQUIRE_TOOLS=1``).
"""

from __future__ import annotations

import io
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from emotive.serve.testing import running_server
from tools import headless_chromium
from wcag import contrast_ratio

#: (width, height) of each window, and whether the panel starts expanded there: 800 px is
#: narrow (the expanded panel, 270 px, would take more than a third of it).
SIZES = [((1280, 800), True), ((800, 600), False)]
#: WCAG 2's minimum contrast for normal text (SC 1.4.3).
MIN_CONTRAST = 4.5
#: Agents of the demo scene.
DEMO_AGENTS = 4
#: Wall seconds any one wait may take (a hang guard, not a budget); Playwright's timeout.
HANG_SECONDS = 300.0
#: Milliseconds between two polls of a wait.
POLL_MS = 200
#: What the page's controls are.
CONTROLS = "button, input, select, summary, a, canvas"
#: Pixels a turn of the mouse wheel scrolls, and the most turns that may take to reach a control.
WHEEL_PIXELS, WHEEL_TURNS = 240, 20
#: Wall seconds a turn of the wheel may take to scroll the panel (a hang guard).
WHEEL_SECONDS = 30.0
#: Whether the element of a selector lies inside the panel's box, on the page.
INSIDE_PANEL = """(selector) => {
    const box = document.getElementById("panel").getBoundingClientRect();
    const r = document.querySelector(selector).getBoundingClientRect();
    return r.top >= box.top && r.bottom <= box.bottom && r.bottom <= innerHeight;
}"""
#: Ground points (metres) whose grid cells' middles are sampled for the ground's colour.
GROUND_CELLS = [(x + 0.5, z + 0.5) for x in range(-7, 8, 2) for z in range(-4, 6, 3)]


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from headless_chromium(HANG_SECONDS)


@pytest.fixture(scope="module")
def server() -> Iterator[str]:
    with running_server(max_agents=2 * DEMO_AGENTS) as base:
        yield base


@pytest.fixture(scope="module")
def screens(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the screenshots go."""
    return tmp_path_factory.mktemp("panel-screens")


@dataclass
class Page:
    """The app's page at one window size, and the problems it reported."""

    page: Any
    size: tuple[int, int]
    starts_expanded: bool
    problems: list[str] = field(default_factory=list)

    def hook(self, expression: str) -> Any:
        """Evaluate ``expression`` with ``e`` bound to ``window.emotive``."""
        return self.page.evaluate(f"() => {{ const e = window.emotive; return {expression}; }}")

    def wait_ready(self) -> None:
        """Until the app runs, draws the demo's agents, and has its AR and VR buttons."""
        self.page.wait_for_function(
            f"() => window.emotive?.ready && window.emotive.agents().length >= {DEMO_AGENTS}"
            " && document.querySelectorAll('#xr button').length === 2",
            polling=POLL_MS, timeout=HANG_SECONDS * 1000)
        self.rendered(2)

    def rendered(self, frames: int) -> None:
        """Until the page rendered ``frames`` more frames."""
        start = self.hook("e.framesRendered")
        self.page.wait_for_function(f"() => window.emotive.framesRendered >= {start + frames}",
                                    polling=POLL_MS, timeout=HANG_SECONDS * 1000)

    def received(self, frames: int) -> None:
        """Until the page received ``frames`` more frames from the server."""
        start = self.hook("e.framesReceived")
        self.page.wait_for_function(f"() => window.emotive.framesReceived >= {start + frames}",
                                    polling=POLL_MS, timeout=HANG_SECONDS * 1000)

    def expanded(self) -> bool:
        return self.page.get_attribute("#panel-toggle", "aria-expanded") == "true"

    def panel_box(self) -> dict[str, float]:
        return self.page.locator("#panel").bounding_box()

    def view_centre(self) -> tuple[float, float]:
        box = self.page.locator("#view canvas").bounding_box()
        return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2

    def assert_centre_clear(self) -> None:
        """The panel's box does not hold the centre of the view."""
        box, (cx, cy) = self.panel_box(), self.view_centre()
        inside = (box["x"] <= cx <= box["x"] + box["width"]
                  and box["y"] <= cy <= box["y"] + box["height"])
        assert not inside, f"the panel {box} covers the view's centre {(cx, cy)} at {self.size}"

    def set_expanded(self, expanded: bool) -> None:
        if self.expanded() != expanded:
            self.page.click("#panel-toggle")
        assert self.expanded() == expanded

    def screenshot(self, folder: Path, state: str) -> np.ndarray:
        """Save a screenshot of the page as ``WxH-state.png`` in ``folder``; return it
        ``(H, W, 3)``."""
        from PIL import Image

        png = self.page.screenshot()
        width, height = self.size
        (folder / f"{width}x{height}-{state}.png").write_bytes(png)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


@pytest.fixture(scope="module", params=SIZES, ids=[f"{w}x{h}" for (w, h), _ in SIZES])
def app(request, browser, server) -> Iterator[Page]:
    """The app at ``/?demo=1`` in a window of one size, once its agents walk."""
    (width, height), starts_expanded = request.param
    context = browser.new_context(viewport={"width": width, "height": height})
    context.set_default_timeout(HANG_SECONDS * 1000)
    # A browser that says it supports AR and VR sessions (no device behind it).
    context.add_init_script("XRSystem.prototype.isSessionSupported = async () => true;")
    page = Page(context.new_page(), (width, height), starts_expanded)
    page.page.on("console", lambda m: page.problems.append(f"console {m.type}: {m.text}")
                 if m.type == "error" else None)
    page.page.on("pageerror", lambda e: page.problems.append(f"page error: {e}"))
    page.page.goto(f"{server}/?demo=1")
    page.wait_ready()
    yield page
    context.close()


def test_the_panel_starts_by_the_window_width_clear_of_the_centre(app):
    assert app.expanded() == app.starts_expanded
    app.assert_centre_clear()
    button = app.page.get_by_role("button", name="Panel", exact=True)
    assert button.get_attribute("aria-controls") == "panel"
    assert button.get_attribute("aria-keyshortcuts") == "P"
    assert app.problems == []


def test_every_control_of_the_panel_can_be_scrolled_into_view(app):
    app.set_expanded(True)
    app.assert_centre_clear()
    if app.size[1] <= 600:
        # The panel is taller than the window: the check below scrolls it.
        assert app.page.evaluate("() => { const p = document.getElementById('panel'); "
                                 "return p.scrollHeight > p.clientHeight; }")
    # Each shown control (not those hidden by the page or in a closed <details>), scrolled
    # into view: inside the panel's and the window's box, and the topmost element there.
    hidden = app.page.evaluate(
        """(selector) => {
            const panel = document.getElementById("panel");
            const box = panel.getBoundingClientRect();
            const out = [];
            const controls = [...panel.querySelectorAll(selector)]
                .filter((c) => c.checkVisibility());
            for (const control of controls) {
                control.scrollIntoView({ block: "nearest" });
                const r = control.getBoundingClientRect();
                const x = r.left + r.width / 2, y = r.top + r.height / 2;
                const top = document.elementFromPoint(x, y);
                const inside = r.top >= box.top - 0.5 && r.bottom <= box.bottom + 0.5
                    && r.left >= box.left - 0.5 && r.right <= box.right + 0.5
                    && r.bottom <= innerHeight && r.right <= innerWidth;
                if (!inside || !(top === control || control.contains(top))) {
                    out.push(`${control.tagName} ${control.id || control.textContent.trim()}`);
                }
            }
            return { out, count: controls.length };
        }""", CONTROLS)
    assert hidden["count"] >= 15
    assert hidden["out"] == [], f"controls out of sight at {app.size}: {hidden['out']}"


def test_the_mouse_wheel_scrolls_the_panel_to_recording_and_ar(app):
    app.set_expanded(True)
    for selector in ("#record-start", "#record-stop", "#xr button:nth-of-type(1)",
                     "#xr button:nth-of-type(2)"):
        _wheel_to(app, selector)
        assert app.page.locator(selector).is_visible(), selector


def test_the_button_and_the_key_collapse_the_panel_and_a_reload_keeps_it(app, screens):
    app.set_expanded(True)
    app.rendered(1)
    app.screenshot(screens, "expanded")
    wide = app.panel_box()["width"]
    app.page.click("#panel-toggle")
    assert not app.expanded()
    assert app.panel_box()["width"] < wide / 2
    assert not app.page.locator("#record-start").is_visible()
    assert app.page.locator("#panel-toggle").is_visible()
    app.assert_centre_clear()
    app.screenshot(screens, "collapsed")
    app.page.keyboard.press("p")
    assert app.expanded()
    assert app.page.locator("#record-start").is_visible()
    assert app.panel_box()["width"] == pytest.approx(wide)
    # The state that is not the window's default, so that the reload shows it was kept.
    app.set_expanded(not app.starts_expanded)
    app.page.reload()
    app.wait_ready()
    assert app.expanded() == (not app.starts_expanded)
    app.assert_centre_clear()
    assert app.problems == []


def test_the_figures_contrast_with_the_background_as_drawn(app, screens):
    app.set_expanded(True)
    colors = app.hook("e.colors()")
    assert set(map(int, colors["figures"])) == set(app.hook("e.agents()"))
    in_use = {c for figure in colors["figures"].values() for c in figure}
    app.page.click("#figure-sticks")
    # The stick figures are coloured as they are posed, from the next frames received.
    app.received(2)
    sticks = app.hook("e.colors()")
    app.page.click("#figure-mannequin")
    in_use |= {c for figure in sticks["figures"].values() for c in figure}
    # The emotion colours all around the circumplex, from neutral out, as figures.js makes
    # them.
    around = app.page.evaluate(
        """async () => {
            const { emotionColor } = await import("/static/figures.js");
            const out = [];
            for (let k = 0; k < 48; k++) {
                for (const r of [0, 0.35, 0.7, 1]) {
                    const a = (k / 48) * 2 * Math.PI;
                    out.push(`#${emotionColor(r * Math.cos(a), r * Math.sin(a)).getHexString()}`);
                }
            }
            return out;
        }""")
    ground = _ground_as_drawn(app, app.screenshot(screens, "colours"))
    for backdrop, name in ((colors["background"], "background"), (colors["ground"], "ground"),
                           (ground, "ground as drawn")):
        low = sorted({c for c in in_use | set(around)
                      if contrast_ratio(c, backdrop) < MIN_CONTRAST})
        assert low == [], f"colours below {MIN_CONTRAST}:1 against the {name} {backdrop}: {low}"
    assert app.problems == []


def _wheel_to(app: Page, selector: str) -> None:
    """From the panel's top, turn the mouse wheel over it until ``selector`` is in sight."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    panel = "document.getElementById('panel')"
    app.page.evaluate(f"() => {{ {panel}.scrollTop = 0; }}")
    box = app.panel_box()
    # Over the panel's left padding: no control there to take the wheel.
    app.page.mouse.move(box["x"] + 4, box["y"] + box["height"] / 2)
    for _ in range(WHEEL_TURNS):
        if app.page.evaluate(INSIDE_PANEL, selector):
            return
        top = app.page.evaluate(f"() => {panel}.scrollTop")
        app.page.mouse.wheel(0, WHEEL_PIXELS)
        try:
            app.page.wait_for_function(
                f"() => {panel}.scrollTop > {top} "
                f"|| {panel}.scrollTop + {panel}.clientHeight >= {panel}.scrollHeight - 1",
                polling=POLL_MS, timeout=WHEEL_SECONDS * 1000)
        except PlaywrightTimeout as exc:
            pytest.fail(f"the panel did not scroll under the mouse wheel at {app.size}: {exc}")
    pytest.fail(f"{selector} is not in sight after {WHEEL_TURNS} turns of the wheel at "
                f"{app.size}")


def _ground_as_drawn(app: Page, image: np.ndarray) -> str:
    """The ground's colour in a screenshot: the median of grid cells' middles that are in
    the view, clear of the panel and at least 1.5 m from every agent."""
    agents = np.array(list(app.hook("e.positions()").values()))[:, ::2]
    box = app.panel_box()
    height, width = image.shape[:2]
    samples = []
    for x, z in GROUND_CELLS:
        if np.linalg.norm(agents - (x, z), axis=1).min() < 1.5:
            continue
        px, py = app.hook(f"e.toScreen({x}, {z})")
        clear = not (box["x"] <= px <= box["x"] + box["width"]
                     and box["y"] <= py <= box["y"] + box["height"])
        if 0 <= px < width and 0 <= py < height and clear:
            samples.append(image[math.floor(py), math.floor(px)])
    assert len(samples) >= 5, f"only {len(samples)} ground samples at {app.size}"
    return "#" + "".join(f"{int(c):02x}" for c in np.median(np.array(samples), axis=0))
