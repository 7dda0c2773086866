"""Synthetic styled motion for the MAR tests, on the rig of ``tests/rigs.py`` (imported by name).

Two actions: ``walk`` (the root moves forward, legs and arms swing) and ``wave`` (standing,
the right arm waves overhead). Three styles differ in tempo, amplitude and posture:
``neutral``; ``proud`` (slower, larger arm swing, chest up, head back); ``sad`` (slower still,
small swing, head and chest down).
"""

from __future__ import annotations

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.models.mar.config import MARConfig
from emotive.models.mar.database import Example
from emotive.transforms.np_rotations import axis_angle_to_quaternion
from rigs import RIG

#: Per style: cycles per second, arm swing, leg swing, chest pitch, neck pitch.
STYLES = {
    "neutral": (1.0, 0.30, 0.30, 0.0, 0.0),
    "proud": (0.8, 0.60, 0.35, -0.25, -0.3),
    "sad": (0.65, 0.10, 0.20, 0.35, 0.5),
}
FPS = 30.0
#: A small config: few neighbours, a short window, few reduced dimensions.
CONFIG = MARConfig(k=8, timing_k=8, window=3, pca_dims=6, screen=32, max_classes=3,
                   candidates=3, datasets=("synthetic",), actions=("walk", "wave"))


def rig(rename: dict[str, str] | None = None, scale: float = 1.0) -> Skeleton:
    """The test rig, optionally with joints renamed and lengths scaled."""
    rename = rename or {}
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    return Skeleton(
        tuple(rename.get(r[0], r[0]) for r in RIG), np.array([r[1] for r in RIG]),
        np.array([r[2] for r in RIG], dtype=float) * scale,
        end_site_parents=[j for j, _ in ends],
        end_site_offsets=[np.array(o, dtype=float) * scale for _, o in ends],
    )


def styled(action: str, style: str, take: int = 0, frames: int | None = None,
           rename: dict[str, str] | None = None, scale: float = 1.0) -> Motion:
    """A clip of ``action`` in ``style``; takes differ in phase and amplitude slightly. By
    default every clip holds three cycles (so a slower style gives a longer clip), as a
    capture of one walk over a fixed distance would."""
    tempo, arm, leg, chest, neck = STYLES[style]
    frames = frames if frames is not None else cycle_frames(style)
    sk = rig(rename, scale)
    idx = {r[0]: j for j, r in enumerate(RIG)}
    t = np.arange(frames) / FPS
    phase = 2 * np.pi * tempo * t + 0.7 * take
    amp = 1.0 + 0.05 * take
    aa = np.zeros((frames, len(RIG), 3))
    if action == "walk":
        for s, sign in (("L", 1.0), ("R", -1.0)):
            aa[:, idx[f"UpperLeg_{s}"], 0] = -0.1 + sign * leg * amp * np.sin(phase)
            aa[:, idx[f"LowerLeg_{s}"], 0] = 0.3 + 0.2 * np.cos(phase + (sign > 0) * np.pi)
            aa[:, idx[f"UpperArm_{s}"], 0] = -sign * arm * amp * np.sin(phase)
            aa[:, idx[f"UpperArm_{s}"], 2] = sign * 0.15
            aa[:, idx[f"LowerArm_{s}"], 0] = -0.4 - 0.1 * np.sin(phase)
    else:
        aa[:, idx["UpperArm_R"], 2] = -2.4
        aa[:, idx["LowerArm_R"], 2] = -0.3 - arm * amp * np.sin(phase)
        aa[:, idx["UpperArm_L"], 2] = 0.15
        for s in ("L", "R"):
            aa[:, idx[f"LowerLeg_{s}"], 0] = 0.05
    aa[:, idx["Chest"], 0] = chest
    aa[:, idx["Neck"], 0] = neck
    aa[:, idx["Spine"], 1] = 0.05 * np.sin(phase)
    positions = np.broadcast_to(sk.offsets, (frames, len(RIG), 3)).copy()
    if action == "walk":
        positions[:, 0, 2] += 1.2 * tempo * t * scale
        positions[:, 0, 1] += 0.02 * np.cos(2 * phase) * scale
    return Motion(sk, axis_angle_to_quaternion(aa), positions, FPS,
                  {"name": f"synthetic_{action}_{style}_{take}", "file_unit": "cm"})


def cycle_frames(style: str, cycles: float = 3.0) -> int:
    """Frames of ``cycles`` cycles in a style."""
    return round(cycles * FPS / STYLES[style][0])


def examples(takes: int = 3, skip: tuple[str, ...] = ()) -> list[Example]:
    """Every action x style x take, minus the named clips."""
    out = []
    for action in ("walk", "wave"):
        for style in STYLES:
            for take in range(takes):
                motion = styled(action, style, take)
                if motion.metadata["name"] not in skip:
                    out.append(Example(motion, "synthetic", action, style,
                                       motion.metadata["name"]))
    return out
