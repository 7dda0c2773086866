"""Data, contrastive-divergence training and checkpoints of the FCRBM (issue 6, section 2).

``emotive fcrbm train --config configs/fcrbm.toml``: the clips of :attr:`FCRBMTrainSettings
.contents` (by default walks) of every style with a valence/arousal entry, in both data sets,
or of the styles named in :attr:`FCRBMTrainSettings.styles`, split by clip per data set
(:func:`emotive.data.splits.split_clips`); frames and context as in
:mod:`emotive.models.fcrbm.data`, the codec fitted on the training split. Every example is a
frame, its ``N`` past frames and its context, never crossing a clip.

Each epoch runs CD-k over the shuffled training examples in mini-batches
(:meth:`~emotive.models.fcrbm.model.FCRBM.train_step`: momentum, weight decay), then measures
the validation **one-step error**: the mean squared error, in standardized units, of the frame
the model generates (Gibbs sampling, mean-field last step) from the true past and context. A
checkpoint ``{"kind", "config", "train", "codec", "state", "velocity", "epoch", "rng",
"best_val", "history", "seed"}`` is written atomically to ``last.pt`` after every epoch and to
``best.pt`` when the validation error is the lowest so far; ``log.csv`` has one row per epoch.
Ctrl-C leaves ``last.pt`` at the last finished epoch; ``resume`` continues from it exactly,
with the same batch order. The run is deterministic for a seed on CPU.

Legend: ``T`` frames, ``D`` visible units, ``N`` order, ``M`` examples.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from emotive.data.clips import load_clips
from emotive.data.emotion import VALENCE_AROUSAL, style_to_label
from emotive.data.splits import split_clips, spread
from emotive.errors import DataError
from emotive.models.fcrbm.checkpoint import KIND, load_fcrbm_checkpoint
from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.data import (
    CONTEXT_RANGE,
    FrameCodec,
    clip_context,
    frame_vectors,
    step_rate,
)
from emotive.models.fcrbm.model import FCRBM, sliding_windows
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

#: Data sets of the default training data.
DEFAULT_DATASETS = ("bandai-namco-1", "bandai-namco-2-locomotion")
#: Columns of ``log.csv``.
CSV_COLUMNS = ("epoch", "train_reconstruction", "val_one_step", "ar_radius", "seconds")
#: Valence/arousal values (per axis) at which the autoregressive part is kept stable: the
#: paper's 1-3 scale and the exaggeration range around it, in steps of 0.75.
STABLE_AXIS = (0.5, 1.25, 2.0, 2.75, 3.5)
#: Lowest valence/arousal of a training context after ``context_noise``: the lowest the
#: generator accepts (kept positive: every interaction is multiplicative in the context).
MIN_CONTEXT = CONTEXT_RANGE[0]
#: Styles whose arousal is at or below the first value are at the low edge of the arousal scale
#: (``low_arousal_weight``: tired, exhausted), those at or above the second at the high edge
#: (``edge_energy``: angry, active).
EDGE_AROUSAL = (1.25, 2.75)
#: A frame's energy score is the z-score of its step rate within its style divided by this
#: (the spread of the mean of root- and joint-speed z-scores, the score of the previous
#: default model, kept so that edge_energy means the same lift per standard deviation).
ENERGY_SPREAD = 0.85
#: The energy score is clipped to this many units either way.
ENERGY_CLIP = 2.0


@dataclass(frozen=True)
class FCRBMTrainSettings(DictConfig):
    """How the FCRBM is trained (``[train]`` of ``configs/fcrbm.toml``).

    Attributes:
        epochs: epochs in all.
        batch_size: examples per CD update.
        datasets: registry names of the data sets.
        contents: clip contents used (e.g. ``walk``).
        styles: ``"data set:style"`` entries (e.g. ``"bandai-namco-1:happy"``) to train on
            only those styles' clips; empty: every style with a valence/arousal entry.
        balance_contexts: repeat the examples of every valence/arousal point in each epoch
            so that each point weighs about as much as the largest (:func:`epoch_examples`);
            otherwise a point weighs as much as its frames.
        split_seed: seed of the split by clip.
        max_clips: for quick runs, at most this many clips per split and data set (0: all).
        past_noise: standard deviation (standardized units) of Gaussian noise added to the
            past frames of every training example, so that the model learns to pull
            generated frames back towards the data instead of amplifying its own errors.
        context_noise: standard deviation (valence/arousal units) of Gaussian noise added to
            the context of every training example (kept at :data:`MIN_CONTEXT` or above), so
            that the model also learns the plane around and between its training points.
        edge_energy: arousal offset (valence/arousal units) per unit of a frame's energy
            score, for the styles at the high edge of the arousal scale
            (:data:`EDGE_AROUSAL`) only (:func:`edge_energy_contexts`): their frames that step
            faster than the style's average are labelled above its arousal, so that arousal
            beyond the 1-3 scale (exaggeration) has data that step faster than the edge
            styles.
            0: every frame has its style's arousal.
        low_arousal_weight: the examples of the styles at the low edge of the arousal scale
            (:data:`EDGE_AROUSAL`) appear this many times in each epoch (after
            ``balance_contexts``); 1: as often as the others.
        max_ar_radius: with the past-to-visible term
            (:attr:`~emotive.models.fcrbm.config.FCRBMConfig.visible_autoregression`), after
            every epoch the autoregressive weights are scaled so that the
            spectral radius of their companion matrix is at most this at every context of
            the grid :data:`STABLE_AXIS` x :data:`STABLE_AXIS`
            (:meth:`~emotive.models.fcrbm.model.FCRBM.limit_ar_radius`): generation cannot
            explode there.
        project_every: the same projection every this many mini-batches, at the corners and
            the centre of the grid only (cheap; 0: only after each epoch). Closer to projected
            gradient descent: each projection is a smaller correction that the next updates
            adapt to. Projecting only once per epoch let the radius reach 1.6-1.9 in between
            and the large rescaling undid the fit (validation one-step error 0.15 after 20
            epochs; 0.054 after 15 with this; 0.026 unprojected, which diverges). The grid's
            maximum is not always at the corners: the radius before the end-of-epoch
            projection still reached 1.2-1.3.
    """

    epochs: int = 100
    batch_size: int = 100
    datasets: tuple[str, ...] = DEFAULT_DATASETS
    contents: tuple[str, ...] = ("walk",)
    styles: tuple[str, ...] = ()
    balance_contexts: bool = False
    split_seed: int = 0
    max_clips: int = 0
    past_noise: float = 0.0
    context_noise: float = 0.0
    edge_energy: float = 0.0
    low_arousal_weight: int = 1
    max_ar_radius: float = 0.999
    project_every: int = 50

    def __post_init__(self) -> None:
        if isinstance(self.max_ar_radius, bool) or not isinstance(
                self.max_ar_radius, int | float) or not 0 < self.max_ar_radius <= 1:
            raise ValueError(f"max_ar_radius must be a number in (0, 1], got "
                             f"{self.max_ar_radius!r}")
        object.__setattr__(self, "max_ar_radius", float(self.max_ar_radius))
        if isinstance(self.past_noise, bool) or not isinstance(self.past_noise, int | float) or (
                not 0 <= self.past_noise < 10):
            raise ValueError(f"past_noise must be a number in [0, 10), got {self.past_noise!r}")
        object.__setattr__(self, "past_noise", float(self.past_noise))
        if isinstance(self.context_noise, bool) or not isinstance(
                self.context_noise, int | float) or not 0 <= self.context_noise < 1:
            raise ValueError(f"context_noise must be a number in [0, 1), got "
                             f"{self.context_noise!r}")
        object.__setattr__(self, "context_noise", float(self.context_noise))
        if isinstance(self.edge_energy, bool) or not isinstance(
                self.edge_energy, int | float) or not 0 <= self.edge_energy <= 1:
            raise ValueError(f"edge_energy must be a number in [0, 1], got {self.edge_energy!r}")
        object.__setattr__(self, "edge_energy", float(self.edge_energy))
        for name, low in (("epochs", 1), ("batch_size", 1), ("split_seed", 0),
                          ("max_clips", 0), ("project_every", 0), ("low_arousal_weight", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        for name in ("datasets", "contents"):
            value = getattr(self, name)
            if isinstance(value, str) or not value or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{name} must be a non-empty list of names, got {value!r}")
            object.__setattr__(self, name, tuple(value))
        if isinstance(self.styles, str) or not all(
                isinstance(v, str) and v.partition(":")[0] in self.datasets and v.partition(":")[2]
                for v in self.styles):
            raise ValueError(f"styles must be a list of \"data set:style\" entries with a data "
                             f"set of datasets ({list(self.datasets)}), got {self.styles!r}")
        object.__setattr__(self, "styles", tuple(self.styles))
        if not isinstance(self.balance_contexts, bool):
            raise ValueError(f"balance_contexts must be true or false, got "
                             f"{self.balance_contexts!r}")


def load_fcrbm_settings(path: str | Path) -> tuple[FCRBMConfig, FCRBMTrainSettings]:
    """``[model]`` and ``[train]`` of a TOML file.

    ``[model]`` (:class:`FCRBMConfig` fields but ``visible``, which the data set) and
    ``[train]`` of a TOML file.

    Raises:
        ConfigError: as :func:`emotive.models.training.load_settings`.
    """
    return load_settings(path, FCRBMConfig, FCRBMTrainSettings, {"visible": 1})


@dataclass
class FCRBMData:
    """Encoded clips by split.

    Attributes:
        codec: fitted on the training split.
        splits: split -> list of ``(clip name, (T, D) frames, (T, 2) context)``.
    """

    codec: FrameCodec
    splits: dict[str, list[tuple[str, np.ndarray, np.ndarray]]]

    def examples(self, split: str, order: int) -> tuple[torch.Tensor, ...]:
        """``v (M, D)``, ``past (M, N, D)``, ``context (M, 2)`` of a split's clips."""
        parts = [sliding_windows(f, c, order) for _, f, c in self.splits.get(split, [])
                 if len(f) > order]
        if not parts:
            d = self.codec.dim
            return torch.zeros(0, d), torch.zeros(0, order, d), torch.zeros(0, 2)
        return tuple(torch.cat([p[k] for p in parts]) for k in range(3))


