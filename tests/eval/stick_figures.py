"""Synthetic stick figures for the metric tests: every joint role, standing or walking."""

from __future__ import annotations

import numpy as np

from emotive.core.roles import ROLES, JointRoles
from emotive.transforms.np_rotations import quaternion_normalize

FPS = 30.0
ROLE_MAP = JointRoles({r: k for k, r in enumerate(ROLES)}, {r: r for r in ROLES}, "test")
IDX = ROLE_MAP.index

# (forward, up, left) offsets of every role from the root's ground point, standing.
_BODY = {
    "root": (0, 0.95, 0), "spine": (0, 1.05, 0), "chest": (0, 1.25, 0), "neck": (0, 1.5, 0),
    "head": (0, 1.6, 0),
    "l_shoulder": (0, 1.45, 0.18), "r_shoulder": (0, 1.45, -0.18),
    "l_elbow": (0, 1.17, 0.18), "r_elbow": (0, 1.17, -0.18),
    "l_wrist": (0, 0.92, 0.18), "r_wrist": (0, 0.92, -0.18),
    "l_handtip": (0, 0.84, 0.18), "r_handtip": (0, 0.84, -0.18),
    "l_hip": (0, 0.95, 0.1), "r_hip": (0, 0.95, -0.1),
    "l_knee": (0.02, 0.5, 0.1), "r_knee": (0.02, 0.5, -0.1),
    "l_ankle": (0, 0.08, 0.1), "r_ankle": (0, 0.08, -0.1),
    "l_toe": (0.15, 0.02, 0.1), "r_toe": (0.15, 0.02, -0.1),
}


def figure(root_xz: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``(T, R, 3)`` stick figure in :data:`ROLES` order, standing over ``(T, 2)`` ground points
    and facing ``(T,)`` headings (radians from +Z towards +X)."""
    fwd = np.stack((np.sin(heading), np.zeros_like(heading), np.cos(heading)), -1)
    left = np.stack((np.cos(heading), np.zeros_like(heading), -np.sin(heading)), -1)
    up = np.array([0.0, 1.0, 0.0])
    off = np.array([_BODY[r] for r in ROLES], dtype=np.float64)
    base = np.stack((root_xz[:, 0], np.zeros(len(root_xz)), root_xz[:, 1]), -1)
    return (base[:, None] + off[:, 0, None] * fwd[:, None] + off[:, 1, None] * up
            + off[:, 2, None] * left[:, None])


def standing(frames: int = 30) -> np.ndarray:
    return figure(np.zeros((frames, 2)), np.zeros(frames))


def unit_quaternions(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return quaternion_normalize(rng.normal(size=(*shape, 4)))
