"""The root role as the one joint that carries a motion's world placement.

Legend: ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

from emotive.core.motion import Motion
from emotive.errors import RigError
from emotive.transforms.kinematics import forward_kinematics_np


def fold_into_root(motion: Motion, root: int) -> Motion:
    """The motion with the transforms of the root role's ancestors folded into the root role.

    The root role's local transform becomes its world transform and its ancestors stay at the
    identity, so that one joint (the *mover*) carries the whole world placement. Every joint
    from the root role down keeps its world position. On the Bandai rig the file root
    ``joint_Root`` sits at the origin in all but four short dataset-1 clips, where it carries
    the trajectory instead of the hips.

    Args:
        motion: rotations ``(T, J, 4)`` (``w, x, y, z``) and positions ``(T, J, 3)``
            (metres).
        root: index of the root role's joint.

    Returns:
        The motion with the same skeleton and new rotations and positions.

    Raises:
        RigError: an ancestor of the root role has another child, which folding would move.
    """
    sk = motion.skeleton
    chain, j = [], int(sk.parents[root])
    while j >= 0:
        chain.append(j)
        j = int(sk.parents[j])
    if not chain:
        return motion
    for a in chain:
        children = [k for k in range(sk.num_joints) if sk.parents[k] == a]
        if len(children) > 1 or a in sk.end_site_parents:
            raise RigError(f"joint {sk.names[a]} above the root role {sk.names[root]} has other "
                           "children; the model needs the root role's ancestors to carry "
                           "nothing else")
    grot, gpos = forward_kinematics_np(motion.rotations, motion.positions, list(sk.parents))
    rotations, positions = motion.rotations.copy(), motion.positions.copy()
    rotations[:, root], positions[:, root] = grot[:, root], gpos[:, root]
    rotations[:, chain] = (1.0, 0.0, 0.0, 0.0)
    positions[:, chain] = 0.0
    return motion.replace(rotations=rotations, positions=positions)
