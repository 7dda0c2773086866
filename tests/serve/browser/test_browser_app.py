"""The browser app of ``emotive serve`` in real headless Chromium.

Debian's ``chromium`` is driven by Playwright's bundled driver (no browser download), with
WebGL on SwiftShader. One server and one page for the module: the page opens ``/?demo=1``
(four agents walking) and the tests use it in order, reading the app through its read-only
debug hook ``window.emotive`` and the server through ``/api/agents``.

Waits are on the app's state, with budgets in scene seconds (the server's scene time, frame
number / fps, of the latest frame the page got) and in frames the page rendered: on a busy
machine the server skips ticks and software WebGL renders a few frames a second, so both run
behind wall time. Wall time only bounds a hang.

Chromium or Playwright missing: the tests skip, naming what to install; CI sets
``EMOTIVE_REQUIRE_TOOLS=1``, which turns a skip into a failure.
"""

from __future__ import annotations

import io
import math
import struct
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qs, urlsplit

import httpx
import numpy as np
import pytest

from emotive.serve.frames import Frame, decode_frame, encode_frame
from emotive.serve.rig import FrameRig
from emotive.serve.testing import running_server
from tools import headless_chromium

#: A small page: WebGL on SwiftShader renders every pixel on the CPU.
VIEWPORT = {"width": 960, "height": 600}
#: The part of the page right of the control panel: only the 3-D view.
VIEW_CLIP = {"x": 280, "y": 0, "width": 680, "height": 600}
#: Agents the demo scene starts with.
DEMO_AGENTS = 4
#: Agents the test server allows: the demo's and the one placed by a click.
MAX_AGENTS = DEMO_AGENTS + 1
#: The token of the test server.
TOKEN = "browser-test-token"
#: Wall seconds in which neither scene time nor rendered frames advance that count as a hang;
#: also Playwright's timeout of each action.
STALL_SECONDS = 120.0
#: Wall seconds any one wait may take in all (a hang guard, not a budget), and the page's
#: start.
HANG_SECONDS = 600.0
#: Wall seconds an HTTP request to the test server may take (a hang guard).
REQUEST_SECONDS = 60.0
#: Milliseconds between two polls of a wait.
POLL_MS = 200


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Headless Chromium, launched once for the module."""
    yield from headless_chromium(HANG_SECONDS)


def _new_page(browser: Any) -> Any:
    """A page of the test size whose actions wait up to the hang guard."""
    page = browser.new_page(viewport=VIEWPORT)
    page.set_default_timeout(STALL_SECONDS * 1000)
    return page


@dataclass
class Progress:
    """How far the app got during a wait."""

    scene: float  #: scene seconds between the frames the page had at the start and now
    frames: int  #: frames the page rendered
    wall: float  #: wall seconds
    fps: float  #: the page's renderFps

    def __str__(self) -> str:
        return (f"after {self.scene:.1f} scene s, {self.frames} frames rendered, "
                f"{self.wall:.1f} wall s (renderFps {self.fps:.1f})")


@dataclass
class App:
    """The page of the app, the server's base URL, and the problems the page reported."""

    page: Any
    base: str
    problems: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)

    def hook(self, expression: str) -> Any:
        """Evaluate ``expression`` with ``e`` bound to ``window.emotive``."""
        return self.page.evaluate(f"() => {{ const e = window.emotive; return {expression}; }}")

    def agents(self) -> dict[int, dict[str, Any]]:
        """The server's agents by id (``GET /api/agents``)."""
        reply = httpx.get(f"{self.base}/api/agents", timeout=REQUEST_SECONDS,
                          headers={"Authorization": f"Bearer {TOKEN}"})
        reply.raise_for_status()
        return {a["id"]: a for a in reply.json()["agents"]}

    def clock(self) -> tuple[float, int, float]:
        """The scene time of the page's latest frame, its frames rendered and its renderFps."""
        return tuple(self.page.evaluate(
            "() => { const e = window.emotive; "
            "return [e.lastFrame ? e.lastFrame.time : 0, e.framesRendered, e.renderFps]; }"))

    def within(self, check: Callable[[], Any], scene: float = 0.0,
               frames: int = 0) -> tuple[Any, Progress]:
        """Poll ``check`` (letting the page run) until it returns something truthy.

        Gives up once the budget is spent: ``scene`` scene seconds passed and ``frames``
        frames were rendered, both. Returns ``check``'s last result and the progress; fails
        on a hang (no progress for ``STALL_SECONDS``, or ``HANG_SECONDS`` in all).
        """
        t0, r0, _ = self.clock()
        start = moved = time.monotonic()
        last = (t0, r0)
        while True:
            # The clock is read before the check: a budget spent means the check saw it.
            t, r, fps = self.clock()
            now = time.monotonic()
            progress = Progress(t - t0, r - r0, now - start, fps)
            result = check()
            if result or (progress.scene >= scene and progress.frames >= frames):
                return result, progress
            if (t, r) != last:
                last, moved = (t, r), now
            if now - moved > STALL_SECONDS:
                pytest.fail(f"no progress: neither scene time nor rendered frames advanced "
                            f"for {STALL_SECONDS:.0f} s ({progress})")
            if now - start > HANG_SECONDS:
                pytest.fail(f"no progress within {HANG_SECONDS:.0f} s ({progress})")
            self.page.wait_for_timeout(POLL_MS)

    def until(self, check: Callable[[], Any], what: str | Callable[[], str],
              scene: float = 0.0, frames: int = 0) -> Any:
        """``check``'s first truthy result within the budget of :meth:`within`, or a failure
        saying ``what`` (a string or a callable giving one) and how far the app got."""
        result, progress = self.within(check, scene, frames)
        if not result:
            pytest.fail(f"{what() if callable(what) else what} ({progress})")
        return result

    def run_for(self, scene: float = 0.0, frames: int = 0) -> Progress:
        """Let the app run for ``scene`` scene seconds and ``frames`` rendered frames."""
        return self.within(lambda: False, scene, frames)[1]

    def view(self) -> np.ndarray:
        """A screenshot of the 3-D view as an ``(H, W, 3)`` array."""
        from PIL import Image

        png = self.page.screenshot(clip=VIEW_CLIP)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))

    def select(self, agent: int) -> None:
        self.page.click(f'#agent-list button[data-agent="{agent}"]')
        assert self.hook("e.selected") == agent


