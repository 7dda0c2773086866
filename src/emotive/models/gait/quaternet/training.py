"""Training of the QuaterNet baseline on the gait network's data, with its recipe.

Legend: ``B`` windows of a batch, ``T`` input frames per window, ``J`` joints.

Everything but the network and the loss is the gait network's
(:mod:`emotive.models.gait.training`): the windows of
:func:`~emotive.models.gait.data.load_gait_data` (heading-canonical frames, split by clip), the
``[train]`` settings (:class:`~emotive.models.gait.training.GaitTrainSettings`), Adam with the
learning rate decayed per epoch, scheduled sampling (a frame that is not teacher-forced gets
the network's own, detached, prediction of its rotations; the movement inputs stay the data's,
as controls), validation fed its own predictions, and ``last.pt``/``best.pt``/``log.csv``
written atomically. QuaterNet's own recipe differs in two ways kept out for a like-for-like
comparison: it clips gradient norms to 0.1 and draws random windows each epoch.

Loss (QuaterNet's): the forward-kinematics pose loss plus ``lambda_versor`` times the unit-norm
penalty ``sum_j (|q^_j| - 1)^2``. The pose term is the gait network's
(:func:`~emotive.models.gait.losses.pose_loss`, squared error of root-relative joint positions)
rather than QuaterNet's unsquared distance, so that ``val_pose`` of both logs compare. QuaterNet
also predicts two trajectory outputs (offset along the path, height); this baseline predicts
rotations only.

A checkpoint is ``{"model": "quaternet", "config", "train", "state", "optimizer", "epoch",
"rng", "best_val", "history", "seed", "controls"}``, ``controls`` as in a gait checkpoint
(:func:`~emotive.models.gait.controls.gait_controls`). Ctrl-C leaves ``last.pt`` at the last
finished epoch and re-raises. A seed gives the same run on CPU, and resuming (after Ctrl-C or
kill -9) gives the results of not stopping.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from emotive.errors import ConfigError
from emotive.models.checkpoint_checks import build_weights, check_optimizer
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.controls import gait_controls
from emotive.models.gait.data import GaitBatch, GaitData, load_gait_data
from emotive.models.gait.losses import GaitRig, motion_loss, pose_loss
from emotive.models.gait.model import read_controls
from emotive.models.gait.quaternet.config import QuaterNetConfig
from emotive.models.gait.quaternet.network import QuaterNetOutputs, QuaterNetwork
from emotive.models.gait.training import (
    GaitTrainResult,
    GaitTrainSettings,
    batch_indices,
    loss_outcome,
    teacher_forcing_mask,
)
from emotive.models.training import (
    EpochOutcome,
    TrainingLog,
    check_resumable,
    load_settings,
    read_checkpoint,
    require_keys,
    restore_rng_state,
    resumed_log,
    rng_state,
    run_epochs,
    seed_everything,
    training_paths,
)

#: Logged loss values.
LOG_TERMS: tuple[str, ...] = ("pose", "versor", "total")
#: Columns of ``log.csv``.
CSV_COLUMNS: tuple[str, ...] = (
    "epoch", *(f"train_{t}" for t in LOG_TERMS), *(f"val_{t}" for t in LOG_TERMS),
    "lr", "teacher_forcing", "seconds",
)
#: Keys of a checkpoint of :func:`train_quaternet` (the committed one drops the last two).
CHECKPOINT_KEYS: tuple[str, ...] = (
    "model", "config", "train", "state", "epoch", "best_val", "history", "seed", "controls",
    "optimizer", "rng",
)


def load_quaternet_settings(path: str | Path) -> tuple[QuaterNetConfig, GaitTrainSettings]:
    """Read ``[model]`` and ``[train]`` from a TOML file.

    Read ``[model]`` (:class:`QuaterNetConfig` fields) and ``[train]``
    (:class:`~emotive.models.gait.training.GaitTrainSettings` fields) from a TOML file, with
    the checks of :func:`emotive.models.training.load_settings`.

    Raises:
        ConfigError: the file is missing or not TOML, or has an unknown section, an unknown
            key or a bad value; the message names the file and the key.
    """
    return load_settings(path, QuaterNetConfig, GaitTrainSettings)


@dataclass
class QuaterNetTrainResult(GaitTrainResult):
    """What :func:`train_quaternet` leaves (``history`` rows have the :data:`CSV_COLUMNS`)."""

    network: QuaterNetwork


def rollout(network: QuaterNetwork, batch: GaitBatch, mask: np.ndarray) -> QuaterNetOutputs:
    """Run the network over the windows, feeding back its predictions where ``mask`` is off.

    Args:
        network: the network.
        batch: ``B`` windows of ``T + 1`` frames.
        mask: ``(T,)`` bool, ``True`` where the input frame is the data.

    Returns:
        Predictions for frames ``1 .. T``: ``(B, T, J, 4)`` each.
    """
    rotations, movement = batch.rotations[:, :-1], batch.movement[:, :-1]
    parts: list[QuaterNetOutputs] = []
    state = None
    t = 0
    while t < len(mask):
        end = t + 1
        if mask[t]:
            while end < len(mask) and mask[end]:
                end += 1
            frames = rotations[:, t:end]
        else:
            frames = parts[-1].rotations[:, -1:].detach()
        out, state = network(frames, movement[:, t:end], state)
        parts.append(out)
        t = end
    return QuaterNetOutputs(*(torch.cat(xs, 1) for xs in zip(*parts, strict=True)))


def quaternet_loss(outputs: QuaterNetOutputs, batch: GaitBatch, rig: GaitRig,
                   config: QuaterNetConfig) -> tuple[torch.Tensor, dict[str, float]]:
    """``pose_weight * L_pose + versor_weight * mean_frames sum_j (|q^_j| - 1)^2``.

    Args:
        outputs: predictions for frames ``1 .. T`` of the batch, ``(B, T, J, 4)`` each.
        batch: the windows.
        rig: the rig, for forward kinematics.
        config: the weights.

    Returns:
        The scalar total (differentiable) and the unweighted terms and total as floats.
    """
    pose = pose_loss(outputs.rotations, batch.next_rotations, batch.next_positions, rig)
    # With no Euler orders, the motion loss is the unit-norm penalty alone.
    versor = motion_loss(outputs.raw_rotations, batch.next_rotations, ("",) * rig.num_joints,
                         1.0)
    total = config.pose_weight * pose + config.versor_weight * versor
    return total, {"pose": float(pose.detach()), "versor": float(versor.detach()),
                   "total": float(total.detach())}


def evaluate_quaternet(network: QuaterNetwork, data: GaitData, rig: GaitRig, batch_size: int,
                       teacher_forcing: float = 0.0, seed: int = 0) -> dict[str, float]:
    """Mean of each loss term over every window of ``data``.

    Mean of each loss term over every window of ``data`` (eval mode, no gradients); the
    network is fed its own predictions after frame 0 unless ``teacher_forcing`` > 0.
    """
    rng = np.random.default_rng(seed)
    sums = dict.fromkeys(LOG_TERMS, 0.0)
    network.eval()
    with torch.no_grad():
        for idx in batch_indices(len(data), batch_size):
            batch = data.batch(idx)
            mask = teacher_forcing_mask(data.length, teacher_forcing, rng)
            _, terms = quaternet_loss(rollout(network, batch, mask), batch, rig, network.config)
            for k, v in terms.items():
                sums[k] += v * len(idx)
    return {k: v / max(len(data), 1) for k, v in sums.items()}


def load_quaternet_checkpoint(path: str | Path) -> tuple[QuaterNetwork, dict[str, Any]]:
    """The network of a checkpoint written by :func:`train_quaternet`, and the checkpoint.

    The weights (and a training checkpoint's optimizer state) are checked as a gait
    checkpoint's (:func:`~emotive.models.gait.model.load_gait_checkpoint`) and the animation
    controls as a gait checkpoint's
    (:func:`~emotive.models.gait.model.read_controls`).

    Raises:
        ConfigError: the file is missing, corrupt, or not a usable QuaterNet checkpoint; one
            line naming the file, the bad entry and the fix.
    """

    def build(ckpt: dict[str, Any]) -> QuaterNetwork:
        require_keys(ckpt, {"config": dict, "state": dict})
        config = QuaterNetConfig.from_dict(ckpt["config"])
        network = build_weights(lambda: QuaterNetwork(config), ckpt["state"])
        if "optimizer" in ckpt:
            check_optimizer(ckpt["optimizer"], network)
        return network

    fix = "give a last.pt or best.pt written by `emotive train quaternet`"
    network, ckpt = read_checkpoint(path, "a QuaterNet checkpoint", build, fix, CHECKPOINT_KEYS)
    read_controls(Path(path), ckpt, network.config.num_joints, fix)
    network.eval()
    return network, ckpt


def train_quaternet(
    config: QuaterNetConfig,
    settings: GaitTrainSettings,
    progress: bool = True,
    out_dir: str | Path = Path("models/quaternet"),
    resume: bool = False,
    seed: int = 0,
    *,
    data: dict[str, GaitData] | None = None,
) -> QuaterNetTrainResult:
    """Train QuaterNet; write ``last.pt``, ``best.pt`` and ``log.csv`` to ``out_dir``.

    Args:
        config: the network's config.
        settings: the training settings (the gait network's).
        progress: progress bars and one line per epoch on stderr.
        out_dir: output folder (created).
        resume: continue from ``out_dir / "last.pt"`` up to ``settings.epochs`` epochs.
        seed: seed of initialization, batch order and teacher forcing.
        data: the splits, when already loaded (:func:`load_gait_data`); ``"train"`` needed.

    Returns:
        The :class:`QuaterNetTrainResult`.

    Raises:
        ConfigError: ``resume`` without a last checkpoint or with one made with another config
            or other settings (``epochs`` may differ), or a rig whose joint count is not
            ``num_joints``.
        OutputError: a checkpoint or the log cannot be written.
        KeyboardInterrupt: Ctrl-C; ``last.pt`` keeps the last finished epoch.
    """
    out_dir = Path(out_dir)
    last_path = training_paths(out_dir, resume)
    if data is None:
        data_config = GaitConfig(labels=config.labels, num_joints=config.num_joints,
                                 fps=config.fps)
        data = load_gait_data(data_config, settings.datasets, settings.window, settings.stride,
                              settings.split_seed, settings.max_clips, progress)
    train, val = data["train"], data.get("val")
    rig = GaitRig.from_skeleton(train.skeleton)
    if rig.num_joints != config.num_joints:
        raise ConfigError(f"[model] num_joints is {config.num_joints} but the rig of "
                          f"{list(settings.datasets)} has {rig.num_joints} joints: set "
                          f"num_joints = {rig.num_joints}")
    controls = gait_controls(train).to_dict()
    rng = seed_everything(seed)
    network = QuaterNetwork(config)
    network.set_feature_statistics(
        tuple(torch.from_numpy(x) for x in train.statistics()["movement"])
    )
    optimizer = torch.optim.Adam(network.parameters(), lr=settings.learning_rate)
    log = TrainingLog()
    if resume:
        _, ckpt = load_quaternet_checkpoint(last_path)
        check_resumable(last_path, ckpt, config.to_dict(), settings.to_dict(), seed)
        network.load_state_dict(ckpt["state"])
        optimizer.load_state_dict(ckpt["optimizer"])
        restore_rng_state(rng, ckpt["rng"])
        log = resumed_log(ckpt)

    def checkpoint(epoch: int, state: dict[str, Any]) -> dict[str, Any]:
        return {
            "model": "quaternet", "config": config.to_dict(), "train": settings.to_dict(),
            "state": network.state_dict(), "optimizer": optimizer.state_dict(),
            "epoch": epoch, "rng": state, "best_val": log.best_val,
            "history": log.history, "seed": seed, "controls": controls,
        }

    def run_epoch(epoch: int, batch_done: Callable[[str], None]) -> EpochOutcome:
        lr = settings.learning_rate * settings.lr_decay**epoch
        ratio = settings.teacher_forcing_decay**epoch
        for group in optimizer.param_groups:
            group["lr"] = lr
        network.train()
        sums, seen = dict.fromkeys(LOG_TERMS, 0.0), 0
        for idx in batch_indices(len(train), settings.batch_size, rng.permutation(len(train))):
            batch = train.batch(idx)
            outputs = rollout(network, batch, teacher_forcing_mask(train.length, ratio, rng))
            total, terms = quaternet_loss(outputs, batch, rig, config)
            optimizer.zero_grad()
            total.backward()
            optimizer.step()
            seen += len(idx)
            for name, value in terms.items():
                sums[name] += value * len(idx)
            batch_done(f"total {sums['total'] / seen:.3g}")
        train_terms = {n: v / seen for n, v in sums.items()}
        val_terms = (evaluate_quaternet(network, val, rig, 4 * settings.batch_size,
                                        settings.val_teacher_forcing, seed)
                     if val is not None and len(val) else {})
        return loss_outcome(LOG_TERMS, train_terms, val_terms, lr, ratio)

    run_epochs(log, settings.epochs, math.ceil(len(train) / settings.batch_size), out_dir,
               CSV_COLUMNS, run_epoch, checkpoint, lambda: rng_state(rng), progress)
    network.eval()
    return QuaterNetTrainResult(network, log.history, out_dir, log.best_or_nan)

