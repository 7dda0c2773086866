"""The page of ``emotive export web`` in real headless Chromium, served by the stdlib's
``http.server`` alone: no request leaves 127.0.0.1, its agents match ``GaitGenerator`` fed the
same inputs, they walk the paths drawn with the mouse, and bad input (a missing file, a
browser without WebAssembly SIMD) gives a message on a page that still responds.

Debian's ``chromium`` is driven by Playwright's bundled driver (``tests/tools.py``), WebGL on
SwiftShader. Waits are on the page's own state (``window.emotiveWeb``), bounded by a hang
guard; the parity test steps the agents through the page's test hook, frame by frame, not by
the clock. Chromium or Playwright missing: the tests skip (a failure under
``EMOTIVE_REQUIRE_TOOLS=1``).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from web_helpers import (
    HANG_SECONDS,
    WebPage,
    distance_to_polyline,
    docs_circles,
    open_page,
    phase_of,
    static_server,
)

from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import load_gait_model
from emotive.paths import GroundPath, waypoints
from tools import headless_chromium

#: Frames the parity test compares after (three seconds at 30 fps).
FRAMES = 90
#: The largest joint difference allowed against the generator, metres.
TOLERANCE = 1e-3
#: Frames of the real-time clock an agent walks before its distance to the drawn path is read.
WALK_FRAMES = 75


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    yield from headless_chromium(HANG_SECONDS)


@pytest.fixture(scope="module")
def served(web_export) -> Iterator[str]:
    with static_server(web_export.folder) as base:
        yield base


@pytest.fixture(scope="module")
def web(browser, served) -> Iterator[WebPage]:
    """The page with its clock stopped (``?paused=1``), once its runtime is loaded."""
    page = open_page(browser, served, "paused=1")
    page.wait("e.ready || e.status === 'error'")
    assert page.hook("e.status") == "running", page.hook("e.error")
    yield page
    page.close()


def test_the_page_runs_from_static_files_with_no_request_off_the_host(web):
    assert web.off_host == []
    assert web.problems == [] and web.hook("e.errors") == []
    fetched = {url.split("?")[0].rsplit("/", 1)[-1] for url in web.requests}
    assert {"agent.onnx", "agent.json", "mannequin.glb", "ort.wasm.bundle.min.mjs",
            "ort-wasm-simd-threaded.wasm", "three.module.js"} <= fetched
    assert web.hook("e.fps") == 30 and "happy" in web.hook("e.labels")
    expanded = web.page.get_attribute("#panel-toggle", "aria-expanded")
    assert expanded in ("true", "false")


def test_joints_after_90_frames_match_the_generator_fed_the_same_inputs(web):
    """The docs' three circles and an open spline with a blend, seeds 0-3: within 1e-3 m."""
    polylines = [(p, True) for p in docs_circles()]
    polylines.append((waypoints(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 1.5], [3.0, 1.0],
                                          [4.0, 3.0]])).points, False))
    emotions = [{"happy": 1}, {"sad": 1}, {"angry": 1}, {"happy": 0.5, "sad": 0.5}]
    specs = [{"points": p.tolist(), "closed": closed, "emotion": e, "phase": phase_of(k)}
             for k, ((p, closed), e) in enumerate(zip(polylines, emotions, strict=True))]
    web.hook("e.test.removeAll()")
    ids = web.page.evaluate("async (specs) => window.emotiveWeb.test.addAgents(specs)", specs)
    warmup = web.hook("e.agents()")[0]["warm"]
    web.page.evaluate("async (n) => window.emotiveWeb.test.step(n)", warmup + FRAMES)
    assert [a["walked"] for a in web.hook("e.agents()")] == [FRAMES] * len(ids)
    ours = np.array([web.hook(f"e.world({i})") for i in ids])

    gen = GaitGenerator(load_gait_model())
    gen.add_agents([GroundPath.from_polyline(p, closed=closed) for p, closed in polylines],
                   [",".join(f"{k}={v}" for k, v in e.items()) for e in emotions],
                   seeds=list(range(len(ids))))
    for _ in range(FRAMES):
        frame = gen.step()
    gap = np.abs(ours - frame.world).max()
    print(f"max joint difference after {FRAMES} frames: {gap:.2e} m")
    assert gap <= TOLERANCE, f"max joint difference {gap:.2e} m"
    # They walked: metres along their paths, as Python's agents did.
    arcs = np.array([a["arc"] for a in web.hook("e.agents()")])
    np.testing.assert_allclose(arcs, np.mod(gen.agent_field("arc"), [
        GroundPath.from_polyline(p, closed=c).length if c else np.inf for p, c in polylines]),
        atol=1e-3)
    assert (arcs > 1.0).all()
    web.hook("e.test.removeAll()")


def _drag(web: WebPage, ground: np.ndarray) -> None:
    screen = [web.hook(f"e.toScreen({x}, {z})") for x, z in ground]
    web.page.mouse.move(*screen[0])
    web.page.mouse.down()
    for x, y in screen[1:]:
        web.page.mouse.move(x, y, steps=2)
    web.page.mouse.up()