def load_fcrbm_data(settings: FCRBMTrainSettings, progress: bool = False) -> FCRBMData:
    """The training clips, split per data set and encoded.

    The clips of the settings' data sets and contents whose style has a valence/arousal
    entry, split by clip per data set and encoded with the training split's codec.

    Raises:
        DataError: a data set is missing or the training split has no clip.
    """
    raw: dict[str, list[tuple[str, np.ndarray, np.ndarray, Any]]] = {}
    for name in settings.datasets:
        clips = [c for c in load_clips(name, contents=settings.contents, progress=progress)
                 if style_to_label(c.style) in VALENCE_AROUSAL and c.motion.num_frames > 1]
        if settings.styles:
            entries = (v.partition(":") for v in settings.styles)
            wanted = {style for data_set, _, style in entries if data_set == name}
            have = {c.style for c in clips}
            if wanted - have:
                raise DataError(f"styles: no {'/'.join(settings.contents)} clips of "
                                f"{sorted(wanted - have)} with a valence/arousal entry in "
                                f"{name}; it has {sorted(have)}")
            clips = [c for c in clips if c.style in wanted]
        for split, members in split_clips(clips, seed=settings.split_seed).items():
            for clip in spread(members, settings.max_clips):
                frames = frame_vectors(clip.motion)
                raw.setdefault(split, []).append(
                    (clip.name, frames, clip_context(clip.style, len(frames)), clip.motion))
    if not raw.get("train"):
        raise DataError(f"no {'/'.join(settings.contents)} clips with a valence/arousal entry in "
                        f"{list(settings.datasets)}")
    codec = FrameCodec.fit([f for _, f, _, _ in raw["train"]], [m for *_, m in raw["train"]])
    return FCRBMData(codec, {s: [(n, codec.encode(f), c) for n, f, c, _ in items]
                             for s, items in raw.items()})


