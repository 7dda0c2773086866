"""Helpers of the retargeting tests (imported by name from the tests beside it)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from emotive.core import Motion
from emotive.core.ops import crop
from emotive.core.roles import resolve_roles
from emotive.features.contacts import leg_length
from emotive.io.bvh import read_bvh
from emotive.retarget.rest import ROLE_PARENT


def walk(bandai1_dir: Path, style: str = "happy", seconds: float = 3.0) -> Motion:
    """The first ``seconds`` of a dataset-1 walk."""
    motion = read_bvh(bandai1_dir / "data" / f"dataset-1_walk_{style}_001.bvh")
    return crop(motion, 0, seconds, seconds=True)


def bone_angles(a: Motion, b: Motion) -> dict[str, float]:
    """Mean angle (degrees) between the role bones of two clips, by child role.

    Bones without length on either rig (Bandai's zero-length tips) are left out.
    """
    ra, rb = resolve_roles(a.skeleton), resolve_roles(b.skeleton)
    pa, pb = a.positions_with_end_sites(), b.positions_with_end_sites()
    out = {}
    for role, parent in ROLE_PARENT.items():
        da = pa[:, ra.index[role]] - pa[:, ra.index[parent]]
        db = pb[:, rb.index[role]] - pb[:, rb.index[parent]]
        na, nb = np.linalg.norm(da, axis=-1), np.linalg.norm(db, axis=-1)
        if na.min() < 1e-6 or nb.min() < 1e-6:
            continue
        cos = np.clip((da * db).sum(-1) / (na * nb), -1.0, 1.0)
        out[role] = float(np.degrees(np.arccos(cos)).mean())
    return out


def root_speed(motion: Motion) -> float:
    """Mean horizontal speed of the root role, m/s."""
    roles = resolve_roles(motion.skeleton)
    root = motion.positions_with_end_sites()[:, roles.index["root"]][:, [0, 2]]
    return float(np.linalg.norm(np.diff(root, axis=0), axis=-1).sum() / motion.duration)


def speed_per_leg(motion: Motion) -> float:
    """Root speed over leg length (leg lengths per second)."""
    legs = leg_length(motion.positions_with_end_sites(), resolve_roles(motion.skeleton))
    return root_speed(motion) / legs