@pytest.fixture(scope="module")
def app(browser) -> Iterator[App]:
    """The app at ``/?demo=1`` on a fresh server that needs a token, once its agents walk.

    The token is given in the page's address only: every call the app makes must pass it on.
    """
    with running_server(token=TOKEN, max_agents=MAX_AGENTS) as base:
        page = _new_page(browser)
        app = App(page, base)
        page.on("console", lambda m: app.problems.append(f"console {m.type}: {m.text}")
                if m.type == "error" else None)
        page.on("pageerror", lambda e: app.problems.append(f"page error: {e}"))
        page.on("request", lambda r: app.requests.append(r.url))
        page.goto(f"{base}/?demo=1&token={TOKEN}")
        page.wait_for_function(
            f"() => window.emotive?.ready && window.emotive.agents().length >= {DEMO_AGENTS}",
            polling=POLL_MS, timeout=HANG_SECONDS * 1000)
        yield app
        page.close()


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """``(N,)`` distance of each of ``(N, 2)`` points to the polyline ``(K, 2)``."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.einsum("nkc,kc->nk", points[:, None] - a, ab) / np.maximum(
        np.einsum("kc,kc->k", ab, ab), 1e-12)
    nearest = a + np.clip(t, 0, 1)[..., None] * ab
    return np.linalg.norm(points[:, None] - nearest, axis=-1).min(axis=1)


def test_page_loads_without_errors(app):
    # The page gets frames and draws them a few times before anything is judged.
    app.until(lambda: app.hook("e.framesReceived > 10 && e.framesRendered > 3"),
              "the page did not receive 10 frames", scene=5)
    assert app.problems == []
    assert app.hook("e.errors") == []
    assert app.hook("e.framesReceived") > 10
    assert set(app.hook("e.agents()")) == set(app.agents())
    assert app.page.title().startswith("emotive")
    # Everything comes from the server itself: no CDN, no other host.
    foreign = [u for u in app.requests if not u.startswith((app.base + "/", "data:", "blob:"))]
    assert foreign == []
    assert any(u.startswith(f"{app.base}/static/vendor/three/") for u in app.requests)


def test_frame_decoder_reads_the_documented_layout(app):
    # A frame built from the table of docs/serve.md by hand: B=2, J=3, P=5, C=4.
    b, j, p, c = 2, 3, 5, 4
    rng = np.random.default_rng(0)
    blocks = {"va": (b, 2), "weights": (b, c), "mover": (b, 3), "rotations": (b, j, 4),
              "points": (b, p, 3)}
    arrays = {k: rng.normal(size=shape).astype("<f4") for k, shape in blocks.items()}
    ids = np.array([7, -3], dtype="<i4")
    data = (struct.pack("<4sIdIIII", b"EMF1", 4_000_000_000, 12.345678901, b, j, p, c)
            + ids.tobytes() + b"".join(a.tobytes() for a in arrays.values()))
    decoded = app.page.evaluate(
        """async (bytes) => {
            const { decodeFrame } = await import("/static/protocol.js");
            const f = decodeFrame(new Uint8Array(bytes).buffer);
            const plain = {};
            for (const [k, v] of Object.entries(f)) {
                plain[k] = ArrayBuffer.isView(v) ? [...v] : v;
            }
            let bad = null;
            try {
                decodeFrame(new Uint8Array(bytes.slice(0, -4)).buffer);
            } catch (e) {
                bad = e.message;
            }
            return { plain, bad };
        }""", list(data))
    frame = decoded["plain"]
    assert (frame["frame"], frame["B"], frame["J"], frame["P"], frame["C"]) == (
        4_000_000_000, b, j, p, c)
    assert frame["time"] == 12.345678901
    assert frame["ids"] == [7, -3]
    for name, array in arrays.items():
        np.testing.assert_array_equal(np.array(frame[name], dtype="<f4"), array.reshape(-1))
    assert "layout needs" in decoded["bad"]


def test_compact_frame_decoder_matches_python(app):
    # A version-2 frame of the server's rig, decoded by the page (protocol.js, rig.js) and by
    # emotive.serve.frames: the same rotations and world positions.
    info = httpx.get(f"{app.base}/api/skeleton", timeout=REQUEST_SECONDS,
                     headers={"Authorization": f"Bearer {TOKEN}"}).json()
    b, j, c = 3, len(info["joints"]), len(info["labels"])
    rng = np.random.default_rng(1)
    rotations = rng.normal(size=(b, j, 4))
    rotations /= np.linalg.norm(rotations, axis=-1, keepdims=True)
    frame = Frame(77, 2.5, np.array([4, 9, -2]), rng.uniform(-1, 1, (b, 2)),
                  rng.random((b, c)), rng.normal(size=(b, 3)), rotations)
    data = encode_frame(frame, 2)
    expected = decode_frame(data, FrameRig.from_info(info))
    decoded = app.page.evaluate(
        """async ([bytes, info]) => {
            const { decodeFrame } = await import("/static/protocol.js");
            const { Rig } = await import("/static/rig.js");
            const f = decodeFrame(new Uint8Array(bytes).buffer, new Rig(info));
            const plain = {};
            for (const [k, v] of Object.entries(f)) {
                plain[k] = ArrayBuffer.isView(v) ? [...v] : v;
            }
            return plain;
        }""", [list(data), info])
    assert (decoded["version"], decoded["frame"], decoded["time"]) == (2, 77, 2.5)
    assert (decoded["B"], decoded["J"], decoded["C"]) == (b, j, c)
    assert decoded["P"] == j + len(info["end_site_parents"])
    assert decoded["ids"] == [4, 9, -2]
    for name, ours in (("rotations", expected.rotations), ("mover", expected.root),
                       ("va", expected.valence_arousal), ("weights", expected.emotion),
                       ("points", expected.world)):
        np.testing.assert_allclose(np.array(decoded[name]), np.ravel(ours), atol=2e-6,
                                   err_msg=name)


def test_characters_move(app):
    before, positions = app.view(), app.hook("e.positions()")
    # A scene second, and the view drawn again since.
    progress = app.run_for(scene=1.0, frames=3)
    after, moved = app.view(), app.hook("e.positions()")
    changed = np.abs(after.astype(int) - before.astype(int)).max(axis=-1) > 16
    assert changed.sum() > 500, f"the 3-D view did not change ({progress})"
    for agent, xyz in positions.items():
        step = math.dist(xyz[::2], moved[agent][::2])
        assert step > 0.3, f"agent {agent} moved {step:.2f} m ({progress})"


def test_mannequin_bones_are_bound_by_name_and_follow_the_frames(app):
    assert app.hook("e.figureMode") == "mannequin"
    joints = app.hook("e.joints")
    assert joints > 10
    for agent in app.hook("e.agents()"):
        assert app.hook(f"e.boundBones({agent})") == joints
        # Posed from the frame's local rotations and mover, each bone lies on the frame's
        # world position of its joint.
        assert app.hook(f"e.mannequinOffset({agent})") < 1e-3
    app.page.click("#figure-sticks")
    assert app.hook("e.figureMode") == "sticks"
    app.run_for(frames=3)
    app.page.click("#figure-mannequin")
    assert app.hook("e.figureMode") == "mannequin"


def test_happy_slider_makes_an_agent_happy(app):
    agent = min(a for a, s in app.agents().items() if s["emotion"].get("happy", 0) < 0.5)
    app.select(agent)
    for label in ("happy", "sad", "angry", "neutral"):
        app.page.press(f'#sliders input[data-label="{label}"]',
                       "End" if label == "happy" else "Home")

    def happy() -> bool:
        emotion = app.agents()[agent]["emotion"]
        return max(emotion, key=emotion.get) == "happy" and emotion["happy"] > 0.9

    app.until(happy, f"agent {agent} is not happy on the server", scene=5)


def test_valence_arousal_disc_sets_emotion(app):
    agent = app.hook("e.selected")
    box = app.page.locator("#va-disc").bounding_box()
    # Valence -0.6, arousal +0.6: the angry quadrant (valence right, arousal up).
    app.page.mouse.click(box["x"] + box["width"] * 0.2, box["y"] + box["height"] * 0.2)

    def unpleasant_and_aroused() -> bool:
        state = app.agents()[agent]
        return state["valence"] < -0.2 and state["arousal"] > 0.2

    app.until(unpleasant_and_aroused, f"agent {agent} did not take the disc's emotion",
              scene=5)


def test_click_on_the_ground_places_an_agent(app):
    before = app.agents()
    positions = np.array(list(app.hook("e.positions()").values()))[:, ::2]
    spots = np.array([[x, z] for x in (-1.0, 0.0, 1.0) for z in (-3.0, 0.0, 3.0)])
    spot = max(spots, key=lambda p: np.linalg.norm(positions - p, axis=1).min())
    app.page.mouse.click(*app.hook(f"e.toScreen({spot[0]}, {spot[1]})"))
    added = app.until(lambda: set(app.agents()) - set(before), "no agent was added", scene=5)
    (agent,) = added
    path = np.array(app.agents()[agent]["path"])
    np.testing.assert_allclose((path.min(0) + path.max(0)) / 2, spot, atol=0.1)
    # Selected in the render loop once its first frame came.
    app.until(lambda: app.hook("e.selected") == agent, "the new agent is not selected",
              scene=5, frames=10)


def test_drawn_path_is_followed(app):
    states = app.agents()

    def screen_x(agent: int) -> float:
        x, _, z = app.hook(f"e.positions()[{agent}]")
        return app.hook(f"e.toScreen({x}, {z})")[0]

    # An agent that is not the happy one, the farthest from the panel on the left.
    agent = max((a for a, s in states.items() if s["emotion"].get("happy", 0) < 0.5),
                key=screen_x)
    app.select(agent)
    app.page.click("#mode-draw")
    start = np.array(app.hook(f"e.positions()[{agent}]"))[::2]
    # Towards the middle of the view and past it, bending: on screen, clear of the panel.
    towards = -start / max(np.linalg.norm(start), 1e-6)
    side = np.array([-towards[1], towards[0]])
    s = np.linspace(0, 1, 13)[:, None]
    wanted = start + 5.0 * s * towards + 1.0 * np.sin(np.pi * s) * side
    screen = [app.hook(f"e.toScreen({x}, {z})") for x, z in wanted]
    app.page.mouse.move(*screen[0])
    app.page.mouse.down()
    for x, y in screen[1:]:
        app.page.mouse.move(x, y)
    app.page.mouse.up()
    app.page.click("#mode-place")

    drawn = np.array(app.hook("e.drawnPath"))
    assert len(drawn) >= 10
    assert _distance_to_polyline(drawn, wanted).max() < 0.1

    path = np.array(app.until(lambda: app.agents()[agent]["path"] != states[agent]["path"]
                              and app.agents()[agent]["path"], "the path did not change",
                              scene=5))
    # The server's path is a smooth curve through the drawn points.
    np.testing.assert_allclose(path[[0, -1]], drawn[[0, -1]], atol=0.05)
    assert _distance_to_polyline(path, drawn).max() < 0.15
    assert _distance_to_polyline(drawn, path).max() < 0.05

    def on_the_path() -> bool:
        here = np.array(app.hook(f"e.positions()[{agent}]"))[::2]
        return (_distance_to_polyline(here[None], path)[0] < 0.4
                and np.linalg.norm(here - start) > 1.5)

    app.until(on_the_path, f"agent {agent} does not walk the drawn path", scene=8)


def test_click_on_an_agent_selects_it(app):
    # The agent at the end of its drawn (open) path stands or walks slowest: it moves least.
    before = app.hook("e.positions()")
    app.run_for(scene=0.5)
    after = app.hook("e.positions()")
    agent = int(min(before, key=lambda a: math.dist(before[a], after[a])))
    app.select(next(a for a in app.hook("e.agents()") if a != agent))
    for _ in range(3):  # it may walk out from under the pointer while the click travels
        x, _, z = app.hook(f"e.positions()[{agent}]")
        app.page.mouse.click(*app.hook(f"e.toScreen({x}, {z})"))
        if app.within(lambda: app.hook("e.selected") == agent, scene=0.3, frames=2)[0]:
            break
    assert app.hook("e.selected") == agent
    assert app.page.locator("#selected-name").inner_text() == f"Agent {agent}"


def test_follow_camera_keeps_the_agent_in_view(app):
    agent = app.hook("e.selected")
    app.page.click("#camera-follow")
    seen = []

    def in_view() -> bool:
        x, z = app.hook(f"e.positions()[{agent}]")[::2]
        px, py = app.hook(f"e.toScreen({x}, {z})")
        seen.append((round(px), round(py)))
        return (abs(px - VIEWPORT["width"] / 2) < 0.2 * VIEWPORT["width"]
                and VIEWPORT["height"] / 2 < py < VIEWPORT["height"])

    # The camera closes in on the agent each rendered frame, by the frame's time (at most
    # 0.5 s): 2.5 scene seconds and 10 rendered frames give it at least 2.5 s of that.
    app.until(in_view, lambda: f"agent {agent} is at {seen[-1]} on the page, out of the "
              "follow camera's view", scene=2.5, frames=10)
    app.page.click("#camera-fixed")
    assert app.hook("e.cameraMode") == "fixed"


def test_recording_downloads_as_bvh_and_glb(app):
    app.page.click("#record-start")
    app.page.wait_for_selector("#record-stop:not([disabled])")
    app.run_for(scene=1.0)
    app.page.click("#record-stop")
    links = app.page.locator("#downloads a")
    links.nth(1).wait_for()
    files = {}
    for href in links.evaluate_all("(as) => as.map((a) => a.getAttribute('href'))"):
        assert f"token={TOKEN}" in href
        reply = httpx.get(f"{app.base}{href}", timeout=REQUEST_SECONDS)
        reply.raise_for_status()
        files[parse_qs(urlsplit(href).query)["format"][0]] = reply.content
    assert files["bvh"].startswith(b"HIERARCHY")
    assert files["glb"][:4] == b"glTF"


def test_webxr_unsupported_shows_a_message(app):
    supported = app.page.evaluate(
        "async () => navigator.xr ? navigator.xr.isSessionSupported('immersive-ar') : false")
    assert not supported
    message = app.page.locator("#xr-message")
    assert message.is_visible()
    assert "AR is not supported" in message.inner_text() or \
        "WebXR is not available" in message.inner_text()
    assert app.page.locator("#xr button").count() == 0


def test_no_errors_in_the_whole_session(app):
    assert app.problems == []
    assert app.hook("e.errors") == []


def test_server_errors_show_as_toasts(app):
    # The scene is full (MAX_AGENTS): one more agent is refused with an error reply.
    assert len(app.agents()) == MAX_AGENTS
    frames = app.hook("e.framesReceived")
    free = np.array(list(app.hook("e.positions()").values()))[:, ::2]
    spot = max((np.array([x, -3.0]) for x in (-2.0, 0.0, 2.0)),
               key=lambda p: np.linalg.norm(free - p, axis=1).min())
    app.page.mouse.click(*app.hook(f"e.toScreen({spot[0]}, {spot[1]})"))
    app.page.locator(".toast").first.wait_for()
    assert len(app.hook("e.errors")) == 1
    assert len(app.agents()) == MAX_AGENTS
    app.until(lambda: app.hook("e.framesReceived") > frames + 10, "the stream stopped",
              frames=150)
    assert app.problems == []


def test_remove_button_removes_the_selected_agent(app):
    agent = app.hook("e.selected")
    assert agent is not None
    app.page.click("#remove-agent")
    app.until(lambda: agent not in app.agents(), f"agent {agent} is still on the server",
              scene=5)
    app.until(lambda: agent not in app.hook("e.agents()"), f"agent {agent} is still drawn",
              scene=5)
    assert app.hook("e.selected") is None


def test_webxr_buttons_where_sessions_are_supported(app, browser):
    # The tests of the main page are done: it leaves, so that its rendering (on the CPU)
    # does not slow down the pages of the tests below.
    app.page.goto("about:blank")
    page = _new_page(browser)
    # A browser that says it supports both session types (no device behind it).
    page.add_init_script("XRSystem.prototype.isSessionSupported = async () => true;")
    page.goto(f"{app.base}/?token={TOKEN}")
    page.wait_for_function("() => window.emotive?.ready", polling=POLL_MS,
                           timeout=HANG_SECONDS * 1000)
    buttons = page.locator("#xr button")
    buttons.nth(1).wait_for()
    assert sorted(buttons.all_inner_texts()) == ["ENTER VR", "START AR"]
    assert page.locator("#xr-message").count() == 0
    page.close()


def test_a_page_without_the_token_says_so(app, browser):
    page = _new_page(browser)
    page.goto(f"{app.base}/")
    page.wait_for_function("() => window.emotive?.errors.length > 0", polling=POLL_MS)
    assert "needs its token" in page.locator("#stat-connection").inner_text()
    page.close()