def _z_score(values: np.ndarray, mean: float, std: float) -> np.ndarray:
    """``(values - mean) / std``; 0 where the style does not vary (``std`` 0)."""
    return (values - mean) / std if std > 0 else np.zeros_like(values)


def edge_energy_contexts(data: FCRBMData, offset: float) -> FCRBMData:
    """The data with the arousal of the high-edge styles' frames raised by how fast they step.

    Each frame's energy score is the z-score of its step rate
    (:func:`~emotive.models.fcrbm.data.step_rate`) among the training frames of its style (its
    valence/arousal point), divided by :data:`ENERGY_SPREAD` and clipped to ``±``
    :data:`ENERGY_CLIP`. A style with arousal at or above ``EDGE_AROUSAL[1]`` adds ``offset``
    times the positive part of the score to its frames' arousal; the others keep theirs.

    Args:
        data: encoded clips with one valence/arousal point per clip.
        offset: arousal units per unit of the score.

    Raises:
        DataError: a clip's style has no training clip.
    """
    def style(context: np.ndarray) -> tuple[float, ...]:
        return tuple(np.round(context[0], 4))

    rates = {split: [step_rate(frames, data.codec) for _, frames, _ in items]
             for split, items in data.splits.items()}
    pooled: dict[tuple[float, ...], list[np.ndarray]] = {}
    for (_, _, context), rate in zip(data.splits["train"], rates["train"], strict=True):
        pooled.setdefault(style(context), []).append(rate)
    stats = {}
    for key, parts in pooled.items():
        style_rate = np.concatenate(parts)
        stats[key] = (style_rate.mean(), style_rate.std())
    high = EDGE_AROUSAL[1]
    splits = {}
    for split, items in data.splits.items():
        moved = []
        for (name, frames, context), rate in zip(items, rates[split], strict=True):
            if style(context) not in stats:
                raise DataError(f"{name}: its valence/arousal point {style(context)} has no "
                                f"training clip; change split_seed or the styles")
            if context[0, 1] < high:
                moved.append((name, frames, context))
                continue
            score = _z_score(rate, *stats[style(context)])
            score = np.clip(score / ENERGY_SPREAD, -ENERGY_CLIP, ENERGY_CLIP)
            score = np.maximum(score, 0)
            shifted = context.copy()
            shifted[:, 1] = context[:, 1] + offset * score
            moved.append((name, frames, shifted))
        splits[split] = moved
    return FCRBMData(data.codec, splits)


