"""FCRBM checkpoints: reading a training or exported checkpoint, exporting the generation part.

A checkpoint of :func:`~emotive.models.fcrbm.training.train_fcrbm` is ``{"kind", "config",
"train", "codec", "state", "velocity", "epoch", "rng", "best_val", "history", "seed"}``; the
exported (committed) one keeps :data:`EXPORTED_KEYS`, weights as float32.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from emotive.errors import ConfigError
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.data import FrameCodec
from emotive.models.fcrbm.model import FCRBM
from emotive.models.training import (
    check_values,
    load_weights,
    read_checkpoint,
    require_keys,
    slim_checkpoint,
)

#: Marks a checkpoint as an FCRBM one.
KIND = "fcrbm"
#: What a committed checkpoint keeps (no momentum or random state).
EXPORTED_KEYS = ("kind", "config", "train", "codec", "state", "epoch", "best_val", "history",
                 "seed")


def load_fcrbm_checkpoint(path: str | Path) -> tuple[FCRBM, FrameCodec, dict[str, Any]]:
    """The model (in eval mode), codec and raw dict of an FCRBM checkpoint.

    The weights are checked tensor by tensor (:func:`~emotive.models.training.load_weights`),
    the codec's numbers are finite and plausible, its standard deviations above 0, and its
    column indices within its rig's frame.

    Raises:
        ConfigError: missing, corrupt, or not a usable FCRBM checkpoint; one line naming the
            file, the bad entry and the fix.
    """

    def build(ckpt: dict[str, Any]) -> tuple[FCRBM, FrameCodec]:
        if ckpt.get("kind") != KIND:
            raise ValueError("not an FCRBM checkpoint")
        require_keys(ckpt, {"config": dict, "state": dict, "codec": dict})
        model = FCRBM(FCRBMConfig.from_dict(ckpt["config"]))
        load_weights(model, ckpt["state"])
        check_values(ckpt["codec"], "codec")
        codec = FrameCodec.from_dict(ckpt["codec"])
        check_values(codec.std, "codec['std']", positive=True)
        if not (codec.keep.shape == codec.mean.shape == codec.std.shape == (codec.dim,)):
            raise ValueError("the codec's keep, mean and std differ in length")
        if codec.dim and not 0 <= codec.keep.min() <= codec.keep.max() < len(codec.constant):
            raise ValueError("the codec keeps columns outside its rig's frame")
        return model, codec

    (model, codec), ckpt = read_checkpoint(path, "a usable FCRBM checkpoint", build,
                                           "retrain it with `emotive fcrbm train`")
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
