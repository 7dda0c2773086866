"""Typed config of the QuaterNet baseline (Pavllo et al. 2018), saved with every checkpoint.

The sizes follow QuaterNet's long-term locomotion model where they do not fight the comparison
with the gait network: a stacked GRU over the joint quaternions, the controls through two
30-unit layers with leaky ReLU before the GRU (QuaterNet's ``fc1``/``fc2``), and a single linear
output layer. QuaterNet's GRU has 1000 units; ours has 150, which gives the baseline as many
parameters as the gait network (272,098 against 272,123 with its 19 labels), so that the
comparison is between designs, not sizes, and both train in comparable time on the same data.
"""

from __future__ import annotations

from dataclasses import dataclass

from emotive.data.emotion import ALL_LABELS, check_labels
from emotive.models.checkpoint_checks import (
    FPS_RANGE,
    LOSS_WEIGHT_RANGE,
    WIDTH_RANGE,
    Range,
    check_fields,
)
from emotive.models.training import DictConfig

_POSITIVE_INTS = ("num_joints", "control_hidden", "gru_hidden", "gru_layers")
_WEIGHTS = ("pose_weight", "versor_weight")
_SWITCHES = ("use_movement", "residual")
#: Plausible values of the numeric fields, checked with their types by
#: :func:`~emotive.models.checkpoint_checks.check_fields` (a TOML file's or a checkpoint's).
RANGES: dict[str, Range] = {
    "num_joints": Range(1, 1000), "fps": FPS_RANGE, "control_hidden": WIDTH_RANGE,
    "gru_hidden": WIDTH_RANGE, "gru_layers": Range(1, 16),
    **dict.fromkeys(_WEIGHTS, LOSS_WEIGHT_RANGE),
}


@dataclass(frozen=True)
class QuaterNetConfig(DictConfig):
    """Sizes, switches and loss weights of :class:`~emotive.models.gait.quaternet.QuaterNetwork`.

    Attributes:
        labels: styles whose clips are trained on, as the gait network's ``labels`` (give both
            the same labels and both see the same clips). Never an input: QuaterNet has no
            emotion.
        num_joints: ``J``, joints whose local rotations the network reads and predicts.
        fps: frame rate of the motion the network runs at.
        control_hidden: width of the two layers the movement inputs go through (QuaterNet: 30).
        gru_hidden: ``H``, hidden size of each GRU layer (150: with two layers, 272,098
            parameters, the size of the gait network; QuaterNet: 1000).
        gru_layers: ``L``, stacked GRU layers (QuaterNet: 2).
        use_movement: read the five movement inputs ``[sin theta, cos theta, omega, s_lowpass,
            kappa]`` as controls, as QuaterNet's long-term model reads its phase, speed and
            trajectory; ``False`` is QuaterNet's short-term model (rotations only).
        residual: predict a rotation applied to the input one (QuaterNet's
            ``model_velocities``, used by its short-term model) instead of the next rotation
            itself (its long-term model, and the gait network).
        pose_weight: weight of the forward-kinematics pose loss.
        versor_weight: ``lambda_versor`` of the unit-norm penalty (QuaterNet: 0.01).
    """

    labels: tuple[str, ...] = ALL_LABELS
    num_joints: int = 22
    fps: float = 30.0
    control_hidden: int = 30
    gru_hidden: int = 150
    gru_layers: int = 2
    use_movement: bool = True
    residual: bool = False
    pose_weight: float = 1.0
    versor_weight: float = 0.01

    def __post_init__(self) -> None:
        check_fields(self)
        object.__setattr__(self, "labels", check_labels(self.labels))
        for name in _POSITIVE_INTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(
                    f"QuaterNetConfig.{name} must be a positive integer, got {value!r}"
                )
        if isinstance(self.fps, bool) or not isinstance(self.fps, int | float) or (
            not self.fps > 0
        ):
            raise ValueError(f"QuaterNetConfig.fps must be a positive number, got {self.fps!r}")
        object.__setattr__(self, "fps", float(self.fps))
        for name in _WEIGHTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value >= 0:
                raise ValueError(
                    f"QuaterNetConfig.{name} must be a non-negative number, got {value!r}"
                )
            object.__setattr__(self, name, float(value))
        for name in _SWITCHES:
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"QuaterNetConfig.{name} must be true or false")
        check_fields(self, RANGES)
