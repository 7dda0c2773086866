"""The emotive gait network of Emotive Gaits (Bhattacharya et al. 2020, sections 3-4).

* :mod:`~emotive.models.gait.config`: :class:`GaitConfig`, every size, label, weight and switch.
* :mod:`~emotive.models.gait.network`: :class:`GaitNetwork`, encoder and predictor with a
  streaming one-frame :meth:`~GaitNetwork.step` and a teacher-forced window ``forward``.
* :mod:`~emotive.models.gait.losses`: the five training losses and :class:`GaitLoss`.
* :mod:`~emotive.models.gait.data`, :mod:`~emotive.models.gait.training`: windows of the
  Bandai Namco locomotion clips and the training loop with scheduled sampling.
* :mod:`~emotive.models.gait.controls`, :mod:`~emotive.models.gait.model`: what a checkpoint
  needs to animate without data, and :func:`load_gait_model` (the committed default).
* :mod:`~emotive.models.gait.generate`: :class:`GaitGenerator`, many agents following paths in
  one batch. :mod:`~emotive.models.gait.walks`: :func:`generate_walks`, whole walks with the
  foot-contact cleanup.
* :mod:`~emotive.models.gait.predict`: the Table 1 predictors of this network and QuaterNet.
"""

from emotive.models.gait.config import (
    AFFECTIVE_SIZE,
    MOVEMENT_INPUT_NAMES,
    ROOT_FEATURE_NAMES,
    GaitConfig,
)
from emotive.models.gait.generate import GaitFrame, GaitGenerator
from emotive.models.gait.losses import (
    LOSS_TERMS,
    GaitLoss,
    GaitRig,
    affective_loss,
    amplitude_loss,
    foot_contact_loss,
    motion_loss,
    pose_loss,
    rig_positions,
    root_loss,
)
from emotive.models.gait.model import GaitModel, load_gait_model
from emotive.models.gait.network import GaitInputs, GaitNetwork, GaitOutputs
from emotive.models.gait.walks import generate_walks

__all__ = [
    "AFFECTIVE_SIZE",
    "LOSS_TERMS",
    "MOVEMENT_INPUT_NAMES",
    "ROOT_FEATURE_NAMES",
    "GaitConfig",
    "GaitFrame",
    "GaitGenerator",
    "GaitInputs",
    "GaitLoss",
    "GaitModel",
    "GaitNetwork",
    "GaitOutputs",
    "GaitRig",
    "affective_loss",
    "amplitude_loss",
    "foot_contact_loss",
    "generate_walks",
    "load_gait_model",
    "motion_loss",
    "pose_loss",
    "rig_positions",
    "root_loss",
]
