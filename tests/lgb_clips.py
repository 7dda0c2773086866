"""Synthetic emotion clips for the resampler tests (imported by name: ``tests/`` is on the path):
a small Bandai-named rig with clavicles and walk-like clips on it."""

from __future__ import annotations

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.data.clips import Clip, ClipInfo
from emotive.transforms.np_rotations import axis_angle_to_quaternion
from rigs import RIG


def clavicle_rig() -> Skeleton:
    """:data:`rigs.RIG` with a clavicle (``Shoulder_L``/``_R``) between the chest and each arm,
    as on the Bandai Namco rig."""
    rows = list(RIG)
    names = [r[0] for r in rows]
    out = []
    for name, parent, offset, end in rows:
        pname = names[parent] if parent >= 0 else None
        if name.startswith("UpperArm_"):
            side = name[-1]
            sign = 1.0 if side == "L" else -1.0
            out.append((f"Shoulder_{side}", "Chest", (sign * 0.06, 0.2, 0.0), None))
            out.append((name, f"Shoulder_{side}", (sign * 0.12, 0.0, 0.0), None))
        else:
            out.append((name, pname, offset, end))
    order = [r[0] for r in out]
    ends = [(j, r[3]) for j, r in enumerate(out) if r[3] is not None]
    return Skeleton(
        tuple(order),
        np.array([order.index(r[1]) if r[1] else -1 for r in out]),
        np.array([r[2] for r in out], dtype=float),
        end_site_parents=[j for j, _ in ends],
        end_site_offsets=[o for _, o in ends],
    )


def synthetic_motion(frames: int, seed: int, skeleton: Skeleton | None = None) -> Motion:
    """A walk-like clip: legs and arms swing at a clip-specific rate and amplitude, knees and
    elbows bend, the clavicles shrug, the spine twists, the root moves forward and turns."""
    sk = skeleton or clavicle_rig()
    rng = np.random.default_rng(seed)
    idx = {n: j for j, n in enumerate(sk.names)}
    t = np.arange(frames) / 30.0
    phase = 2 * np.pi * rng.uniform(0.6, 1.2) * t + rng.uniform(0, 2 * np.pi)
    amp = rng.uniform(0.6, 1.4)
    # A rig without clavicles moves the (absent) clavicle into a scratch row.
    idx.setdefault("Shoulder_L", len(sk.names))
    idx.setdefault("Shoulder_R", len(sk.names))
    aa = np.zeros((frames, len(sk.names) + 1, 3))
    for s, sign in (("L", 1.0), ("R", -1.0)):
        aa[:, idx[f"UpperLeg_{s}"], 0] = -0.2 + sign * 0.3 * amp * np.sin(phase)
        aa[:, idx[f"LowerLeg_{s}"], 0] = 0.4 + 0.2 * np.cos(phase)
        aa[:, idx[f"Foot_{s}"], 0] = -0.15
        aa[:, idx[f"Shoulder_{s}"], 2] = sign * 0.1 * np.sin(phase + 0.5)
        aa[:, idx[f"UpperArm_{s}"], 0] = -sign * 0.4 * amp * np.sin(phase)
        aa[:, idx[f"UpperArm_{s}"], 2] = sign * 0.15
        aa[:, idx[f"LowerArm_{s}"], 0] = -0.6 - 0.2 * amp * np.sin(phase)
    aa[:, idx["Spine"], 1] = 0.1 * np.sin(phase)
    aa[:, idx["Neck"], 0] = 0.1 + 0.05 * np.sin(2 * phase)
    aa[:, idx["Hips"], 1] = 0.2 * np.sin(0.3 * phase)
    rotations = axis_angle_to_quaternion(aa[:, : len(sk.names)])
    positions = np.broadcast_to(sk.offsets, (frames, len(sk.names), 3)).copy()
    positions[:, 0, 2] += rng.uniform(0.5, 1.2) * t
    positions[:, 0, 1] += 0.02 * np.cos(2 * phase)
    return Motion(sk, rotations, positions, 30.0, metadata={"file_unit": "cm"})


def synthetic_clip(frames: int = 160, seed: int = 0, style: str = "sad",
                   motion: Motion | None = None) -> Clip:
    """A labelled clip of :func:`synthetic_motion`."""
    name = f"dataset-1_walk_{style}_{seed + 1:03d}"
    info = ClipInfo("bandai-namco-1", name, name + ".bvh", "walk", style, seed + 1)
    return Clip(info, motion if motion is not None else synthetic_motion(frames, seed))
