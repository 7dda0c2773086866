"""FCRBM checkpoints: reading a training or exported checkpoint, exporting the generation part.

A checkpoint of :func:`~emotive.models.fcrbm.training.train_fcrbm` is ``{"kind", "config",
"train", "codec", "state", "velocity", "epoch", "rng", "best_val", "history", "seed"}``; the
exported (committed) one keeps :data:`EXPORTED_KEYS`, weights as float32.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from emotive.errors import ConfigError
from emotive.models.checkpoint_checks import (
    FPS_RANGE,
    build_weights,
    check_bound,
    check_tensor,
)
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.data import FrameCodec
from emotive.models.fcrbm.model import FCRBM
from emotive.models.training import (
    check_values,
    read_checkpoint,
    require_keys,
    slim_checkpoint,
)

#: Marks a checkpoint as an FCRBM one.
KIND = "fcrbm"
#: What a committed checkpoint keeps (no momentum or random state).
EXPORTED_KEYS = ("kind", "config", "train", "codec", "state", "epoch", "best_val", "history",
                 "seed")
#: What a training checkpoint holds besides: momentum and random state.
TRAINING_KEYS = (*EXPORTED_KEYS, "velocity", "rng")
#: Largest magnitude of a weight or momentum: the shipped model's largest weight is 0.75
#: (``b_ctx``), so this is 133 times the trained range
#: (:data:`~emotive.models.checkpoint_checks.WEIGHT_LIMIT` explains the choice).
WEIGHT_LIMIT = 100.0


def load_fcrbm_checkpoint(path: str | Path) -> tuple[FCRBM, FrameCodec, dict[str, Any]]:
    """The model (in eval mode), codec and raw dict of an FCRBM checkpoint.

    The config is checked field by field (:class:`FCRBMConfig`), the weights tensor by tensor
    before the model is built (:func:`~emotive.models.checkpoint_checks.build_weights`), the
    codec's numbers are finite and plausible, its standard deviations above 0, and its column
    indices within its rig's frame; a shipped file must match its model card's fingerprint.

    Raises:
        ConfigError: missing, corrupt, or not a usable FCRBM checkpoint; one line naming the
            file, the bad entry and the fix.
    """

    def build(ckpt: dict[str, Any]) -> tuple[FCRBM, FrameCodec]:
        if ckpt.get("kind") != KIND:
            raise ValueError("not an FCRBM checkpoint")
        require_keys(ckpt, {"config": dict, "state": dict, "codec": dict})
        config = FCRBMConfig.from_dict(ckpt["config"])
        model = build_weights(lambda: FCRBM(config), ckpt["state"], limit=WEIGHT_LIMIT)
        velocity = ckpt.get("velocity", {})
        if not isinstance(velocity, dict):
            raise ValueError(f"'velocity' is a {type(velocity).__name__}, not a dict")
        weights = model.state_dict()
        for key, value in velocity.items():
            if key not in weights:
                raise ValueError(f"velocity[{key!r}] is of no weight of the model")
            check_tensor(value, weights[key], f"velocity[{key!r}]", limit=WEIGHT_LIMIT)
        check_values(ckpt["codec"], "codec")
        codec = FrameCodec.from_dict(ckpt["codec"])
        check_values(codec.std, "codec['std']", positive=True)
        for name in ("mean", "std", "constant"):
            check_bound(getattr(codec, name), f"codec[{name!r}]")
        if not FPS_RANGE.holds(codec.fps):
            raise ValueError(f"codec['fps'] is {codec.fps:g}, not in {FPS_RANGE}")
        if not 0 <= codec.mover < codec.skeleton.num_joints:
            raise ValueError(f"codec['mover'] is {codec.mover}, not a joint of the codec's rig "
                             f"(0 to {codec.skeleton.num_joints - 1})")
        if not (codec.keep.shape == codec.mean.shape == codec.std.shape == (codec.dim,)):
            raise ValueError("the codec's keep, mean and std differ in length")
        if codec.dim and not 0 <= codec.keep.min() <= codec.keep.max() < len(codec.constant):
            raise ValueError("the codec keeps columns outside its rig's frame")
        return model, codec

    (model, codec), ckpt = read_checkpoint(path, "a usable FCRBM checkpoint", build,
                                           "retrain it with `emotive fcrbm train`", TRAINING_KEYS)
    if codec.dim != model.config.visible:
        raise ConfigError(f"{path}: the codec has {codec.dim} dimensions but the model "
                          f"{model.config.visible}; the checkpoint is corrupt")
    model.eval()
    return model, codec, ckpt


def export_fcrbm_checkpoint(source: str | Path, out: str | Path) -> Path:
    """Write the generation part of an FCRBM training checkpoint to ``out``.

    Write the generation part of an FCRBM training checkpoint (:data:`EXPORTED_KEYS`,
    float32) to ``out``, atomically.

    Raises:
        ConfigError: as :func:`load_fcrbm_checkpoint`.
    """
    load_fcrbm_checkpoint(source)
    return slim_checkpoint(source, out, EXPORTED_KEYS)
