"""The emotive gait network of Emotive Gaits (Bhattacharya et al. 2020, sections 3-4).

* :mod:`~emotive.models.gait.config`: :class:`GaitConfig`, every size, label, weight and switch.
* :mod:`~emotive.models.gait.network`: :class:`GaitNetwork`, encoder and predictor with a
  streaming one-frame :meth:`~GaitNetwork.step` and a teacher-forced window ``forward``.
* :mod:`~emotive.models.gait.losses`: the five training losses and :class:`GaitLoss`.
"""

from emotive.models.gait.config import (
    AFFECTIVE_SIZE,
    MOVEMENT_INPUT_NAMES,
    ROOT_FEATURE_NAMES,
    GaitConfig,
)
from emotive.models.gait.losses import (
    LOSS_TERMS,
    GaitLoss,
    GaitRig,
    affective_loss,
    foot_contact_loss,
    motion_loss,
    pose_loss,
    rig_positions,
    root_loss,
)
from emotive.models.gait.network import GaitInputs, GaitNetwork, GaitOutputs

__all__ = [
    "AFFECTIVE_SIZE",
    "LOSS_TERMS",
    "MOVEMENT_INPUT_NAMES",
    "ROOT_FEATURE_NAMES",
    "GaitConfig",
    "GaitInputs",
    "GaitLoss",
    "GaitNetwork",
    "GaitOutputs",
    "GaitRig",
    "affective_loss",
    "foot_contact_loss",
    "motion_loss",
    "pose_loss",
    "rig_positions",
    "root_loss",
]
