"""Synthetic rigs for the IK tests: a two-link leg and a small Bandai-named humanoid."""

from __future__ import annotations

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.core.roles import JointRoles
from emotive.ik import ChainSpec, JointSpec, build_chain
from emotive.transforms.np_rotations import axis_angle_to_quaternion


def two_link(hip_swing: float = 120.0):
    """A hip (ball) and knee (hinge about local Z, 0..150 degrees) of 0.5 m links, on a base
    at the origin; the target is the ankle. Returns ``(chain, skeleton)``."""
    sk = Skeleton(
        ("Base", "Hip", "Knee", "Ankle"), [-1, 0, 1, 2],
        [[0, 0, 0], [0, 0, 0], [0, -0.5, 0], [0, -0.5, 0]],
    )
    spec = ChainSpec(
        "test_leg",
        (
            JointSpec(
                "l_hip", "ball", (-60.0, -hip_swing, -hip_swing), (60.0, hip_swing, hip_swing)
            ),
            JointSpec("l_knee", "hinge", (0.0, 0.0, 0.0), (150.0, 0.0, 0.0)),
        ),
        (("l_ankle", 1.0),),
        "root",
    )
    roles = JointRoles({"root": 0, "l_hip": 1, "l_knee": 2, "l_ankle": 3}, {}, "test")
    return build_chain(sk, spec, roles), sk


def solve_inputs(chain, targets: np.ndarray):
    """Base transforms, local positions and target offsets of :func:`two_link` for T frames."""
    t = len(targets)
    base_rot = np.tile([1.0, 0, 0, 0], (t, 1))
    base_pos = np.zeros((t, 3))
    local_pos = np.tile([[0.0, 0, 0], [0, -0.5, 0]], (t, 1, 1))
    offsets = np.tile([[0.0, -0.5, 0]], (t, 1, 1))
    return base_rot, base_pos, local_pos, offsets


def _side(names: list, parents: list, offsets: list, side: str, sign: float, chest: int, hips: int):
    s = side
    base = len(names)
    names += [f"Shoulder_{s}", f"UpperArm_{s}", f"LowerArm_{s}", f"Hand_{s}"]
    parents += [chest, base, base + 1, base + 2]
    offsets += [
        [sign * 0.05, 0.18, 0], [sign * 0.12, 0, 0], [sign * 0.28, 0, 0], [sign * 0.25, 0, 0]
    ]
    leg = len(names)
    names += [f"UpperLeg_{s}", f"LowerLeg_{s}", f"Foot_{s}", f"Toes_{s}"]
    parents += [hips, leg, leg + 1, leg + 2]
    offsets += [[sign * 0.1, -0.05, 0], [0, -0.42, 0], [0, -0.42, 0], [0, -0.05, 0.12]]


def make_humanoid(frames: int = 60, speed: float = 0.3, fps: float = 30.0) -> Motion:
    """A Bandai-named humanoid (Y up, facing +Z) walking forward at ``speed`` m/s with its legs
    swinging slowly, so planted feet would slide."""
    names = ["Hips", "Spine", "Chest", "Neck", "Head"]
    parents = [-1, 0, 1, 2, 3]
    offsets = [[0, 0.9, 0], [0, 0.1, 0], [0, 0.15, 0], [0, 0.2, 0], [0, 0.1, 0]]
    _side(names, parents, offsets, "L", 1.0, 2, 0)
    _side(names, parents, offsets, "R", -1.0, 2, 0)
    idx = {n: i for i, n in enumerate(names)}
    ends = [idx["Head"], idx["Hand_L"], idx["Hand_R"], idx["Toes_L"], idx["Toes_R"]]
    end_off = [[0, 0.1, 0], [0.08, 0, 0], [-0.08, 0, 0], [0, 0, 0.05], [0, 0, 0.05]]
    sk = Skeleton(tuple(names), parents, offsets, (), ends, end_off)
    t = np.arange(frames) / fps
    aa = np.zeros((frames, len(names), 3))
    phase = 2 * np.pi * 0.5 * t
    for s, sign in (("L", 1.0), ("R", -1.0)):
        aa[:, idx[f"UpperLeg_{s}"], 0] = -0.25 + sign * 0.1 * np.sin(phase)
        aa[:, idx[f"LowerLeg_{s}"], 0] = 0.45 + 0.05 * np.cos(phase)
        aa[:, idx[f"Foot_{s}"], 0] = -0.2
        aa[:, idx[f"UpperArm_{s}"], 2] = -sign * 1.2
        aa[:, idx[f"LowerArm_{s}"], 1] = sign * (0.5 + 0.1 * np.sin(phase))
    aa[:, idx["Spine"], 1] = 0.1 * np.sin(phase)
    aa[:, idx["Neck"], 0] = 0.1
    rot = axis_angle_to_quaternion(aa)
    pos = np.broadcast_to(np.asarray(offsets, dtype=np.float64), (frames, len(names), 3)).copy()
    pos[:, 0, 2] += speed * t
    return Motion(sk, rot, pos, fps)
