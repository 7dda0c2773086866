"""What a crowd run keeps and writes: each body's motion, and trajectories in PedPy's layout.

Legend: ``T`` frames of one agent, ``J`` joints.

:class:`Recording` collects every :class:`~emotive.crowd.crowd.CrowdFrame` per agent (float32,
so hundreds of agents over a minute fit in memory) and turns each agent's frames into a
:class:`~emotive.core.motion.Motion` for the BVH writer.

:func:`write_trajectories` writes ``trajectories.csv`` as PedPy's text trajectory format
(``pedpy.load_trajectory_from_txt`` reads it directly): a ``# framerate: F`` header line, a
``# id frame x/m y/m`` line naming the columns and the unit, then one whitespace-separated row
per agent and frame: the agent id, the frame number, and the body's root on the ground in
metres (the scene's ``x, y``).
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.crowd.crowd import CrowdFrame
from emotive.io.atomic import atomic_output

__all__ = ["Recording", "trajectory_text", "write_trajectories"]


@dataclass
class _Track:
    first: int
    rotations: list[np.ndarray] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    root: list[np.ndarray] = field(default_factory=list)
    navigation: list[np.ndarray] = field(default_factory=list)
    emotion: list[np.ndarray] = field(default_factory=list)


class Recording:
    """Every agent's frames of a crowd run.

    Args:
        skeleton: the bodies' rig.
        fps: frame rate.
    """

    def __init__(self, skeleton: Skeleton, fps: float) -> None:
        self.skeleton = skeleton
        self.fps = float(fps)
        self.tracks: dict[int, _Track] = {}
        self.frames = 0

    def add(self, frame: CrowdFrame) -> None:
        """Keep one frame."""
        for k, a in enumerate(frame.agents):
            track = self.tracks.get(a)
            if track is None:
                track = self.tracks[a] = _Track(frame.index)
            track.rotations.append(frame.rotations[k].astype(np.float32))
            track.positions.append(frame.positions[k].astype(np.float32))
            track.root.append(frame.root[k].astype(np.float64))
            track.navigation.append(frame.navigation[k].astype(np.float64))
            track.emotion.append(frame.emotion[k].astype(np.float32))
        self.frames = frame.index + 1

    def motion(self, agent: int) -> Motion:
        """The agent's motion, from its first frame to its last."""
        t = self.tracks[agent]
        return Motion(self.skeleton, np.stack(t.rotations).astype(np.float64),
                      np.stack(t.positions).astype(np.float64), self.fps,
                      {"name": f"agent-{agent:04d}", "first_frame": t.first})

    def table(self) -> np.ndarray:
        """``(R, 4)`` rows ``id, frame, x, y`` sorted by frame then id."""
        rows = [np.column_stack((np.full(len(t.root), a), t.first + np.arange(len(t.root)),
                                 np.stack(t.root))) for a, t in self.tracks.items()]
        if not rows:
            return np.zeros((0, 4))
        out = np.vstack(rows)
        return out[np.lexsort((out[:, 0], out[:, 1]))]


def trajectory_text(table: np.ndarray, fps: float) -> str:
    """PedPy's text trajectory format of rows ``id, frame, x, y`` (see the module docstring)."""
    buf = io.StringIO()
    buf.write(f"# framerate: {fps:g}\n# id frame x/m y/m\n")
    for a, f, x, y in table:
        buf.write(f"{int(a)} {int(f)} {x:.4f} {y:.4f}\n")
    return buf.getvalue()


def write_trajectories(path: Path, table: np.ndarray, fps: float) -> Path:
    """Write ``trajectories.csv`` (atomically) and return its path."""
    with atomic_output(path) as tmp:
        tmp.write_text(trajectory_text(table, fps), encoding="utf-8")
    return path
