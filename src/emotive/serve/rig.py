"""World positions of a frame's agents from their local rotations and the rig.

Version-2 frames (:mod:`~emotive.serve.frames`) carry each agent's local rotations and the
world position of its mover joint, not the world positions of its joints: a client computes
them by forward kinematics over the rig of ``GET /api/skeleton``. The joints above the mover
(a placement root) hang from the origin by their rig offsets; the mover sits at its world
position; every joint below hangs from its parent by its offset, turned by the parent's
global rotation; end sites likewise by their offsets. ``static/rig.js`` is the browser's copy
of the same computation.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``P = J + E`` points.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from emotive.transforms.fast_np import qapply, qmul
from emotive.transforms.kinematics import depth_levels


class FrameRig:
    """The rig of a scene's frames, for their world positions.

    Args:
        parents: ``J`` parent indices in topological order (root ``-1``).
        offsets: ``(J, 3)`` local translations, metres (the mover's is not used).
        mover: the joint whose world position each frame carries.
        end_site_parents: ``E`` joints the end sites hang from.
        end_site_offsets: ``(E, 3)`` end-site offsets, metres (``None``: zeros).

    Raises:
        ValueError: shapes that disagree, or parents out of topological order.
    """

    def __init__(self, parents: Sequence[int], offsets: np.ndarray, mover: int,
                 end_site_parents: Sequence[int] = (),
                 end_site_offsets: np.ndarray | None = None) -> None:
        self.parents = np.asarray(parents, dtype=np.intp)
        self.offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
        self.mover = int(mover)
        self.end_parents = np.asarray(end_site_parents, dtype=np.intp)
        ends = (np.zeros((len(self.end_parents), 3)) if end_site_offsets is None
                else end_site_offsets)
        self.end_offsets = np.asarray(ends, dtype=np.float64).reshape(-1, 3)
        if (len(self.offsets) != len(self.parents)
                or len(self.end_offsets) != len(self.end_parents)):
            raise ValueError(f"a rig of {len(self.parents)} joints and {len(self.end_parents)} "
                             f"end sites needs offsets of those lengths, got "
                             f"{len(self.offsets)} and {len(self.end_offsets)}")
        if not 0 <= self.mover < len(self.parents):
            raise ValueError(f"mover {mover} is not a joint of a rig of {len(self.parents)}")
        self.levels = [np.asarray(level, dtype=np.intp) for level in depth_levels(parents)]

    @classmethod
    def from_info(cls, info: Mapping[str, Any]) -> FrameRig:
        """The rig of a ``GET /api/skeleton`` answer (parsed JSON)."""
        return cls(info["parents"], np.asarray(info["offsets"]), info["mover"],
                   info.get("end_site_parents", ()),
                   np.asarray(info["end_site_offsets"]) if "end_site_offsets" in info else None)

    @property
    def num_points(self) -> int:
        """``P``: joints then end sites."""
        return len(self.parents) + len(self.end_parents)

    def world(self, rotations: np.ndarray, mover: np.ndarray) -> np.ndarray:
        """``(B, P, 3)`` world positions of joints then end sites, metres.

        Args:
            rotations: ``(B, J, 4)`` local rotations ``(w, x, y, z)``, unit length.
            mover: ``(B, 3)`` world position of the mover joint, metres.

        Raises:
            ValueError: shapes that do not fit the rig.
        """
        rotations = np.asarray(rotations, dtype=np.float64)
        mover = np.asarray(mover, dtype=np.float64)
        b, j = rotations.shape[0], len(self.parents)
        if rotations.shape != (b, j, 4) or mover.shape != (b, 3):
            raise ValueError(f"rotations (B, {j}, 4) and mover positions (B, 3) expected, got "
                             f"{rotations.shape} and {mover.shape}")
        # Joints first: each tree level reads and writes whole (B, ...) blocks.
        local = np.swapaxes(rotations, 0, 1)
        glob = np.empty_like(local)
        points = np.empty((self.num_points, b, 3))
        for level in self.levels:
            parents = self.parents[level]
            if parents[0] < 0:
                glob[level] = local[level]
                points[level] = self.offsets[level][:, None]
            else:
                glob[level] = qmul(glob[parents], local[level])
                points[level] = (qapply(glob[parents], self.offsets[level][:, None])
                                 + points[parents])
            if self.mover in level:
                points[self.mover] = mover
        if len(self.end_parents):
            ends = self.end_parents
            points[j:] = qapply(glob[ends], self.end_offsets[:, None]) + points[ends]
        return np.swapaxes(points, 0, 1)
