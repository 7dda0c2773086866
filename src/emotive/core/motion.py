"""A motion clip: a skeleton animated by local rotations and translations at a frame rate."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from emotive.core.skeleton import Skeleton
from emotive.errors import EmotiveError
from emotive.transforms.kinematics import forward_kinematics_np
from emotive.transforms.np_rotations import quaternion_apply


@dataclass(frozen=True, eq=False)
class Motion:
    """Local joint transforms over time.

    Attributes:
        skeleton: the rig.
        rotations: ``(T, J, 4)`` local unit quaternions ``w, x, y, z``.
        positions: ``(T, J, 3)`` local translations in metres. Joints whose file does not animate
            translation hold their rest offset in every frame; the root joint's entry is its
            position in the world.
        fps: frames per second.
        metadata: free-form facts about the clip (``name``, ``source``, ``content``, ``style``,
            ``file_unit``, ...). Never used by the math.
    """

    skeleton: Skeleton
    rotations: np.ndarray
    positions: np.ndarray
    fps: float
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        rot = np.asarray(self.rotations, dtype=np.float64)
        pos = np.asarray(self.positions, dtype=np.float64)
        n = self.skeleton.num_joints
        if rot.ndim != 3 or rot.shape[1:] != (n, 4):
            raise EmotiveError(f"rotations must have shape (T, {n}, 4), got {rot.shape}")
        if pos.shape != (rot.shape[0], n, 3):
            raise EmotiveError(
                f"positions must have shape ({rot.shape[0]}, {n}, 3), got {pos.shape}"
            )
        if not self.fps > 0:
            raise EmotiveError(f"fps must be positive, got {self.fps}")
        object.__setattr__(self, "rotations", rot)
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "fps", float(self.fps))

    @property
    def num_frames(self) -> int:
        """Number of frames ``T``."""
        return self.rotations.shape[0]

    @property
    def duration(self) -> float:
        """Length in seconds (``T / fps``)."""
        return self.num_frames / self.fps

    @property
    def root_positions(self) -> np.ndarray:
        """``(T, 3)`` translation of the file's root joint."""
        return self.positions[:, 0]

    def replace(self, **changes: Any) -> Motion:
        """A copy with some fields replaced (``rotations=...``, ``fps=...``)."""
        return replace(self, **changes)

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotations ``(T, J, 4)`` and positions ``(T, J, 3)`` by forward kinematics."""
        return forward_kinematics_np(self.rotations, self.positions, self.skeleton.parents)

    def global_positions(self) -> np.ndarray:
        """``(T, J, 3)`` world joint positions in metres."""
        return self.global_transforms()[1]

    def positions_with_end_sites(self) -> np.ndarray:
        """``(T, J + E, 3)`` world positions of the joints followed by the end sites."""
        grot, gpos = self.global_transforms()
        sk = self.skeleton
        p = sk.end_site_parents
        offsets = np.broadcast_to(sk.end_site_offsets, (self.num_frames, len(p), 3))
        ends = quaternion_apply(grot[:, p], offsets) + gpos[:, p]
        return np.concatenate((gpos, ends), axis=1)
