"""Feature rows of end-effector trajectories: the chain layout, chain anchors and clip features.

Issue 7, section 2, step 1 (paper section 5.2). Every clip's pelvis path and chain targets (end
effectors, elbows, shoulders, neck) are extracted in their chain frames
(:func:`emotive.ik.extract_trajectories`) and laid out as one ``(T, F)`` feature row per frame
(:func:`clip_features`), with two kinds of bookkeeping columns: each chain's *anchor* (its first
joint in the chain's frame, :func:`chain_anchors`) and the local rotations of the *link* joints
between a chain's frame and its first joint (the clavicles between the chest and the arms,
:func:`chain_links`), which no chain drives.

Legend: ``T`` frames, ``F`` features per frame, ``L`` link joints of a chain, ``P`` effector
points.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.core.motion import Motion
from emotive.ik import extract_trajectories, to_frame
from emotive.models.lgb.novelty import EFFECTORS

if TYPE_CHECKING:
    from emotive.ik import Chain

__all__ = [
    "Column",
    "chain_anchors",
    "chain_links",
    "clip_features",
    "effector_columns",
    "feature_layout",
    "layout_columns",
]


@dataclass(frozen=True)
class Column:
    """Columns of one named block of the ``(T, F)`` feature layout."""

    start: int
    width: int

    @property
    def slice(self) -> slice:
        """The block's columns as a slice."""
        return slice(self.start, self.start + self.width)


def chain_links(chain: Chain, parents: np.ndarray) -> np.ndarray:
    """``(L,)`` joints strictly between a chain's frame joint and its first joint.

    Nearest the frame first (the clavicle of an arm); empty when the frame is the first joint's
    parent or not its ancestor.
    """
    out, j = [], int(parents[chain.joints[0]])
    while j >= 0 and j != chain.frame:
        out.append(j)
        j = int(parents[j])
    return np.array(out[::-1] if j == chain.frame else [], dtype=np.int64)


def feature_layout(chains: dict[str, Chain], parents: np.ndarray) -> dict[str, Column]:
    """Feature blocks of the process's state columns.

    Feature blocks: ``chain:role`` targets (3 columns each), ``anchor:chain`` (3 each),
    ``link:chain`` (4 per link joint, chains with links only), then the pelvis path.
    """
    blocks: list[tuple[str, int]] = [
        (f"{name}:{role}", 3) for name, c in chains.items() for role in c.target_roles
    ]
    blocks += [(f"anchor:{name}", 3) for name in chains]
    blocks += [(f"link:{name}", 4 * len(chain_links(c, parents))) for name, c in chains.items()
               if len(chain_links(c, parents))]
    blocks += [("pelvis:height", 1), ("pelvis:step", 2), ("pelvis:turn", 1), ("pelvis:tilt", 4)]
    out, start = {}, 0
    for name, width in blocks:
        out[name] = Column(start, width)
        start += width
    return out


def layout_columns(layout: dict[str, Column], blocks: Sequence[str]) -> np.ndarray:
    """Columns of the blocks of ``layout`` among ``blocks``."""
    return np.concatenate([np.arange(layout[b].start, layout[b].start + layout[b].width)
                           for b in blocks if b in layout])


def chain_anchors(motion: Motion, chains: dict[str, Chain]) -> dict[str, np.ndarray]:
    """Chain name -> ``(T, 3)`` position of the chain's first joint in the chain's frame.

    For the arms it moves with the clavicle:
    :meth:`~emotive.models.lgb.resampler.EmotionResampler.trajectories` moves each
    arm's sampled targets with the difference between the rebuilt anchor and the sampled one,
    so that they keep their sampled place relative to the shoulder.
    """
    grot, gpos = motion.global_transforms()
    return {
        name: to_frame(gpos[:, c.joints[:1]], grot[:, c.frame], gpos[:, c.frame])[:, 0]
        for name, c in chains.items()
    }


def _hemisphere(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(..., 4)`` with ``w >= 0`` (one sign, so that blends stay short)."""
    return np.where(q[..., :1] < 0, -q, q)


def clip_features(
    motion: Motion, chains: dict[str, Chain], layout: dict[str, Column], role_map: Any = None
) -> np.ndarray:
    """``(T, F)`` feature rows of a clip (see :func:`feature_layout`)."""
    traj = extract_trajectories(motion, chains, role_map)
    n = len(traj.pelvis.height)
    anchors = chain_anchors(motion, chains)
    out = np.empty((n, sum(c.width for c in layout.values())))
    pelvis = {"height": traj.pelvis.height, "step": traj.pelvis.displacement,
              "turn": traj.pelvis.turn, "tilt": _hemisphere(traj.pelvis.tilt)}
    for key, col in layout.items():
        group, role = key.split(":")
        if group == "pelvis":
            out[:, col.slice] = np.reshape(pelvis[role], (n, -1))
        elif group == "anchor":
            out[:, col.slice] = anchors[role]
        elif group == "link":
            links = chain_links(chains[role], motion.skeleton.parents)
            out[:, col.slice] = _hemisphere(motion.rotations[:, links]).reshape(n, -1)
        else:
            targets = traj.targets[group]
            out[:, col.slice] = targets[:, chains[group].target_roles.index(role)]
    return out


def effector_columns(layout: dict[str, Column]) -> np.ndarray:
    """Feature columns of the not-a-replay effector points (:data:`EFFECTORS`), ``(3P,)``."""
    return layout_columns(layout, EFFECTORS)
