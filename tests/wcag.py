"""WCAG 2 contrast of colours, and the colours the served app keeps in its style sheet.

The relative luminance and contrast ratio are WCAG 2.x's (Understanding SC 1.4.3): sRGB
channels linearised (threshold 0.04045, as the sRGB standard), luminance
``0.2126 R + 0.7152 G + 0.0722 B``, ratio ``(L1 + 0.05) / (L2 + 0.05)`` with ``L1`` the
lighter.
"""

from __future__ import annotations

import re
from pathlib import Path

#: The served app's style sheet, where the scene's and the figures' colours are defined.
APP_CSS = Path(__file__).resolve().parents[1] / "src" / "emotive" / "serve" / "static" / "app.css"
#: A custom property set to a ``#rrggbb`` colour: ``--name: #rrggbb;``.
_PROPERTY = re.compile(r"--([a-z0-9-]+)\s*:\s*(#[0-9a-fA-F]{6})\s*;")


def linear_rgb(color: str) -> tuple[float, float, float]:
    """``"#rrggbb"`` (sRGB) -> its three linear-light channels, 0..1 each."""
    if not re.fullmatch(r"#[0-9a-fA-F]{6}", color):
        raise ValueError(f"{color!r} is not a #rrggbb colour")
    channels = [int(color[i:i + 2], 16) / 255 for i in (1, 3, 5)]
    r, g, b = (c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in channels)
    return r, g, b


def relative_luminance(color: str) -> float:
    """WCAG 2 relative luminance of ``"#rrggbb"``: 0 (black) .. 1 (white)."""
    r, g, b = linear_rgb(color)
    return 0.2126 * r + 0.7152 * g + 0.0722 * b


def contrast_ratio(a: str, b: str) -> float:
    """WCAG 2 contrast ratio of two ``"#rrggbb"`` colours: 1 (the same) .. 21 (black, white)."""
    light, dark = sorted((relative_luminance(a), relative_luminance(b)), reverse=True)
    return (light + 0.05) / (dark + 0.05)


def css_colors(path: Path = APP_CSS) -> dict[str, str]:
    """The ``--name: #rrggbb;`` custom properties of a style sheet, by name (no dashes)."""
    return {name: value.lower() for name, value in _PROPERTY.findall(path.read_text("utf-8"))}
