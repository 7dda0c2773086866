"""Helpers of the retargeting tests (imported by name from the tests beside it)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from emotive.core import Motion, Skeleton
from emotive.core.ops import crop
from emotive.core.roles import resolve_roles
from emotive.features.contacts import leg_length
from emotive.io.bvh import read_bvh
from emotive.retarget import rest_template
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


def mixamo_cm_rig(prefix: str = "mixamorig:", spine2: bool = True) -> Skeleton:
    """A Mixamo-named rig without fingers, standing in a T-pose, with end sites that reach.

    The head's end site is 15 cm above it and the hands' 10 cm beyond the wrists (rigs
    exported from DCC tools end their limbs past the last joint, unlike the Bandai rig).

    Args:
        prefix: the joint names' namespace (``"mixamorig:"``, ``"mixamorig1:"``, ``""``).
        spine2: whether the rig has ``Spine2`` (older Mixamo rigs stop at ``Spine1``).
    """
    joints = [("Hips", None, (0, 95, 0)), ("Spine", "Hips", (0, 10, 0)),
              ("Spine1", "Spine", (0, 12, 0))]
    top = "Spine1"
    if spine2:
        joints.append(("Spine2", "Spine1", (0, 12, 0)))
        top = "Spine2"
    joints += [("Neck", top, (0, 15, 0)), ("Head", "Neck", (0, 10, 0))]
    for side, x in (("Left", 1), ("Right", -1)):
        joints += [(f"{side}Shoulder", top, (x * 5, 10, 0)),
                   (f"{side}Arm", f"{side}Shoulder", (x * 13, 0, 0)),
                   (f"{side}ForeArm", f"{side}Arm", (x * 28, 0, 0)),
                   (f"{side}Hand", f"{side}ForeArm", (x * 25, 0, 0))]
    for side, x in (("Left", 1), ("Right", -1)):
        joints += [(f"{side}UpLeg", "Hips", (x * 10, -5, 0)),
                   (f"{side}Leg", f"{side}UpLeg", (0, -43, 0)),
                   (f"{side}Foot", f"{side}Leg", (0, -42, 0)),
                   (f"{side}ToeBase", f"{side}Foot", (0, -7, 12))]
    names = [n for n, _, _ in joints]
    ends = {"Head": (0, 15, 0), "LeftHand": (10, 0, 0), "RightHand": (-10, 0, 0),
            "LeftToeBase": (0, 0, 8), "RightToeBase": (0, 0, 8)}
    rig = Skeleton(tuple(prefix + n for n in names),
                   [names.index(p) if p else -1 for _, p, _ in joints],
                   np.array([o for _, _, o in joints], dtype=float) / 100.0,
                   end_site_parents=[names.index(n) for n in ends],
                   end_site_offsets=np.array(list(ends.values()), dtype=float) / 100.0)
    return rest_template(rig, pose="t")
