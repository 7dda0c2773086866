"""Tests that need an outside tool (Blender, node packages, Chromium, Playwright)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

#: Run inside Blender: import a BVH (metres) and export it as FBX (``-- IN.bvh OUT.fbx``),
#: every frame baked (no key reduction) and the leaf bones FBX tools add at chain ends.
BVH_TO_FBX = """
import builtins, sys, bpy
_open = builtins.open
# Blender 3.4's BVH importer opens files with mode "rU", which Python 3.11 removed.
builtins.open = lambda f, mode="r", *a, **k: _open(f, mode.replace("U", ""), *a, **k)
src, dst = sys.argv[sys.argv.index("--") + 1:][:2]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=src, update_scene_fps=True, update_scene_duration=True)
bpy.ops.export_scene.fbx(filepath=dst, bake_anim=True, add_leaf_bones=True,
                         bake_anim_simplify_factor=0.0)
"""


def require_tool(tool_ok: bool, reason: str) -> None:
    """Skip unless ``tool_ok``, or fail when CI demands the tools (``EMOTIVE_REQUIRE_TOOLS=1``)."""
    if not tool_ok:
        if os.environ.get("EMOTIVE_REQUIRE_TOOLS") == "1":
            pytest.fail(f"EMOTIVE_REQUIRE_TOOLS=1 but {reason}")
        pytest.skip(reason)


def bvh_to_fbx(blender: str, bvh: Path, fbx: Path) -> None:
    """Make ``fbx`` from ``bvh`` with a headless Blender (:data:`BVH_TO_FBX`)."""
    run = subprocess.run([blender, "-b", "--factory-startup", "--python-exit-code", "1",
                          "--python-expr", BVH_TO_FBX, "--", str(bvh), str(fbx)],
                         capture_output=True, text=True, timeout=300, check=False)
    assert run.returncode == 0 and fbx.is_file(), run.stdout[-2000:] + run.stderr[-2000:]


#: Flags that give headless Chromium a software WebGL 2 (SwiftShader through ANGLE).
CHROMIUM_FLAGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--ignore-gpu-blocklist")


def headless_chromium(timeout_s: float):
    """Debian's Chromium, headless, driven by Playwright's bundled driver (a generator for a
    module-scoped fixture: it yields the browser and closes it after).

    Skips naming what to install when Playwright or Chromium is missing (a failure under
    ``EMOTIVE_REQUIRE_TOOLS=1``).
    """
    import shutil

    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        require_tool(False, "Playwright is not installed (pip install playwright; its bundled "
                     "driver is enough, no browser download)")
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    require_tool(exe is not None, "Chromium is not installed (apt-get install chromium)")
    with sync_playwright() as pw:
        chromium = pw.chromium.launch(executable_path=exe, args=list(CHROMIUM_FLAGS),
                                      timeout=timeout_s * 1000)
        yield chromium
        chromium.close()
