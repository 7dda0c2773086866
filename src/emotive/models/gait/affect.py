"""The 18 affective features as the gait network reads and compares them: ratios in log space.

Distance and area ratios (:data:`~emotive.features.affective.AFFECTIVE_FEATURE_KINDS`) are
heavy-tailed: the wrists-spine-root area ratio, whose denominator triangle (shoulders and hips)
nearly flattens in some poses, ranges from 0.15 to over 200 in the Bandai Namco locomotion
clips, and one frame to the next its change exceeds 30 in 0.1 % of frames. Left as they are,
such features dominate both the standardised network input and the squared affective loss,
and the network learns to chase them instead of the pose (on the validation split the
one-step affective loss of simply repeating the last pose was 12.8, against 0.15 for the
motion loss). The network therefore sees and compares ``log`` of every ratio (a ratio and its
inverse then weigh the same, and a 100-fold jump costs 4.6 instead of 100); angles stay in
radians. The features themselves (:mod:`emotive.features.affective`) are unchanged.
"""

from __future__ import annotations

import numpy as np
import torch

from emotive.features.affective import (
    AFFECTIVE_FEATURE_KINDS,
    affective_features,
    affective_features_batch_last,
    affective_features_np,
)

#: Columns of the 18 features that are ratios (compared in log space).
RATIO_COLUMNS: tuple[int, ...] = tuple(
    k for k, kind in enumerate(AFFECTIVE_FEATURE_KINDS) if kind != "angle"
)
#: Floor under a ratio before its logarithm.
RATIO_FLOOR = 1e-6


def log_ratios(features: torch.Tensor) -> torch.Tensor:
    """``(..., 18)`` features with the ratio columns replaced by their logarithm."""
    ratio = torch.zeros(features.shape[-1], dtype=torch.bool, device=features.device)
    ratio[list(RATIO_COLUMNS)] = True
    return torch.where(ratio, torch.log(features.clamp_min(RATIO_FLOOR)), features)


def gait_affective(positions: torch.Tensor, roles) -> torch.Tensor:
    """``(..., 18)`` network affective features of ``(..., J + E, 3)`` positions.

    ``(..., 18)`` network affective features of ``(..., J + E, 3)`` positions (torch,
    differentiable).
    """
    return log_ratios(affective_features(positions, roles))


def gait_affective_batch_last(points: torch.Tensor, roles) -> torch.Tensor:
    """``(18, B)`` network affective features of ``(J + E, 3, B)`` points, agents last."""
    features = affective_features_batch_last(points, roles)
    ratio = torch.zeros(features.shape[0], 1, dtype=torch.bool, device=features.device)
    ratio[list(RATIO_COLUMNS)] = True
    return torch.where(ratio, torch.log(features.clamp_min(RATIO_FLOOR)), features)


def gait_affective_np(positions: np.ndarray, roles) -> np.ndarray:
    """:func:`gait_affective` in NumPy (float64)."""
    out = affective_features_np(positions, roles).astype(np.float64)
    cols = list(RATIO_COLUMNS)
    out[..., cols] = np.log(np.maximum(out[..., cols], RATIO_FLOOR))
    return out
