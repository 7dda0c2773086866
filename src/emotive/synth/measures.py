"""What the manifest says of every walk: the classifier's reading, foot skate, path deviation.

Every synthetic walk of the main paper's augmented data set (Bhattacharya et al. 2020, section
5.2) is judged by the toolkit's own measures, the ones its evaluation suites use:

* the perceived-emotion classifier, as
  :meth:`emotive.eval.classifier.EmotionClassifier.judge` judges a clip (4 s windows every
  second), the windows of a whole shard through the network at once and the joints read from
  the world positions already computed: the label of the highest mean probability over the
  walk's windows, that probability, the mean valence/arousal it reads, and whether it was
  unsure (most windows unlike its training data);
* foot skating (:func:`emotive.eval.feet.foot_skating`): the mean horizontal speed of the
  planted feet (m/s) and the share of planted intervals faster than 0.1 m/s, contacts
  detected from the walk itself;
* path following (:func:`emotive.eval.path_following.path_following`): the mean and largest
  distance of the root from the path (metres) and the mean angle between the body's facing
  and the path (degrees), against the path's points every :data:`PATH_STEP` metres (the
  chords are within a millimetre of the curve at the paths' curvature); ``NaN`` for a walk
  that followed no path.

Legend: ``N`` walks, ``T`` frames, ``J`` joints, ``E`` end sites.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from emotive.core.skeleton import Skeleton
from emotive.eval.classifier import judge_joints, load_default_classifier, track_features
from emotive.eval.feet import foot_skating
from emotive.eval.path_following import path_following
from emotive.paths import GroundPath

#: Spacing of the path points measured against, metres.
PATH_STEP = 0.1
#: The classifier's windows and their spacing, seconds (those of ``judge``).
WINDOW_SECONDS, HOP_SECONDS = 4.0, 1.0


@functools.cache
def classifier() -> Any:
    """The shipped perceived-emotion classifier, loaded once per process."""
    return load_default_classifier()


def perceive(skeleton: Skeleton, roles: Any, world: np.ndarray, fps: float
             ) -> list[dict[str, Any]]:
    """The classifier's reading of every walk (module docstring).

    Args:
        skeleton: the walks' rig.
        roles: its resolved roles.
        world: ``(N, T, J + E, 3)`` world positions, metres.
        fps: frames per second.

    Returns:
        Per walk: ``perceived``, ``perceived_probability``, ``perceived_valence``,
        ``perceived_arousal``, ``unsure``.
    """
    clf = classifier()
    joints = judge_joints(skeleton, roles)
    windows, counts = [], []
    for k, walk in enumerate(world):
        feats = track_features(walk[:, joints], fps, clf.config)
        _, w = clf.windows(feats, WINDOW_SECONDS, HOP_SECONDS, f"walk {k}", len(walk) / fps)
        windows.append(w)
        counts.append(len(w))
    out = clf.outputs(np.concatenate(windows))
    ends = np.cumsum(counts)
    rows = []
    for lo, hi in zip(ends - counts, ends, strict=True):
        mean = out["probabilities"][lo:hi].mean(0)
        best = int(mean.argmax())
        va = out["valence_arousal"][lo:hi].mean(0)
        rows.append({"perceived": clf.labels[best], "perceived_probability": float(mean[best]),
                     "perceived_valence": float(va[0]), "perceived_arousal": float(va[1]),
                     "unsure": bool(out["unsure"][lo:hi].mean() > 0.5)})
    return rows


def measure(skeleton: Skeleton, roles: Any, world: np.ndarray, fps: float,
            paths: Sequence[GroundPath | None]) -> list[dict[str, Any]]:
    """The manifest's measures of every walk (module docstring).

    Args:
        skeleton: the walks' rig.
        roles: its resolved roles.
        world: ``(N, T, J + E, 3)`` world positions of joints then end sites, metres.
        fps: frames per second.
        paths: the path each walk followed, or ``None``.

    Returns:
        Per walk: the keys of :func:`perceive`, ``foot_skate``, ``foot_skate_ratio``,
        ``path_deviation``, ``path_deviation_max``, ``heading_deviation``.
    """
    rows = perceive(skeleton, roles, world, fps)
    skate = foot_skating(world, roles, fps)
    for k, (row, path) in enumerate(zip(rows, paths, strict=True)):
        row.update(foot_skate=float(skate.mean_speed[k]), foot_skate_ratio=float(skate.ratio[k]),
                   path_deviation=math.nan, path_deviation_max=math.nan,
                   heading_deviation=math.nan)
        if path is not None:
            points = path.position(np.linspace(0.0, path.length,
                                               max(2, round(path.length / PATH_STEP) + 1)))
            follow = path_following(world[k], roles, points)
            row.update(path_deviation=float(follow.position_deviation.mean()),
                       path_deviation_max=float(follow.position_deviation.max()),
                       heading_deviation=float(follow.heading_deviation.mean()))
    return rows
