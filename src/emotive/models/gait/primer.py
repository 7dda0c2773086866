"""A primer clip as the gait network's inputs: the frames an agent starts from.

Shared by the generator (:class:`~emotive.models.gait.generate.GaitGenerator`), the Table 1
predictors and the QuaterNet baseline, which all run a primer through their network first.

Legend: ``T`` frames.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.errors import RigError
from emotive.models.gait.data import canonical_frames, clip_features


def primer_features(primer: Motion, controls: Any) -> dict[str, np.ndarray]:
    """Per-frame network inputs of a primer clip, as in training, at the model's rate.

    Args:
        primer: a clip on the model's rig (same joint names and hierarchy).
        controls: the model's :class:`~emotive.models.gait.controls.GaitControls`.

    Returns:
        :func:`~emotive.models.gait.data.clip_features` of the clip resampled to
        ``controls.fps``, with ``rotations`` made heading-canonical per frame (the mover in the
        standing pose's hemisphere); ``T >= 2`` frames.

    Raises:
        RigError: not a motion, another rig, or fewer than two frames.
    """
    sk = controls.skeleton
    if not isinstance(primer, Motion):
        raise RigError(f"a primer must be a Motion, got {type(primer).__name__}")
    if primer.skeleton.names != sk.names or not np.array_equal(primer.skeleton.parents,
                                                               sk.parents):
        raise RigError(
            f"primer {primer.metadata.get('name', '')!r} is on another rig "
            f"({primer.skeleton.num_joints} joints) than the model's ({sk.num_joints} "
            "joints of the Bandai Namco rig): give a clip of the training rig"
        )
    if abs(primer.fps - controls.fps) > 1e-6 * controls.fps:
        primer = resample(primer, controls.fps)
    if primer.num_frames < 2:
        raise RigError("a primer needs at least two frames at the model's frame rate")
    f = clip_features(primer)
    rot, _ = canonical_frames(f["rotations"], f["positions"], f["heading"], f["root_xz"],
                              controls.mover)
    mv = controls.mover
    rot[:, mv] *= np.where((rot[:, mv] @ controls.standing_rotations[mv])[:, None] < 0, -1.0, 1.0)
    f["rotations"] = rot
    return f
