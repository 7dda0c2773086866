"""Fixtures of the feature tests: real walk clips and synthetic stick-figure walks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from emotive.core.roles import ROLES, JointRoles


@pytest.fixture(scope="session")
def walk_dir(bandai1_dir: Path) -> Path:
    """The ``data`` folder of Bandai Namco dataset 1 (skips, or fails under
    ``EMOTIVE_REQUIRE_DATA=1``, when the data is missing)."""
    return bandai1_dir / "data"


def _ease(s: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero slope at both ends."""
    return 0.5 - 0.5 * np.cos(np.pi * s)


def make_stick_walk(
    frames: int = 150,
    fps: float = 30.0,
    step_hz: float = 2.0,
    speed: float = 1.2,
    heading: float = 0.0,
    duty: float = 0.6,
    scale: float = 1.0,
) -> tuple[np.ndarray, JointRoles, dict[str, np.ndarray]]:
    """A stick figure walking straight at ``speed`` m/s with ``step_hz`` steps per second.

    Left strikes at ``t = k / (step_hz / 2)``, right strikes half a cycle later; each foot is
    planted (heel 8 cm and toe 2 cm above ground, fixed) for ``duty`` of the cycle and swings
    along a 10 cm arc otherwise. ``heading`` is the walking direction in radians from +Z
    towards +X; the body faces it.

    Returns:
        ``(T, R, 3)`` positions in :data:`emotive.core.roles.ROLES` order (times ``scale``),
        the roles, and the truth: ``strikes`` ``(T, 2)`` bool and ``planted`` ``(T, 2)`` bool.
    """
    t = np.arange(frames) / fps
    cycle = 2.0 / step_hz
    stride = speed * cycle
    fwd = np.array([np.sin(heading), 0.0, np.cos(heading)])
    left = np.array([fwd[2], 0.0, -fwd[0]])
    up = np.array([0.0, 1.0, 0.0])
    root_s = speed * t
    pos: dict[str, np.ndarray] = {}
    strikes = np.zeros((frames, 2), dtype=bool)
    planted = np.zeros((frames, 2), dtype=bool)
    for foot, (side, offset) in enumerate((("l", 0.0), ("r", 0.5))):
        u = t / cycle - offset  # cycle position of this foot; strike at integer u
        k = np.floor(u)
        s = u - k
        # Planted mid-stance under the root: strike k lands at the root's place then.
        land = speed * (k + offset) * cycle + 0.5 * duty * stride
        swing = np.clip((s - duty) / (1 - duty), 0, 1)
        along = land + stride * _ease(swing)
        lift = 0.10 * np.sin(np.pi * swing)
        sign = 1.0 if side == "l" else -1.0
        base = along[:, None] * fwd + 0.1 * sign * left
        pos[f"{side}_ankle"] = base + (0.08 + lift)[:, None] * up
        pos[f"{side}_toe"] = base + 0.15 * fwd + (0.02 + lift)[:, None] * up
        pos[f"{side}_hip"] = root_s[:, None] * fwd + 0.1 * sign * left + 0.95 * up
        pos[f"{side}_knee"] = 0.5 * (pos[f"{side}_hip"] + pos[f"{side}_ankle"]) + 0.02 * fwd
        pos[f"{side}_shoulder"] = root_s[:, None] * fwd + 0.18 * sign * left + 1.45 * up
        pos[f"{side}_elbow"] = pos[f"{side}_shoulder"] - 0.28 * up
        pos[f"{side}_wrist"] = pos[f"{side}_elbow"] - 0.25 * up
        pos[f"{side}_handtip"] = pos[f"{side}_wrist"] - 0.08 * up
        planted[:, foot] = s < duty
        strike_frames = np.flatnonzero(np.diff(k) > 0) + 1
        strikes[strike_frames, foot] = True
    for role, height in (("root", 0.95), ("spine", 1.05), ("chest", 1.25), ("neck", 1.5),
                         ("head", 1.6)):
        pos[role] = root_s[:, None] * fwd + height * up
    positions = np.stack([pos[r] for r in ROLES], 1) * scale
    roles = JointRoles({r: k for k, r in enumerate(ROLES)}, {r: r for r in ROLES}, "stick")
    return positions, roles, {"strikes": strikes, "planted": planted}


@pytest.fixture
def stick_walk():
    """Factory of :func:`make_stick_walk` synthetic walks."""
    return make_stick_walk
