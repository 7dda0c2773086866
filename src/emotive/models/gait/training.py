"""Training loop of the emotive gait network (Emotive Gaits, section 5.3) with checkpoints.

Legend: ``B`` windows of a batch, ``T`` input frames per window, ``J`` joints, ``C`` labels.

Recipe (the paper's): Adam with learning rate ``1e-3`` decayed by ``0.999`` per epoch, and
curriculum learning by scheduled sampling: in epoch ``e`` (from 0) the teacher-forcing ratio is
``0.995 ** e``. Each input frame after the first of a batch is, with that probability, the
data (teacher-forced) and otherwise the network's own prediction of it: predicted rotations,
predicted root features ``[h, s, delta]`` and the affective features of the predicted pose
(forward kinematics with :func:`~emotive.models.gait.losses.rig_positions`), the rotations put
in the hemisphere of the input they followed
(:func:`~emotive.models.gait.network.same_hemisphere`). The movement
inputs and the emotion stay the data's: they are the controls given at animation time. The
choice is drawn per frame for the whole batch, so that runs of teacher-forced frames go
through the GRU in one call. As in scheduled sampling (Bengio et al. 2015), a fed-back
prediction is treated as data: no gradient flows through it.

The loss is :class:`~emotive.models.gait.losses.GaitLoss` on every predicted frame; each term
is logged. Validation runs every epoch on the validation split, with the network fed its own
predictions after the first frame (``val_teacher_forcing = 0``, as when animating), and the
checkpoint with the lowest total validation loss is kept as ``best.pt``.

Output folder: ``last.pt`` after every epoch, ``best.pt``, ``log.csv`` (one row per epoch:
every loss term on train and val, learning rate, teacher-forcing ratio, seconds), all written
atomically. A checkpoint is ``{"config", "train", "state", "optimizer", "epoch" (epochs done),
"rng", "best_val", "history", "seed", "controls"}``, ``controls`` the rig, standing pose and
walking paces the generator needs (:mod:`emotive.models.gait.controls`). Ctrl-C
(``KeyboardInterrupt``) leaves ``last.pt`` at the last finished epoch and re-raises.

Determinism: on CPU, a seed gives the same run (``torch.manual_seed`` for the weights, a NumPy
generator for batch order and teacher forcing), and resuming from a checkpoint written at the
end of an epoch gives the same results as not stopping; after Ctrl-C inside an epoch,
``last.pt`` is that end-of-epoch checkpoint, so resuming is bit-identical too. On ``N``
processes (:mod:`emotive.models.distributed`) a run is one process's on the same global batches
up to float rounding in the summed gradients, and the same again for the same ``N``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from emotive.errors import ConfigError
from emotive.models.distributed import World, current_world
from emotive.models.gait.affect import gait_affective
from emotive.models.gait.config import GaitConfig
from emotive.models.gait.controls import gait_controls
from emotive.models.gait.data import DEFAULT_DATASETS, GaitBatch, GaitData, load_gait_data
from emotive.models.gait.losses import LOSS_TERMS, GaitLoss, GaitRig, rig_positions
from emotive.models.gait.model import load_gait_checkpoint
from emotive.models.gait.network import (
    GaitInputs,
    GaitNetwork,
    GaitOutputs,
    same_hemisphere,
)
from emotive.models.training import (
    DictConfig,
    EpochOutcome,
    TrainingLog,
    check_resumable,
    load_settings,
    restore_rng_state,
    resumed_log,
    rng_state,
    run_epochs,
    seed_everything,
    training_paths,
)

#: Names of the logged loss values: the five terms then their weighted sum.
LOG_TERMS: tuple[str, ...] = (*LOSS_TERMS, "total")
#: Columns of ``log.csv``.
CSV_COLUMNS: tuple[str, ...] = (
    "epoch",
    *(f"train_{t}" for t in LOG_TERMS),
    *(f"val_{t}" for t in LOG_TERMS),
    "lr", "teacher_forcing", "seconds",
)


@dataclass(frozen=True)
class GaitTrainSettings(DictConfig):
    """How the gait network is trained (the ``[train]`` section of ``configs/gait.toml``).

    Attributes:
        epochs: epochs to train in all (the paper: 500).
        batch_size: windows per batch.
        window: ``T``, input frames per window (each window holds ``T + 1`` frames).
        stride: frames between window starts within a clip.
        learning_rate: Adam's initial learning rate.
        lr_decay: factor on the learning rate per epoch.
        teacher_forcing_decay: factor on the teacher-forcing ratio per epoch (``beta``).
        val_teacher_forcing: teacher-forcing ratio of the validation runs.
        datasets: registry names of the data sets (locomotion clips only).
        split_seed: seed of the split by clip.
        max_clips: for quick runs, at most this many clips per split and data set (0: all).
        initial_teacher_forcing: teacher-forcing ratio of the first epoch; the ratio of epoch
            ``e`` is ``initial_teacher_forcing * teacher_forcing_decay ** e``.
        label_balance: exponent ``a`` of label-balanced sampling: each epoch draws as many
            windows as there are, with replacement, window ``i`` with probability
            proportional to ``n_i ** -a``, ``n_i`` the windows of its dominant label (0: every
            window once, in random order, as the paper).
        init_from: a gait checkpoint whose weights start the training (fine-tuning); its
            model must have the same labels and sizes (loss weights may differ). ``""``:
            random initialization. In a TOML file a relative path is read from the file's
            folder (:func:`load_gait_settings`).
    """

    epochs: int = 500
    batch_size: int = 32
    window: int = 60
    stride: int = 15
    learning_rate: float = 1e-3
    lr_decay: float = 0.999
    teacher_forcing_decay: float = 0.995
    val_teacher_forcing: float = 0.0
    datasets: tuple[str, ...] = DEFAULT_DATASETS
    split_seed: int = 0
    max_clips: int = 0
    initial_teacher_forcing: float = 1.0
    label_balance: float = 0.0
    init_from: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.init_from, str):
            raise ValueError(f"init_from must be a checkpoint path or \"\", got "
                             f"{self.init_from!r}")
        for name, low in (("epochs", 1), ("batch_size", 1), ("window", 1), ("stride", 1),
                          ("split_seed", 0), ("max_clips", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        for name in ("learning_rate", "lr_decay", "teacher_forcing_decay"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
                raise ValueError(f"{name} must be a positive number, got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in ("val_teacher_forcing", "initial_teacher_forcing", "label_balance"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not (
                    0 <= value <= 1):
                raise ValueError(f"{name} must be a number in [0, 1], got {value!r}")
            object.__setattr__(self, name, float(value))
        if isinstance(self.datasets, str) or not self.datasets or not all(
            isinstance(d, str) for d in self.datasets
        ):
            raise ValueError(f"datasets must be a non-empty list of names, got {self.datasets!r}")
        object.__setattr__(self, "datasets", tuple(self.datasets))


def load_gait_settings(path: str | Path) -> tuple[GaitConfig, GaitTrainSettings]:
    """Read ``[model]`` and ``[train]`` from a TOML file.

    Read ``[model]`` (:class:`GaitConfig` fields) and ``[train]``
    (:class:`GaitTrainSettings` fields) from a TOML file
    (:func:`emotive.models.training.load_settings`: ``[model] labels`` defaults to every
    style). A relative ``init_from`` is taken from the file's folder, so a recipe and the
    checkpoint it starts from can move together.

    Raises:
        ConfigError: the file is missing or not TOML, or has an unknown section, an unknown
            key or a bad value; the message names the file and the key.
    """
    config, settings = load_settings(path, GaitConfig, GaitTrainSettings)
    start = Path(settings.init_from)
    if settings.init_from and not start.is_absolute():
        settings = replace(settings,
                           init_from=os.path.normpath(Path(path).resolve().parent / start))
    return config, settings


@dataclass
class GaitTrainResult:
    """What :func:`train_gait` leaves.

    Attributes:
        network: the network after the last epoch.
        history: one dict per epoch with the :data:`CSV_COLUMNS`.
        out_dir: the folder of ``last.pt``, ``best.pt`` and ``log.csv``.
        best_val: lowest total validation loss (``nan`` without validation windows).
    """

    network: GaitNetwork
    history: list[dict[str, float]]
    out_dir: Path
    best_val: float

    @property
    def last_path(self) -> Path:
        """The last checkpoint."""
        return self.out_dir / "last.pt"

    @property
    def best_path(self) -> Path:
        """The best checkpoint (lowest total validation loss)."""
        return self.out_dir / "best.pt"


def teacher_forcing_mask(frames: int, ratio: float, rng: np.random.Generator) -> np.ndarray:
    """``(T,)`` bool, ``True`` where input frame ``t`` is the data; frame 0 always is.

    Ratios 1 and 0 draw nothing from ``rng``, so fully teacher-forced and free-running runs
    leave it untouched.
    """
    if ratio >= 1.0:
        return np.ones(frames, dtype=bool)
    mask = np.zeros(frames, dtype=bool) if ratio <= 0.0 else rng.random(frames) < ratio
    mask[0] = True
    return mask


def rollout(network: GaitNetwork, batch: GaitBatch, mask: np.ndarray, rig: GaitRig
            ) -> GaitOutputs:
    """Run the network over the windows, feeding back its predictions where ``mask`` is off.

    Args:
        network: the network.
        batch: ``B`` windows of ``T + 1`` frames.
        mask: ``(T,)`` bool, ``True`` where the input frame is the data.
        rig: the rig, for the affective features of predicted poses.

    Returns:
        Predictions for frames ``1 .. T``: ``(B, T, J, 4)``, ``(B, T, J, 4)``, ``(B, T, 3)``.
    """
    inputs = batch.inputs()
    frames = inputs.rotations.shape[1]
    use_affective = network.config.use_affective
    parts: list[GaitOutputs] = []
    state = None
    t = 0
    while t < frames:
        if mask[t]:
            end = t + 1
            while end < frames and mask[end]:
                end += 1
            seg = GaitInputs(
                inputs.rotations[:, t:end],
                inputs.affective[:, t:end] if use_affective else None,
                inputs.emotion, inputs.movement[:, t:end], inputs.root[:, t:end],
            )
            out, state = network(seg, state)
            previous = inputs.rotations[:, end - 1]
            t = end
        else:
            last = parts[-1]
            rotations = same_hemisphere(last.rotations[:, -1].detach(), previous)
            affective = None
            if use_affective:
                pose = rig_positions(rotations, batch.positions[:, t], rig)
                affective = gait_affective(pose, rig.roles)
            frame = GaitInputs(rotations, affective, inputs.emotion, inputs.movement[:, t],
                               last.root[:, -1].detach())
            out, state = network.step(frame, state)
            previous = rotations
            out = GaitOutputs(*(x.unsqueeze(1) for x in out))
            t += 1
        parts.append(out)
    return GaitOutputs(*(torch.cat(xs, 1) for xs in zip(*parts, strict=True)))


def epoch_order(data: GaitData, settings: GaitTrainSettings, rng: np.random.Generator
                ) -> np.ndarray:
    """``(N,)`` window indices of one epoch (see ``label_balance``)."""
    n = len(data)
    if not settings.label_balance:
        return rng.permutation(n)
    label = data.emotions[data.window_clip].argmax(1)
    counts = np.bincount(label)
    weight = counts[label].astype(np.float64) ** -settings.label_balance
    return rng.choice(n, size=n, replace=True, p=weight / weight.sum())


def batch_indices(n: int, size: int, order: np.ndarray | None = None) -> list[np.ndarray]:
    """``order`` (by default ``0 .. n - 1``) cut into batches of ``size`` (the last shorter).

    Args:
        n: items in all.
        size: items per batch.
        order: ``(n,)`` item indices in the order to take them.

    Returns:
        ``ceil(n / size)`` arrays of item indices.
    """
    idx = np.arange(n) if order is None else order
    return [idx[i:i + size] for i in range(0, n, size)]


def evaluate_loss(network: GaitNetwork, data: GaitData, loss: GaitLoss, batch_size: int,
                  teacher_forcing: float = 0.0, seed: int = 0, world: World | None = None
                  ) -> dict[str, float]:
    """Mean of each loss term over every window of ``data`` (weighted by windows).

    Args:
        network: the network (run in eval mode without gradients).
        data: the windows.
        loss: the loss.
        batch_size: windows per batch.
        teacher_forcing: teacher-forcing ratio (0: fed its own predictions after frame 0).
        seed: seed of the teacher-forcing draws for ratios between 0 and 1.
        world: the training processes, which share the batches out (batch ``k`` to process
            ``k % size``) and sum them in one process's order (the same result); ``None``: one.

    Returns:
        ``{term: value}`` for the active terms and ``total``.
    """
    world = world or World()
    rng = np.random.default_rng(seed)
    rows: list[dict[str, float]] = []
    network.eval()
    with torch.no_grad():
        for k, idx in enumerate(batch_indices(len(data), batch_size)):
            mask = teacher_forcing_mask(data.length, teacher_forcing, rng)
            if k % world.size != world.rank:
                rows.append({})
                continue
            batch = data.batch(idx)
            outputs = rollout(network, batch, mask, loss.rig)
            _, terms = loss(outputs, batch.next_rotations, batch.next_root,
                            batch.next_positions)
            rows.append({name: v * len(idx) for name, v in terms.items()})
    sums: dict[str, float] = {}
    for row in world.merge_rows(rows, LOG_TERMS):
        for name, v in row.items():
            sums[name] = sums.get(name, 0.0) + v
    return {name: v / max(len(data), 1) for name, v in sums.items()}


#: Config fields a fine-tuning run may change from its starting checkpoint.
_LOSS_FIELDS = frozenset({"motion_weight", "pose_weight", "affective_weight", "root_weight",
                          "foot_contact_weight", "versor_weight", "amplitude_weight",
                          "use_root_loss"})


def _initialize_from(network: GaitNetwork, path: str) -> None:
    """Copy the weights of a checkpoint into ``network`` (see ``init_from``).

    Raises:
        ConfigError: the checkpoint is unusable or its model differs beyond loss settings.
    """
    start, _ = load_gait_checkpoint(path)
    ours = {k: v for k, v in network.config.to_dict().items() if k not in _LOSS_FIELDS}
    theirs = {k: v for k, v in start.config.to_dict().items() if k not in _LOSS_FIELDS}
    differ = sorted(k for k in ours if ours[k] != theirs.get(k))
    if differ:
        raise ConfigError(f"init_from {path}: its model differs in {differ}; fine-tuning "
                          "needs the same labels and sizes")
    network.load_state_dict(start.state_dict())


def train_gait(
    config: GaitConfig,
    settings: GaitTrainSettings,
    progress: bool = True,
    out_dir: str | Path = Path("models/gait"),
    resume: bool = False,
    seed: int = 0,
    *,
    data: dict[str, GaitData] | None = None,
    on_batch: Callable[[int, int], None] | None = None,
) -> GaitTrainResult:
    """Train the gait network; write ``last.pt``, ``best.pt`` and ``log.csv`` to ``out_dir``.

    Data parallel when run by :func:`emotive.models.distributed.run_parallel` (or torchrun,
    Ray Train): each process trains on its share of every batch; process 0 alone reads
    ``last.pt`` (sent to the others) and writes the files and progress.

    Args:
        config: the network's config (its labels define the emotion vector).
        settings: the training settings.
        progress: rich progress bars with each loss term on stderr.
        out_dir: output folder (created).
        resume: continue from ``out_dir / "last.pt"`` up to ``settings.epochs`` epochs.
        seed: seed of initialization, batch order and teacher forcing.
        data: the splits, when already loaded (:func:`load_gait_data`); ``"train"`` needed.
        on_batch: called as ``on_batch(epoch, batch)`` after every optimizer step (tests).

    Returns:
        The :class:`GaitTrainResult`.

    Raises:
        ConfigError: ``resume`` without a last checkpoint, or one made with another model
            config or other training settings (``epochs`` may differ).
        KeyboardInterrupt: Ctrl-C; ``last.pt`` keeps the last finished epoch.
    """
    out_dir = Path(out_dir)
    world = current_world()
    world.check_batch(settings.batch_size, "[train] batch_size")
    progress = progress and world.is_main
    last_path = training_paths(out_dir, resume) if world.is_main else out_dir / "last.pt"
    if data is None:
        data = load_gait_data(config, settings.datasets, settings.window, settings.stride,
                              settings.split_seed, settings.max_clips, progress)
    train, val = data["train"], data.get("val")
    rng = seed_everything(seed)
    network = GaitNetwork(config)
    network.set_feature_statistics(**{k: tuple(torch.from_numpy(x) for x in v)
                                      for k, v in train.statistics().items()})
    rig = GaitRig.from_skeleton(train.skeleton)
    controls = gait_controls(train).to_dict()
    loss_fn = GaitLoss(config, rig)
    if settings.init_from and not resume and world.is_main:  # sent to the others below
        _initialize_from(network, settings.init_from)
    optimizer = torch.optim.Adam(network.parameters(), lr=settings.learning_rate)
    log = TrainingLog()
    if resume:
        ckpt = world.from_main(lambda: load_gait_checkpoint(last_path)[1])
        check_resumable(last_path, ckpt, config.to_dict(), settings.to_dict(), seed)
        network.load_state_dict(ckpt["state"])
        optimizer.load_state_dict(ckpt["optimizer"])
        restore_rng_state(rng, ckpt["rng"])
        log = resumed_log(ckpt)
    world.broadcast_module(network)

    def checkpoint(epoch: int, state: dict[str, Any]) -> dict[str, Any]:
        return {
            "config": config.to_dict(), "train": settings.to_dict(),
            "state": network.state_dict(), "optimizer": optimizer.state_dict(),
            "epoch": epoch, "rng": state, "best_val": log.best_val,
            "history": log.history, "seed": seed, "controls": controls,
        }

    def run_epoch(epoch: int, batch_done: Callable[[str], None]) -> EpochOutcome:
        lr = settings.learning_rate * settings.lr_decay**epoch
        ratio = settings.initial_teacher_forcing * settings.teacher_forcing_decay**epoch
        for group in optimizer.param_groups:
            group["lr"] = lr
        network.train()
        sums: dict[str, float] = {}
        seen = 0
        for k, idx in enumerate(batch_indices(len(train), settings.batch_size,
                                         epoch_order(train, settings, rng))):
            mask = teacher_forcing_mask(train.length, ratio, rng)
            mine = idx[world.rows(len(idx))]  # all of idx for one process
            optimizer.zero_grad()
            if len(mine):
                batch = train.batch(mine)
                total, terms = loss_fn(rollout(network, batch, mask, rig), batch.next_rotations,
                                       batch.next_root, batch.next_positions)
                total.backward()
                for name, value in terms.items():
                    sums[name] = sums.get(name, 0.0) + value * len(mine)
            world.sum_gradients(network.parameters(), len(mine) / len(idx))
            optimizer.step()
            seen += len(mine)
            batch_done(_describe({n: v / seen for n, v in sums.items()}))
            if on_batch is not None:
                on_batch(epoch, k)
        sums, seen = world.sum_terms(sums, seen, LOG_TERMS)
        train_terms = {n: v / seen for n, v in sums.items()}
        val_terms = (
            # Without gradients, larger batches cost no more memory than training ones.
            evaluate_loss(network, val, loss_fn, 4 * settings.batch_size,
                          settings.val_teacher_forcing, seed, world)
            if val is not None and len(val) else {}
        )
        return loss_outcome(LOG_TERMS, train_terms, val_terms, lr, ratio,
                            _describe(val_terms or train_terms))

    run_epochs(log, settings.epochs, math.ceil(len(train) / settings.batch_size), out_dir,
               CSV_COLUMNS, run_epoch, checkpoint, lambda: rng_state(rng), progress,
               write=world.is_main)
    network.eval()
    return GaitTrainResult(network, log.history, out_dir, log.best_or_nan)


def loss_outcome(terms: tuple[str, ...], train_terms: dict[str, float],
                 val_terms: dict[str, float], lr: float, teacher_forcing: float,
                 detail: str = "") -> EpochOutcome:
    """An epoch of a trainer of loss terms.

    Its log row (``train_``/``val_`` of every name in ``terms``, learning rate, teacher forcing),
    scored by the validation total (the training total without validation data).
    """
    row: dict[str, float | None] = {}
    for name in terms:
        row[f"train_{name}"] = train_terms.get(name)
        row[f"val_{name}"] = val_terms.get(name)
    row.update(lr=lr, teacher_forcing=teacher_forcing)
    return EpochOutcome(
        row, val_terms.get("total", train_terms["total"]),
        f"train {train_terms['total']:.4g}"
        + (f"  val {val_terms['total']:.4g}" if val_terms else ""),
        (f"{detail}  " if detail else "") + f"lr {lr:.3g}  teacher forcing {teacher_forcing:.3g}",
    )


def _describe(terms: dict[str, float]) -> str:
    """``"total 1.23 motion 0.5 ..."`` for the progress bar."""
    order = ("total", *LOSS_TERMS)
    return "  ".join(f"{n} {terms[n]:.3g}" for n in order if n in terms)
