"""Typed config of the emotive gait network: every size, label, loss weight and switch.

The config is saved with every checkpoint (:meth:`GaitConfig.to_dict` is JSON-safe) so that
a checkpoint alone rebuilds its network.

Paper sizes. Emotive Gaits (Bhattacharya et al. 2020, section 4) fixes the layer counts
(three fully connected layers in each of ``FC_enc1`` and ``FC_enc2``, one GRU, one layer in
``FC_root``, two in ``FC_versors``, one in each of ``FC_h``, ``FC_s``, ``FC_delta``) and ELU
on every fully connected layer (section 5.3), but names the widths only as symbols ``H_1``
(``FC_enc1`` output), ``H_2`` (``FC_enc2`` output), ``H_3`` (GRU) and ``H_4`` (``FC_root``)
without values. The defaults here are therefore our own, chosen small enough to train on two
CPU cores; the loss weights default to the paper's 1.0 (section 5.3: "We used a value of 1.0
for all of the performances reported").
"""

from __future__ import annotations

from dataclasses import dataclass

from emotive.data.emotion import DEFAULT_LABELS, check_labels
from emotive.models.checkpoint_checks import (
    FPS_RANGE,
    LOSS_WEIGHT_RANGE,
    WIDTH_RANGE,
    Range,
    check_fields,
)
from emotive.models.training import DictConfig

#: Per-frame inputs of the network besides rotations and emotion, in column order.
AFFECTIVE_SIZE = 18
#: ``[sin theta, cos theta, omega, s_lowpass, kappa]``.
MOVEMENT_INPUT_NAMES: tuple[str, ...] = (
    "sin_step_phase", "cos_step_phase", "step_frequency", "root_speed_lowpass", "curvature",
)
#: ``[h, s, delta]``, input and predicted.
ROOT_FEATURE_NAMES: tuple[str, ...] = ("root_height", "root_speed", "orientation_difference")

_POSITIVE_INTS = (
    "num_joints", "enc1_hidden", "enc1_out", "enc2_hidden", "enc2_out", "gru_hidden",
    "gru_layers", "root_hidden", "versor_hidden",
)
_WEIGHTS = (
    "motion_weight", "pose_weight", "affective_weight", "root_weight", "foot_contact_weight",
    "versor_weight", "amplitude_weight",
)
#: Plausible values of the numeric fields, checked with their types by
#: :func:`~emotive.models.checkpoint_checks.check_fields` (a TOML file's or a checkpoint's).
RANGES: dict[str, Range] = {
    "num_joints": Range(1, 1000), "fps": FPS_RANGE, "gru_layers": Range(1, 16),
    "head_hidden": Range(0, WIDTH_RANGE.high),
    **dict.fromkeys(("enc1_hidden", "enc1_out", "enc2_hidden", "enc2_out", "gru_hidden",
                     "root_hidden", "versor_hidden"), WIDTH_RANGE),
    **dict.fromkeys(_WEIGHTS, LOSS_WEIGHT_RANGE),
}


@dataclass(frozen=True)
class GaitConfig(DictConfig):
    """Sizes, labels, loss weights and ablation switches of :class:`GaitNetwork`.

    Attributes:
        labels: the ``C`` emotion labels of the emotion vector ``m``, in order.
        num_joints: ``J``, joints whose local rotations the network reads and predicts (the
            Bandai rig: 22, including the static ``joint_Root``).
        fps: frame rate of the motion the network runs at; the per-frame features (``s``,
            ``omega``, ``kappa``) and the recurrence are tied to it.
        enc1_hidden: width of the two hidden layers of ``FC_enc1``.
        enc1_out: ``H_1``, output width of ``FC_enc1``.
        enc2_hidden: width of the two hidden layers of ``FC_enc2``.
        enc2_out: ``H_2``, output width of ``FC_enc2``.
        gru_hidden: ``H_3``, hidden size of ``GRU_versors``.
        gru_layers: stacked GRU layers (the paper: one).
        root_hidden: ``H_4``, output width of ``FC_root``.
        versor_hidden: hidden width of the two-layer ``FC_versors``.
        head_hidden: hidden width of each of ``FC_h``, ``FC_s``, ``FC_delta``; 0 makes each a
            single linear layer, as in the paper.
        motion_weight: ``lambda_motion``.
        pose_weight: ``lambda_pose``.
        affective_weight: ``lambda_aff``.
        root_weight: ``lambda_root``.
        foot_contact_weight: ``lambda_ft_ct``.
        versor_weight: ``lambda_versor`` of the unit-norm penalty inside the motion loss. The
            paper gives no value; 0.01 is QuaterNet's (Pavllo et al. 2018), on which the paper
            builds.
        amplitude_weight: weight of the amplitude term, an extension of the paper's loss
            (0: off, the paper's equation 13): the L1 distance between the predicted and true
            standard deviation over each training window of every root-relative joint
            position and of the root height. The autoregressive rollout regresses towards the
            mean pose and damps every oscillation (the generated hip bounce was half the real
            one for every emotion); this term asks for the data's amplitude.
        use_affective: read the 18 affective features and train with the affective loss.
            ``False`` is the paper's first ablation (section 5.6): ``FC_enc1`` reads only
            ``m`` and the affective loss is dropped.
        use_root_loss: train with the root loss. ``False`` is the paper's second ablation; the
            network still predicts ``h, s, delta``.
    """

    labels: tuple[str, ...] = DEFAULT_LABELS
    num_joints: int = 22
    fps: float = 30.0
    enc1_hidden: int = 64
    enc1_out: int = 32
    enc2_hidden: int = 64
    enc2_out: int = 32
    gru_hidden: int = 192
    gru_layers: int = 1
    root_hidden: int = 32
    versor_hidden: int = 192
    head_hidden: int = 0
    motion_weight: float = 1.0
    pose_weight: float = 1.0
    affective_weight: float = 1.0
    root_weight: float = 1.0
    foot_contact_weight: float = 1.0
    versor_weight: float = 0.01
    amplitude_weight: float = 0.0
    use_affective: bool = True
    use_root_loss: bool = True

    def __post_init__(self) -> None:
        check_fields(self)
        object.__setattr__(self, "labels", check_labels(self.labels))
        for name in _POSITIVE_INTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"GaitConfig.{name} must be a positive integer, got {value!r}")
        if isinstance(self.head_hidden, bool) or not isinstance(self.head_hidden, int) or (
            self.head_hidden < 0
        ):
            raise ValueError(
                f"GaitConfig.head_hidden must be a non-negative integer, got {self.head_hidden!r}"
            )
        if not self.fps > 0:
            raise ValueError(f"GaitConfig.fps must be positive, got {self.fps!r}")
        object.__setattr__(self, "fps", float(self.fps))
        for name in _WEIGHTS:
            value = float(getattr(self, name))
            if not value >= 0:
                raise ValueError(f"GaitConfig.{name} must be a non-negative number, got {value!r}")
            object.__setattr__(self, name, value)
        for name in ("use_affective", "use_root_loss"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"GaitConfig.{name} must be true or false")
        check_fields(self, RANGES)

    @property
    def num_labels(self) -> int:
        """``C``, the length of the emotion vector."""
        return len(self.labels)
