"""Recordings of the live scene: every frame's poses kept, then written as BVH or glTF.

Between ``start_recording`` and ``stop_recording`` the simulation thread hands each frame to
:meth:`Recorder.capture`; a :class:`Recording` keeps each agent's local rotations and
translations as float32 (``28 J`` bytes per agent and frame), up to a length in seconds and a
size in MB (then it stops keeping frames and says so once). Each client runs one recording at
a time, the server at most :data:`MAX_RUNNING`; a client that leaves stops its recording; the
finished recordings kept are bounded in number and in bytes. A finished recording never
changes, so downloads read it from other threads; :func:`write_recording` builds the
agent's :class:`~emotive.core.motion.Motion` on the engine's rig and writes it with
:func:`~emotive.io.motion_files.write_motion`.

Legend: ``T`` frames, ``B`` agents in a frame, ``J`` joints.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton
from emotive.io.motion_files import write_motion
from emotive.serve.errors import MessageError

#: Download formats and their file suffixes.
FORMATS = {"bvh": ".bvh", "glb": ".glb"}
#: Recordings running at once, server-wide (each client may run one).
MAX_RUNNING = 4
#: Finished recordings kept hold at most this many times one recording's size limit.
KEPT_BUDGET = 4


@dataclass
class Recording:
    """The frames of one recording.

    Attributes:
        rid: its id.
        owner: the client that started it (its connection number).
        max_frames: frames it may hold.
        max_bytes: bytes it may hold.
        ids: per frame, ``(B,)`` agent ids.
        rotations: per frame, ``(B, J, 4)`` float32 local rotations.
        positions: per frame, ``(B, J, 3)`` float32 local translations.
        nbytes: bytes held.
        full: whether it reached a limit (and stopped keeping frames).
        stopped: whether it was stopped (then it never changes).
    """

    rid: int
    owner: int
    max_frames: int
    max_bytes: int
    ids: list[np.ndarray] = field(default_factory=list)
    rotations: list[np.ndarray] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    nbytes: int = 0
    full: bool = False
    stopped: bool = False

    @property
    def frames(self) -> int:
        """Frames held ``T``."""
        return len(self.ids)

    @property
    def agents(self) -> list[int]:
        """Ids of every agent seen, ascending."""
        return sorted({int(a) for ids in self.ids for a in ids})

    def append(self, ids: np.ndarray, rotations: np.ndarray, positions: np.ndarray) -> bool:
        """Keep one frame; ``False`` (and nothing kept) once a limit is reached."""
        size = rotations.size * 4 + positions.size * 4 + ids.size * 4
        if self.full or self.frames >= self.max_frames or self.nbytes + size > self.max_bytes:
            self.full = True
            return False
        self.ids.append(np.asarray(ids, dtype=np.int32))
        self.rotations.append(np.asarray(rotations, dtype=np.float32))
        self.positions.append(np.asarray(positions, dtype=np.float32))
        self.nbytes += size
        return True

    def motion(self, agent: int | None, skeleton: Skeleton, fps: float) -> Motion:
        """Agent ``agent``'s frames (default: the first agent seen) as a motion.

        Raises:
            MessageError: no frames, or an agent that was not in the recording.
        """
        agents = self.agents
        if not agents:
            raise MessageError(f"recording {self.rid} holds no agent frames: add agents and "
                               "record again")
        agent = agents[0] if agent is None else agent
        rows = [(k, int(np.flatnonzero(ids == agent)[0])) for k, ids in enumerate(self.ids)
                if np.any(ids == agent)]
        if not rows:
            raise MessageError(f"agent {agent} is not in recording {self.rid}; its agents: "
                               f"{agents}")
        rot = np.stack([self.rotations[k][i] for k, i in rows]).astype(np.float64)
        pos = np.stack([self.positions[k][i] for k, i in rows]).astype(np.float64)
        rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
        return Motion(skeleton, rot, pos, fps,
                      {"name": f"recording{self.rid}_agent{agent}", "source": "emotive serve"})


class Recorder:
    """The server's recordings: the running ones (fed by the simulation thread) and the kept.

    Args:
        max_frames: frames one recording may hold.
        max_bytes: bytes one recording may hold.
        kept: finished recordings kept (the oldest go first).
    """

    def __init__(self, max_frames: int, max_bytes: int, kept: int) -> None:
        self.max_frames = int(max_frames)
        self.max_bytes = int(max_bytes)
        self.kept = int(kept)
        self._lock = threading.Lock()
        self._next = 0
        self._running: dict[int, Recording] = {}
        self._done: OrderedDict[int, Recording] = OrderedDict()

    @property
    def running(self) -> bool:
        """Whether any recording is running."""
        return bool(self._running)

    def start(self, owner: int) -> Recording:
        """Start a recording for client ``owner``.

        Raises:
            MessageError: ``owner`` already runs one, or :data:`MAX_RUNNING` are running.
        """
        with self._lock:
            mine = [r.rid for r in self._running.values() if r.owner == owner]
            if mine:
                raise MessageError(f"your recording {mine[0]} is running: send stop_recording "
                                   "before starting another")
            if len(self._running) >= MAX_RUNNING:
                raise MessageError(f"{MAX_RUNNING} recordings are running, the server's limit: "
                                   "try again when one stops")
            rec = Recording(self._next, owner, self.max_frames, self.max_bytes)
            self._next += 1
            self._running[rec.rid] = rec
        return rec

    def stop(self, owner: int, rid: int | None) -> Recording:
        """Stop recording ``rid`` (default: ``owner``'s latest running one).

        Raises:
            MessageError: no such running recording.
        """
        with self._lock:
            if rid is None:
                mine = [r for r in self._running if self._running[r].owner == owner]
                if not mine:
                    raise MessageError("no recording of yours is running: send "
                                       '{"type": "start_recording"} first')
                rid = mine[-1]
            if rid not in self._running:
                raise MessageError(f"recording {rid} is not running; running: "
                                   f"{sorted(self._running)}")
            rec = self._running.pop(rid)
            rec.stopped = True
            self._done[rid] = rec
            while len(self._done) > self.kept or (
                    len(self._done) > 1
                    and sum(r.nbytes for r in self._done.values())
                    > KEPT_BUDGET * self.max_bytes):
                self._done.popitem(last=False)
        return rec

    def release(self, owner: int) -> None:
        """Stop the recordings of a client that left (they stay downloadable)."""
        for rid in [r.rid for r in self._running.values() if r.owner == owner]:
            self.stop(owner, rid)

    def capture(self, ids: np.ndarray, rotations: np.ndarray, positions: np.ndarray
                ) -> list[Recording]:
        """Keep a frame in every running recording; returns those that just became full."""
        filled = []
        for rec in list(self._running.values()):
            if not rec.full and not rec.append(ids, rotations, positions):
                filled.append(rec)
        return filled

    def finished(self, rid: int) -> Recording:
        """A finished recording.

        Raises:
            KeyError: not a finished recording (the message says whether it still runs).
        """
        with self._lock:
            if rid in self._done:
                return self._done[rid]
            if rid in self._running:
                raise KeyError(f"recording {rid} is still running: send stop_recording first")
        raise KeyError(f"no recording {rid}; kept recordings: {sorted(self._done)}")


def write_recording(rec: Recording, agent: int | None, fmt: str, skeleton: Skeleton,
                    fps: float, folder: Path) -> Path:
    """Write agent ``agent`` of a recording as ``fmt`` (``"bvh"`` or ``"glb"``) in ``folder``.

    Raises:
        MessageError: an unknown format, or an agent not in the recording.
    """
    if fmt not in FORMATS:
        raise MessageError(f"format {fmt!r} is unknown; use {' or '.join(FORMATS)}")
    motion = rec.motion(agent, skeleton, fps)
    return write_motion(motion, folder / f"{motion.metadata['name']}{FORMATS[fmt]}")
