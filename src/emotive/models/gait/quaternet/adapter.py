"""The QuaterNet baseline behind the model contract (:mod:`emotive.models.api`).

Registered as ``quaternet`` (:mod:`emotive.models.registry`): a Table 1 predictor, the
:class:`~emotive.models.gait.quaternet.predict.QuaterNetPredictor` of the committed checkpoint
``emotive/assets/gait/quaternet.pt`` (or of a checkpoint of ``emotive train quaternet``). It
reads no emotion and follows no path, so it is no generator.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from emotive.models.gait.controls import GaitControls
from emotive.models.gait.model import default_checkpoint_path as gait_checkpoint
from emotive.models.gait.quaternet.predict import QuaterNetPredictor
from emotive.models.gait.quaternet.training import load_quaternet_checkpoint

#: The committed checkpoint's file name, beside the gait network's.
CHECKPOINT = "quaternet.pt"


def default_checkpoint_path() -> Path:
    """The committed QuaterNet checkpoint."""
    return gait_checkpoint().with_name(CHECKPOINT)


def load_predictor(name: str = "quaternet", weights: str | Path | None = None) -> Any:
    """Registry loader: QuaterNet as a Table 1 predictor.

    Raises:
        ConfigError: a missing, corrupt or non-QuaterNet checkpoint.
    """
    network, ckpt = load_quaternet_checkpoint(weights if weights is not None
                                              else default_checkpoint_path())
    return QuaterNetPredictor(network, GaitControls.from_dict(ckpt["controls"]))