def test_an_agent_walks_the_path_drawn_with_the_mouse(web):
    web.hook("e.test.removeAll()")
    web.wait("e.agents().length === 0")
    web.page.click("#mode-draw")
    s = np.linspace(0.0, 1.0, 13)[:, None]
    wanted = np.array([-1.5, 2.5]) + 4.0 * s * np.array([1.0, -0.6]) + np.sin(np.pi * s) * [
        0.6, 1.0]
    _drag(web, wanted)
    web.page.click("#mode-place")
    drawn = np.array(web.hook("e.drawnPath"))
    assert len(drawn) >= 10 and distance_to_polyline(drawn, wanted).max() < 0.1
    web.wait("e.agents().length === 1")
    (agent,) = web.hook("e.agents()")
    assert not agent["closed"] and agent["length"] > 3.5
    web.hook("e.test.resume()")
    web.wait(f"e.agents()[0].walked >= {WALK_FRAMES}")
    web.hook("e.test.pause()")
    here = np.array(web.hook(f"e.positions()[{agent['id']}]"))[[0, 2]]
    assert distance_to_polyline(here[None], drawn)[0] < 0.2
    assert np.linalg.norm(here - drawn[0]) > 1.0
    # The new agent is selected: the sliders make it happy, the disc makes it sad.
    web.wait(f"e.selected === {agent['id']}")
    for label in ("happy", "sad", "angry", "neutral"):
        web.page.press(f'#sliders input[data-label="{label}"]',
                       "End" if label == "happy" else "Home")
    emotion = dict(zip(web.hook("e.labels"), web.hook("e.agents()")[0]["emotion"], strict=True))
    assert emotion["happy"] == pytest.approx(1.0)
    box = web.page.locator("#va-disc").bounding_box()
    # Valence -0.6, arousal -0.6: the sad quadrant (valence right, arousal up).
    web.page.mouse.click(box["x"] + box["width"] * 0.2, box["y"] + box["height"] * 0.8)
    emotion = dict(zip(web.hook("e.labels"), web.hook("e.agents()")[0]["emotion"], strict=True))
    assert max(emotion, key=emotion.get) == "sad"
    assert web.off_host == [] and web.problems == []


def test_a_click_on_the_ground_places_an_agent_on_a_circle_there(web):
    before = len(web.hook("e.agents()"))
    web.page.mouse.click(*web.hook("e.toScreen(2.5, -2.0)"))
    web.wait(f"e.agents().length === {before + 1}")
    agent = web.hook("e.agents()")[-1]
    assert agent["closed"] and agent["length"] == pytest.approx(2 * np.pi * 1.5, rel=1e-3)
    web.page.evaluate("async () => window.emotiveWeb.test.step(20)")
    x, _, z = web.hook(f"e.positions()[{agent['id']}]")
    # On the circle of radius 1.5 m centred on the click.
    assert abs(np.hypot(x - 2.5, z + 2.0) - 1.5) < 0.2
    assert web.problems == []


def test_webxr_unsupported_shows_a_message(web):
    message = web.page.locator("#xr-message")
    assert message.is_visible()
    assert web.page.locator("#xr button").count() == 0


def test_webxr_buttons_where_sessions_are_supported(browser, served):
    page = open_page(browser, served, "paused=1",
                     init_script="XRSystem.prototype.isSessionSupported = async () => true;")
    try:
        # The buttons come before the runtime loads: no need to wait for it.
        buttons = page.page.locator("#xr button")
        buttons.nth(1).wait_for()
        assert sorted(buttons.all_inner_texts()) == ["ENTER VR", "START AR"]
    finally:
        page.close()


def _still_responds(page: WebPage) -> None:
    """The view renders on and the controls answer."""
    frames = page.hook("e.framesRendered")
    page.wait(f"e.framesRendered > {frames + 2}")
    page.page.click("#figure-sticks")
    assert page.hook("e.figureMode") == "sticks"
    page.page.mouse.click(*page.hook("e.toScreen(1.0, 1.0)"))
    page.page.locator(".toast").first.wait_for()


@pytest.mark.parametrize("missing", ["agent.onnx", "agent.json"])
def test_a_missing_file_gives_a_message_and_the_page_still_responds(browser, web_export,
                                                                    missing):
    with static_server(web_export.folder, missing=(missing,)) as base:
        page = open_page(browser, base)
        try:
            page.wait("e.status === 'error'")
            banner = page.page.locator("#runtime-error")
            assert banner.is_visible()
            text = banner.inner_text()
            assert missing in text and "404" in text and "emotive export web" in text, text
            assert page.hook("e.error") == text
            _still_responds(page)
            assert page.off_host == []
        finally:
            page.close()


#: A browser without WebAssembly SIMD: modules using the SIMD prefix (0xFD) do not validate.
NO_SIMD = """
const validate = WebAssembly.validate;
WebAssembly.validate = (bytes) => {
  const b = bytes instanceof Uint8Array ? bytes : new Uint8Array(bytes.buffer ?? bytes);
  return b.includes(0xfd) ? false : validate.call(WebAssembly, bytes);
};
"""


def test_a_browser_without_wasm_simd_gets_a_message_not_a_frozen_page(browser, served):
    page = open_page(browser, served, init_script=NO_SIMD)
    try:
        page.wait("e.status === 'error'")
        text = page.page.locator("#runtime-error").inner_text()
        assert "WebAssembly SIMD" in text and "Chrome" in text, text
        # Nothing heavy was fetched for a runtime that cannot run.
        assert not any(u.endswith((".wasm", ".onnx")) for u in page.requests)
        _still_responds(page)
        assert page.off_host == []
    finally:
        page.close()
