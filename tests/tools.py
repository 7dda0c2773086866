"""Tests that need an outside tool (Blender, node packages, Chromium, Playwright)."""

from __future__ import annotations

import os

import pytest


def require_tool(tool_ok: bool, reason: str) -> None:
    """Skip unless ``tool_ok``, or fail when CI demands the tools (``EMOTIVE_REQUIRE_TOOLS=1``)."""
    if not tool_ok:
        if os.environ.get("EMOTIVE_REQUIRE_TOOLS") == "1":
            pytest.fail(f"EMOTIVE_REQUIRE_TOOLS=1 but {reason}")
        pytest.skip(reason)