def epoch_examples(context: np.ndarray, balance: bool) -> np.ndarray:
    """Indices of the examples of one epoch.

    Each once, or with ``balance`` each repeated so that every valence/arousal point of the data has
    about as many as the largest.

    Args:
        context: ``(M, 2)`` context of every training example.
        balance: weigh the valence/arousal points alike.

    Returns:
        ``(M',)`` example indices (``M' >= M``), in example order.
    """
    index = np.arange(len(context))
    if not balance or not len(context):
        return index
    _, group, counts = np.unique(context, axis=0, return_inverse=True, return_counts=True)
    repeats = np.maximum(1, np.round(counts.max() / counts)).astype(int)
    return np.repeat(index, repeats[group.ravel()])


def stable_grid() -> torch.Tensor:
    """``(G, 2)`` the valence/arousal grid of :data:`STABLE_AXIS`."""
    axis = torch.tensor(STABLE_AXIS)
    return torch.cartesian_prod(axis, axis)


def stable_corners() -> torch.Tensor:
    """``(5, 2)`` the corners and the centre of :func:`stable_grid`.

    ``(5, 2)`` the corners and the centre of :func:`stable_grid` (the cheap check between
    epochs).
    """
    low, mid, high = STABLE_AXIS[0], STABLE_AXIS[len(STABLE_AXIS) // 2], STABLE_AXIS[-1]
    return torch.tensor([[low, low], [low, high], [high, low], [high, high], [mid, mid]])


def one_step_error(model: FCRBM, v: torch.Tensor, past: torch.Tensor, context: torch.Tensor,
                   seed: int = 0, batch: int = 4096) -> float:
    """Mean squared error of frames generated one step ahead from the true past."""
    if not len(v):
        return math.nan
    gen = torch.Generator().manual_seed(seed)
    total = 0.0
    for a in range(0, len(v), batch):
        out = model.generate(past[a:a + batch], context[a:a + batch], steps=1, generator=gen)
        total += float(((out[:, 0] - v[a:a + batch]) ** 2).sum())
    return total / v.numel()


@dataclass
class FCRBMTrainResult:
    """What :func:`train_fcrbm` leaves.

    The model after the last epoch, one dict per epoch (:data:`CSV_COLUMNS`), the output folder and
    the best validation one-step error.
    """

    model: FCRBM
    codec: FrameCodec
    history: list[dict[str, float]]
    out_dir: Path
    best_val: float


def train_fcrbm(
    config: FCRBMConfig,
    settings: FCRBMTrainSettings,
    progress: bool = True,
    out_dir: str | Path = Path("models/fcrbm"),
    resume: bool = False,
    seed: int = 0,
    *,
    data: FCRBMData | None = None,
    on_batch: Callable[[int, int], None] | None = None,
) -> FCRBMTrainResult:
    """Train the FCRBM; write ``last.pt``, ``best.pt`` and ``log.csv`` to ``out_dir``.

    Args:
        config: sizes and CD settings; ``visible`` is replaced by the data's ``D``.
        settings: the training settings.
        progress: progress bars on stderr.
        out_dir: output folder (created).
        resume: continue from ``out_dir / "last.pt"`` up to ``settings.epochs``.
        seed: seed of initialization, batch order and hidden samples.
        data: the encoded splits, when already loaded (:func:`load_fcrbm_data`).
        on_batch: called as ``on_batch(epoch, batch)`` after every update (tests).

    Raises:
        ConfigError: ``resume`` without a last checkpoint or with other settings.
        KeyboardInterrupt: Ctrl-C; ``last.pt`` keeps the last finished epoch.
    """
    out_dir = Path(out_dir)
    last_path = training_paths(out_dir, resume)
    data = data if data is not None else load_fcrbm_data(settings, progress)
    config = replace(config, visible=data.codec.dim, seed=seed)
    v, past, ctx = data.examples("train", config.order)
    if not len(v):
        raise DataError(f"no training clip is longer than the order {config.order}")
    val = data.examples("val", config.order)
    rng = seed_everything(seed)
    gen = torch.Generator().manual_seed(seed)
    model = FCRBM(config)
    log = TrainingLog()
    if resume:
        _, _, ckpt = load_fcrbm_checkpoint(last_path)
        # Settings added since a checkpoint was written take their defaults.
        saved = {"config": FCRBMConfig.from_dict(ckpt["config"]).to_dict(),
                 "train": FCRBMTrainSettings().to_dict() | ckpt["train"],
                 "seed": ckpt.get("seed")}
        check_resumable(last_path, saved, config.to_dict(), settings.to_dict(), seed)
        model.load_state_dict(ckpt["state"])
        model._velocity = dict(ckpt["velocity"])
        restore_rng_state(rng, ckpt["rng"], gen)
        log = resumed_log(ckpt)

    def checkpoint(epoch: int, state: dict[str, Any]) -> dict[str, Any]:
        return {
            "kind": KIND, "config": config.to_dict(), "train": settings.to_dict(),
            "codec": data.codec.to_dict(), "state": model.state_dict(),
            "velocity": dict(model._velocity), "epoch": epoch, "rng": state,
            "best_val": log.best_val, "history": log.history, "seed": seed,
        }

    pool = epoch_examples(ctx.numpy(), settings.balance_contexts)
    if settings.low_arousal_weight > 1:
        low = ctx.numpy()[pool, 1] <= EDGE_AROUSAL[0]
        pool = np.sort(np.concatenate([pool] + [pool[low]] * (settings.low_arousal_weight - 1)))
    if settings.edge_energy:
        moved = edge_energy_contexts(data, settings.edge_energy)
        ctx = moved.examples("train", config.order)[2]
        val = moved.examples("val", config.order)
    n_batches = math.ceil(len(pool) / settings.batch_size)
    corners = stable_corners()

    def run_epoch(epoch: int, batch_done: Callable[[str], None]) -> EpochOutcome:
        order = pool[rng.permutation(len(pool))]
        errors = []
        for k in range(n_batches):
            idx = torch.from_numpy(order[k * settings.batch_size:(k + 1) * settings.batch_size])
            p = past[idx]
            if settings.past_noise:
                p = p + settings.past_noise * torch.randn(p.shape, generator=gen)
            z = ctx[idx]
            if settings.context_noise:
                z = (z + settings.context_noise * torch.randn(z.shape, generator=gen)).clamp_min(
                    MIN_CONTEXT)
            errors.append(model.train_step(v[idx], p, z, gen))
            if settings.project_every and (k + 1) % settings.project_every == 0:
                model.limit_ar_radius(corners, settings.max_ar_radius)
            batch_done(f"reconstruction {np.mean(errors):.4g}")
            if on_batch is not None:
                on_batch(epoch, k)
        radius = model.limit_ar_radius(stable_grid(), settings.max_ar_radius)
        val_error = one_step_error(model, *val, seed=seed)
        train_error = float(np.mean(errors))
        return EpochOutcome(
            {"train_reconstruction": train_error, "val_one_step": val_error,
             "ar_radius": radius},
            val_error if math.isfinite(val_error) else train_error,
            f"reconstruction {train_error:.4g}  one-step {val_error:.4g}  AR radius {radius:.3f}",
        )

    run_epochs(log, settings.epochs, n_batches, out_dir, CSV_COLUMNS, run_epoch, checkpoint,
               lambda: rng_state(rng, gen), progress)
    model.eval()
    return FCRBMTrainResult(model, data.codec, log.history, out_dir, log.best_or_nan)
