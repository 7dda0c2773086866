"""A trained gait model ready to animate: network, controls, and the committed default.

:func:`load_gait_checkpoint` reads the network of a checkpoint of
:func:`~emotive.models.gait.training.train_gait`; :func:`load_gait_model` adds the animation
controls (by default of the exported default under ``emotive/assets/gait/``);
:func:`export_checkpoint` strips a
training checkpoint down to what animation needs (config, weights, controls, the training
settings and log for the model card), so the committed file stays small.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from emotive.errors import ConfigError
from emotive.models.checkpoint_checks import build_weights, check_optimizer
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.network import GaitNetwork
from emotive.models.training import (
    check_values,
    read_checkpoint,
    require_keys,
    slim_checkpoint,
)

#: The committed default checkpoint, inside the package.
DEFAULT_CHECKPOINT = "emotive-gait.pt"
#: Keys an exported checkpoint keeps.
EXPORTED_KEYS: tuple[str, ...] = (
    "config", "state", "controls", "train", "epoch", "best_val", "history", "seed",
)
#: Keys a training checkpoint of :func:`~emotive.models.gait.training.train_gait` holds.
TRAINING_KEYS: tuple[str, ...] = (*EXPORTED_KEYS, "optimizer", "rng")


@dataclass(frozen=True, eq=False)
class GaitModel:
    """A gait network with what it needs to animate without data.

    Attributes:
        network: the network, in eval mode.
        controls: rig, standing pose and walking paces.
        source: the checkpoint file it came from.
    """

    network: GaitNetwork
    controls: GaitControls
    source: Path

    @property
    def labels(self) -> tuple[str, ...]:
        """The ``C`` labels of the emotion vector."""
        return self.network.config.labels

    @property
    def fps(self) -> float:
        """Frame rate the network runs at."""
        return self.network.config.fps


def default_checkpoint_path() -> Path:
    """The committed default checkpoint (``emotive/assets/gait/emotive-gait.pt``)."""
    return Path(str(resources.files("emotive") / "assets" / "gait" / DEFAULT_CHECKPOINT))


def load_gait_checkpoint(path: str | Path) -> tuple[GaitNetwork, dict[str, Any]]:
    """The network (in eval mode) of a gait checkpoint, and the checkpoint.

    The network (in eval mode) of a checkpoint written by
    :func:`~emotive.models.gait.training.train_gait`, and the checkpoint.

    The weights are checked tensor by tensor before the network is built
    (:func:`~emotive.models.checkpoint_checks.build_weights`): the keys, dtypes and shapes of
    the config's network, finite values within the trained range, feature standard deviations
    above 0; a training checkpoint's optimizer state against the network's parameters; the
    config field by field; a shipped file against its model card's fingerprint.

    Raises:
        ConfigError: the file is missing, a folder, unreadable, or not a usable gait
            checkpoint; one line naming the file, the bad entry and the fix.
    """

    def build(ckpt: dict[str, Any]) -> GaitNetwork:
        require_keys(ckpt, {"config": dict, "state": dict})
        config = GaitConfig.from_dict(ckpt["config"])
        network = build_weights(lambda: GaitNetwork(config), ckpt["state"])
        if "optimizer" in ckpt:
            check_optimizer(ckpt["optimizer"], network)
        return network

    network, ckpt = read_checkpoint(path, "a gait checkpoint", build,
                                    "give a last.pt or best.pt written by `emotive train gait`",
                                    TRAINING_KEYS)
    network.eval()
    return network, ckpt


def read_controls(path: Path, ckpt: dict[str, Any], num_joints: int,
                  fix: str = "retrain it with `emotive train gait`") -> GaitControls:
    """The animation controls of a checkpoint, checked.

    Args:
        path: the checkpoint file, for the message.
        ckpt: the checkpoint.
        num_joints: the network's joint count, which the rig must have.
        fix: how the user gets a good checkpoint, for the message.

    Raises:
        ConfigError: no controls (checkpoints written before the controls existed must be
            retrained), a missing or bad entry, a number that is not finite or is absurd, a
            rate or pace that is not positive, or a rig of another joint count.
    """
    if "controls" not in ckpt:
        raise ConfigError(f"{path}: gait checkpoint without animation controls; {fix}")
    values = ckpt["controls"]
    try:
        if not isinstance(values, dict):
            raise TypeError(f"a {type(values).__name__}, not a dict")
        check_values(values, "controls")
        controls = GaitControls.from_dict(values)
        for name in ("step_frequency", "speed", "fps"):
            check_values(getattr(controls, name), f"controls[{name!r}]", positive=True)
    except KeyError as exc:
        raise ConfigError(f"{path}: bad animation controls in the checkpoint (no {exc} entry); "
                          f"{fix}") from None
    except (ValueError, TypeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(f"{path}: bad animation controls in the checkpoint ({reason}); "
                          f"{fix}") from None
    if controls.skeleton.num_joints != num_joints:
        raise ConfigError(f"{path}: the rig has {controls.skeleton.num_joints} joints, the "
                          f"network {num_joints}; {fix}")
    return controls


def load_gait_model(path: str | Path | None = None) -> GaitModel:
    """A gait model from a checkpoint, by default the committed one.

    Raises:
        ConfigError: the file is missing, corrupt, or not a gait checkpoint with usable
            controls (see :func:`read_controls`).
    """
    path = default_checkpoint_path() if path is None else Path(path)
    network, ckpt = load_gait_checkpoint(path)
    controls = read_controls(path, ckpt, network.config.num_joints)
    return GaitModel(network, controls, path)


def export_checkpoint(source: str | Path, out: str | Path) -> Path:
    """Write the animation part of a gait training checkpoint (:data:`EXPORTED_KEYS`), float32.

    Raises:
        ConfigError: as :func:`load_gait_model`.
    """
    load_gait_model(source)
    return slim_checkpoint(source, out, EXPORTED_KEYS)

