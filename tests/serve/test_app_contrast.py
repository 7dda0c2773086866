"""The served app's figure colours against its background, read from the shipped files.

The colours live in ``app.css`` (``--scene-*``, ``--figure-*``); ``figures.js`` colours each
figure by blending them in linear RGB (neutral towards the blend of two quadrants' colours).
Every figure colour, and every blend ``figures.js`` can make of them, must be at least 4.5:1
(WCAG 2, SC 1.4.3) against the scene's background and its ground. The same is checked in
the browser on the colours the app really draws (``tests/serve/browser/test_browser_panel.py``).
"""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wcag import APP_CSS, contrast_ratio, css_colors, linear_rgb, relative_luminance

STATIC = APP_CSS.parent
#: WCAG 2's minimum contrast for normal text (SC 1.4.3), asked of every figure colour.
MIN_CONTRAST = 4.5
#: What the figures are seen against: the cleared background and the ground they stand on.
BACKDROPS = ("scene-background", "scene-ground")


def _quadrants() -> list[tuple[float, str]]:
    """``figures.js``'s QUADRANTS: (angle in degrees, emotion) of each quadrant's colour."""
    text = (STATIC / "figures.js").read_text("utf-8")
    block = re.search(r"const QUADRANTS = \[(.*?)\];", text, re.S)
    assert block, "figures.js has no QUADRANTS table"
    return [(float(a), name) for a, name in re.findall(r'\[(\d+), "(\w+)"\]', block.group(1))]


def _to_srgb_hex(rgb: tuple[float, float, float]) -> str:
    """Linear-light channels -> ``"#rrggbb"`` (sRGB, rounded as a browser shows it)."""
    def encode(c: float) -> int:
        c = min(max(c, 0.0), 1.0)
        s = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055
        return round(255 * s)

    return "#" + "".join(f"{encode(c):02x}" for c in rgb)


def _lerp(a, b, t):
    return tuple(x + (y - x) * t for x, y in zip(a, b, strict=True))


def emotion_color(valence: float, arousal: float) -> str:
    """What ``figures.js``'s ``emotionColor`` makes of app.css's colours, as ``#rrggbb``."""
    colors = css_colors()
    quadrants = _quadrants()
    angle = (math.degrees(math.atan2(arousal, valence)) - quadrants[0][0]) % 360
    i = min(int(angle // 90), 3)
    a, b = (linear_rgb(colors[f"figure-{quadrants[k % 4][1]}"]) for k in (i, i + 1))
    around = _lerp(a, b, angle / 90 - i)
    return _to_srgb_hex(_lerp(linear_rgb(colors["figure-neutral"]), around,
                              min(1.0, math.hypot(valence, arousal))))


def test_contrast_ratio_matches_wcag_reference_values():
    assert contrast_ratio("#000000", "#ffffff") == pytest.approx(21.0)
    assert contrast_ratio("#1d2126", "#1d2126") == pytest.approx(1.0)
    # The grey usually quoted as the lightest that passes 4.5:1 on white, and its neighbour.
    assert contrast_ratio("#767676", "#ffffff") == pytest.approx(4.54, abs=0.01)
    assert contrast_ratio("#ffffff", "#777777") < MIN_CONTRAST
    assert relative_luminance("#ffffff") == pytest.approx(1.0)


def test_app_css_defines_the_scene_and_every_figure_colour():
    colors = css_colors()
    names = {f"figure-{name}" for _, name in _quadrants()} | {"figure-neutral"}
    assert {"happy", "angry", "sad", "calm"} == {name for _, name in _quadrants()}
    assert names | set(BACKDROPS) <= set(colors)
    # Every colour a module asks app.css for is defined there (a missing one stops the page).
    for path in STATIC.glob("*.js"):
        for name in re.findall(r'paletteColor\(\s*"([a-z0-9-]+)"', path.read_text("utf-8")):
            assert name in colors, f"{path.name} reads --{name}, which app.css does not define"


@pytest.mark.parametrize("backdrop", BACKDROPS)
def test_every_figure_colour_contrasts_with_the_backdrop(backdrop):
    colors = css_colors()
    figures = {name: value for name, value in colors.items() if name.startswith("figure-")}
    assert len(figures) == 5
    low = {name: round(contrast_ratio(value, colors[backdrop]), 2)
           for name, value in figures.items()
           if contrast_ratio(value, colors[backdrop]) < MIN_CONTRAST}
    assert low == {}, f"figure colours below {MIN_CONTRAST}:1 against --{backdrop}: {low}"


@settings(max_examples=300, deadline=None)
@given(st.floats(-1, 1), st.floats(-1, 1))
def test_every_emotion_colour_contrasts_with_the_backdrops(valence, arousal):
    colors = css_colors()
    color = emotion_color(valence, arousal)
    for backdrop in BACKDROPS:
        assert contrast_ratio(color, colors[backdrop]) >= MIN_CONTRAST, (color, backdrop)


def test_emotion_colours_reach_each_quadrant_colour_and_neutral():
    colors = css_colors()
    assert emotion_color(0.0, 0.0) == colors["figure-neutral"]
    for angle, name in _quadrants():
        v, a = math.cos(math.radians(angle)), math.sin(math.radians(angle))
        assert emotion_color(v, a) == colors[f"figure-{name}"]
