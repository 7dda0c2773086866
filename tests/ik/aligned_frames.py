"""Re-express a clip with other joint frames, pose unchanged (imported by name in the tests).

Rigs from other studios differ from the Bandai rig not only in names and extra joints but in
their joint frames: a CMU or Mixamo rest pose has frames aligned with the world, the Bandai
rig's bones run along local X. :func:`world_aligned` turns a clip (any rig) into one whose
joint frames are the world's in a chosen frame, like a rig built in that pose, so that tests
cover rigs whose rest pose is not straight-limbed.
"""

from __future__ import annotations

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_invert,
    quaternion_multiply,
)


def world_aligned(motion: Motion, frame: int = 0) -> Motion:
    """The same clip on a rig whose joint frames are aligned with the world at ``frame``.

    Every joint's world position is unchanged; its world rotation becomes ``G_j G_j(frame)^-1``
    (the identity at ``frame``): local rotations ``D_p^-1 R_j D_j`` with ``D_j = G_j(frame)^-1``,
    offsets and translations ``D_p^-1 t_j``, end-site offsets ``D_j^-1 e``.
    """
    sk = motion.skeleton
    grot, _ = motion.global_transforms()
    turn = quaternion_invert(grot[frame])  # (J, 4): D_j
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    turn_parent = np.where(sk.parents[:, None] >= 0, turn[np.maximum(sk.parents, 0)], ident)
    undo = quaternion_invert(turn_parent)
    shape = motion.rotations.shape
    rotations = quaternion_multiply(quaternion_multiply(np.broadcast_to(undo, shape),
                                                        motion.rotations),
                                    np.broadcast_to(turn, shape))
    positions = quaternion_apply(np.broadcast_to(undo, shape), motion.positions)
    positions[:, sk.parents < 0] = motion.positions[:, sk.parents < 0]
    offsets = quaternion_apply(undo, sk.offsets)
    offsets[sk.parents < 0] = sk.offsets[sk.parents < 0]
    ends = quaternion_apply(quaternion_invert(turn[sk.end_site_parents]), sk.end_site_offsets)
    rig = Skeleton(sk.names, sk.parents, offsets, sk.channels, sk.end_site_parents, ends)
    return Motion(rig, rotations, positions, motion.fps, dict(motion.metadata))
