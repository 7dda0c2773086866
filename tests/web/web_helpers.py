"""Helpers of the browser runtime's tests: a stdlib static server, a page whose every request
is checked to stay on 127.0.0.1, and waits on the page's own state."""

from __future__ import annotations

import functools
import http.server
import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np

#: A small page: WebGL on SwiftShader renders every pixel on the CPU.
VIEWPORT = {"width": 960, "height": 600}
#: Wall seconds any one wait or page action may take (a hang guard, not a budget).
HANG_SECONDS = 300.0
#: Milliseconds between two polls of a wait.
POLL_MS = 100


class _Handler(http.server.SimpleHTTPRequestHandler):
    """Static files of one folder; paths in ``missing`` answer 404; no log lines."""

    missing: frozenset[str] = frozenset()

    def do_GET(self) -> None:
        if urlsplit(self.path).path.lstrip("/") in self.missing:
            self.send_error(404)
            return
        super().do_GET()

    def log_message(self, format: str, *args: Any) -> None:
        pass


@contextmanager
def static_server(folder: Path, missing: tuple[str, ...] = ()) -> Iterator[str]:
    """``python -m http.server`` on 127.0.0.1 (a free port) in a thread; yields its base URL.

    Args:
        folder: the folder served.
        missing: file names (relative to ``folder``) answered with 404, as if deleted.
    """
    handler = type("Handler", (_Handler,), {"missing": frozenset(missing)})
    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(handler, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=30)


@dataclass
class WebPage:
    """A page of the exported folder and what it did: requests, problems."""

    page: Any
    context: Any
    base: str
    requests: list[str] = field(default_factory=list)
    off_host: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    def hook(self, expression: str) -> Any:
        """Evaluate ``expression`` with ``e`` bound to ``window.emotiveWeb`` (awaited)."""
        return self.page.evaluate(
            f"async () => {{ const e = window.emotiveWeb; return {expression}; }}")

    def wait(self, condition: str) -> None:
        """Wait until the JavaScript ``condition`` (``e``: the hook) is true."""
        self.page.wait_for_function(
            f"() => {{ const e = window.emotiveWeb; return Boolean(e && ({condition})); }}",
            polling=POLL_MS, timeout=HANG_SECONDS * 1000)

    def close(self) -> None:
        self.context.close()


def open_page(browser: Any, base: str, query: str = "", init_script: str | None = None
              ) -> WebPage:
    """The page at ``base/?query`` in a fresh context whose requests are all intercepted:
    those to 127.0.0.1 go on, any other is recorded in ``off_host`` and aborted."""
    context = browser.new_context(viewport=VIEWPORT)
    context.set_default_timeout(HANG_SECONDS * 1000)
    page = context.new_page()
    web = WebPage(page, context, base)

    def route(r: Any) -> None:
        url = r.request.url
        web.requests.append(url)
        if urlsplit(url).hostname == "127.0.0.1":
            r.continue_()
        else:
            web.off_host.append(url)
            r.abort()

    context.route("**/*", route)
    page.on("console", lambda m: web.problems.append(f"console {m.type}: {m.text}")
            if m.type == "error" else None)
    page.on("pageerror", lambda e: web.problems.append(f"page error: {e}"))
    if init_script is not None:
        page.add_init_script(init_script)
    page.goto(f"{base}/{'?' + query if query else ''}")
    return web


def docs_circles(radii: tuple[float, ...] = (1.5, 2.0, 2.5)) -> list[np.ndarray]:
    """The circles of ``docs/runtime.md``'s example as dense polylines (``(N, 2)`` each)."""
    out = []
    for r in radii:
        a = np.linspace(0.0, 2.0 * math.pi, int(2.0 * math.pi * r / 0.005) + 1)
        out.append(np.stack((r * (1 - np.cos(a)), r * np.sin(a)), -1))
    return out


def phase_of(seed: int) -> float:
    """The starting phase ``GaitGenerator.add_agents(..., seeds=[seed])`` draws."""
    return float(np.random.default_rng([seed]).uniform(0.0, 2.0 * math.pi))


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """``(N,)`` distance of each of ``(N, 2)`` points to the polyline ``(K, 2)``."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.einsum("nkc,kc->nk", points[:, None] - a, ab) / np.maximum(
        np.einsum("kc,kc->k", ab, ab), 1e-12)
    nearest = a + np.clip(t, 0, 1)[..., None] * ab
    return np.linalg.norm(points[:, None] - nearest, axis=-1).min(axis=1)


@dataclass
class CrowdRun:
    """What a page with a scene did: its frames' records (``crowd.frames()`` of the hook) and
    its summary at the end, with the wall seconds the stepping took (for the report only)."""

    frames: list[dict[str, Any]]
    summary: dict[str, Any]
    seconds: float


def run_crowd(web: WebPage, max_frames: int, chunk: int = 30) -> CrowdRun:
    """Step the page's crowd ``chunk`` frames at a time through the test hook until it is done
    (every agent spawned and at its goal) or ``max_frames`` frames were stepped; collects
    every frame's record on the way."""
    import time

    frames: list[dict[str, Any]] = []
    start = time.perf_counter()
    while True:
        web.page.evaluate("async (n) => window.emotiveWeb.test.step(n)", chunk)
        frames += web.page.evaluate("(k) => window.emotiveWeb.crowd.frames(k)",
                                    frames[-1]["frame"] + 1 if frames else 0)
        summary = web.hook("e.crowd.summary()")
        if summary["done"] or summary["frame"] >= max_frames:
            return CrowdRun(frames, summary, time.perf_counter() - start)


def closest_hips(frames: list[dict[str, Any]]) -> tuple[float, int, int]:
    """The smallest distance between two bodies' hips in any one frame (metres), the frame
    where it happened, and the number of pair-frames closer than 0.3 m."""
    best, where, close = math.inf, -1, 0
    for record in frames:
        hips = np.asarray(record["hips"], dtype=np.float64).reshape(-1, 2)
        if len(hips) < 2:
            continue
        d = np.linalg.norm(hips[:, None] - hips[None], axis=-1)
        upper = d[np.triu_indices(len(hips), 1)]
        close += int((upper < 0.3).sum())
        if upper.min() < best:
            best, where = float(upper.min()), int(record["frame"])
    return best, where, close
