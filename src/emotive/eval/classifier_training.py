"""Training and held-out measurement of the perceived-emotion classifier on real data.

Data: the locomotion clips of :attr:`ClassifierConfig.datasets` (dataset 1: walk, walk-back,
walk-left, walk-right, run, dash; dataset 2: walk, walk-turn-left, walk-turn-right, run), every
style, split by clip per data set with :func:`emotive.data.splits.split_clips` (seed 0, 10 %
validation, 10 % test per style). Each clip's 21 role positions are computed once and cached
(:func:`load_tracks`, ``$EMOTIVE_HOME/preprocessed/classifier-tracks-*.npz``).

What each clip teaches (:class:`ClipFeatures`):

* the label head: clips whose style is one of the labels (dataset 1 happy, sad, angry and
  normal as neutral; dataset 2 normal as neutral). Dataset 2 has no happy, sad or angry.
* the valence/arousal head: every clip, at its style's point of
  :data:`emotive.data.circumplex.VALENCE_AROUSAL` (some are the project's estimates).
* the shared-style head: clips of the seven styles both data sets hold
  (:data:`~emotive.eval.classifier.SHARED_STYLE_OF`).

Training clips enter as themselves plus :attr:`ClassifierConfig.augment_copies` variants of
:func:`emotive.eval.classifier_augment.augment` (other proportions, layouts, heights, mirror,
frame rates). Each step draws ``batch_size`` windows of one length (``min_seconds`` to
``max_seconds``) from the clips, every (data set, style) group equally likely; the label loss is
cross-entropy weighted so that every label counts alike, plus the valence/arousal squared error
and the style cross-entropy. The kept weights are those of the epoch with the best validation
score (mean of the label and style balanced accuracies; ties: the later epoch). Then the
temperature is fitted on the validation windows (:mod:`emotive.eval.calibration`) and the
embedding statistics of training windows give the unsure distance.

Measurement (:func:`measure`): held-out clips cut into 4-second windows with a 1-second hop (a
clip shorter than 4 s is one window).

Legend: ``T`` frames, ``J`` joint roles, ``F`` features, ``B`` windows, ``C`` labels, ``E``
embedding width.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    track,
)
from torch import nn

from emotive.data.circumplex import VALENCE_AROUSAL
from emotive.data.clips import load_clips, preprocessed_path
from emotive.data.emotion import style_to_label
from emotive.data.splits import SPLITS, assign_splits
from emotive.data.store import emotive_home
from emotive.errors import ConfigError
from emotive.eval.calibration import expected_calibration_error, fit_temperature
from emotive.eval.classifier import (
    SHARED_STYLE_OF,
    ClassifierConfig,
    EmotionClassifier,
    role_track,
    track_features,
)
from emotive.eval.classifier_augment import augment
from emotive.eval.classifier_nets import build_net
from emotive.eval.classifier_probes import joint_noise, spinning_figure
from emotive.io.atomic import atomic_output
from emotive.models.distributed import current_world

#: Length and hop of the held-out windows, seconds.
EVAL_WINDOW_SECONDS = 4.0
EVAL_HOP_SECONDS = 1.0
#: Training windows whose embeddings set the unsure distance.
UNSURE_FIT_WINDOWS = 4096
#: Distinct training window lengths between ``min_seconds`` and ``max_seconds``.
WINDOW_LENGTHS = 5


@dataclass(frozen=True)
class ClipTrack:
    """One clip's role positions and labels.

    Attributes:
        name: clip name.
        dataset: registry name of its data set.
        content: the action.
        style: the data set's style name.
        split: ``"train"``, ``"val"`` or ``"test"``.
        points: ``(T, J, 3)`` float32 role positions, metres, Y up.
        fps: frame rate.
    """

    name: str
    dataset: str
    content: str
    style: str
    split: str
    points: np.ndarray
    fps: float


@dataclass(frozen=True)
class ClipFeatures:
    """One clip's features and targets.

    Attributes:
        name: clip name.
        dataset: registry name of its data set.
        style: the data set's style name.
        label: index into the classifier's labels, or -1 (not a label).
        style_index: index into the shared styles, or -1 (not shared).
        valence_arousal: ``(2,)`` the style's point in the circumplex.
        features: ``(T, F)`` features at the classifier's rate.
        variant: 0 for the clip itself, ``k`` for its ``k``-th augmented variant.
    """

    name: str
    dataset: str
    style: str
    label: int
    style_index: int
    valence_arousal: np.ndarray
    features: np.ndarray
    variant: int = 0


def _tracks_path(dataset: str) -> Path:
    digest = hashlib.sha256(preprocessed_path(dataset).name.encode())
    for module in ("core/roles", "core/motion", "core/skeleton", "eval/classifier"):
        digest.update((Path(__file__).parents[1] / f"{module}.py").read_bytes())
    name = f"classifier-tracks-{dataset}-{digest.hexdigest()[:16]}.npz"
    return emotive_home() / "preprocessed" / name


def load_tracks(datasets: Sequence[str], progress: bool = False) -> list[ClipTrack]:
    """Role tracks of the locomotion clips of ``datasets``, with their splits, cached.

    Returns:
        The tracks, data set by data set, clips by name.
    """
    out = []
    for dataset in datasets:
        path = _tracks_path(dataset)
        clips = load_clips(dataset, locomotion=True, progress=progress)
        parts = assign_splits(clips)
        if not path.exists():
            points = [role_track(c.motion).astype(np.float32) for c in track(
                clips, description=f"role tracks of {dataset} (once)", disable=not progress,
                console=Console(stderr=True), transient=True)]
            with atomic_output(path) as tmp, open(tmp, "wb") as fh:
                np.savez(fh, names=np.array([c.name for c in clips]),
                         lengths=np.array([len(p) for p in points]),
                         points=np.concatenate(points))
        with np.load(path) as z:
            offsets = np.concatenate(([0], np.cumsum(z["lengths"])))
            cached = dict(zip(z["names"].tolist(), np.split(z["points"], offsets[1:-1]),
                              strict=True))
        out += [ClipTrack(c.name, dataset, c.content, c.style, parts[c.name], cached[c.name],
                          c.motion.fps) for c in clips]
    return out


def clip_features(clip: ClipTrack, config: ClassifierConfig, points: np.ndarray | None = None,
                  fps: float | None = None, variant: int = 0) -> ClipFeatures:
    """The targets of a clip with the features of its track (or of its variant ``variant``)."""
    label = style_to_label(clip.style)
    shared = SHARED_STYLE_OF.get(clip.style)
    va = VALENCE_AROUSAL[label]
    return ClipFeatures(
        clip.name, clip.dataset, clip.style,
        config.labels.index(label) if label in config.labels else -1,
        config.style_labels.index(shared) if shared in config.style_labels else -1,
        np.array([va.valence, va.arousal], dtype=np.float32),
        track_features(clip.points if points is None else points,
                       clip.fps if fps is None else fps, config),
        variant,
    )


def split_features(tracks: Sequence[ClipTrack], config: ClassifierConfig, progress: bool = False
                   ) -> dict[str, list[ClipFeatures]]:
    """Features by split; training clips with their augmented variants (seeded by config)."""
    rng = np.random.default_rng(config.seed)
    need = math.ceil(config.min_seconds * config.fps)
    out: dict[str, list[ClipFeatures]] = {s: [] for s in SPLITS}
    for clip in track(list(tracks), description="classifier features", disable=not progress,
                      console=Console(stderr=True), transient=True):
        copies = config.augment_copies if clip.split == "train" else 0
        items = [clip_features(clip, config)]
        for k in range(copies):
            items.append(clip_features(clip, config, *augment(clip.points, clip.fps, rng,
                                                              config.augment), variant=k + 1))
        out[clip.split] += [i for i in items if len(i.features) >= need]
    return out


def _eval_windows(item: ClipFeatures, config: ClassifierConfig) -> np.ndarray:
    """``(K, L, F)`` held-out windows of one clip."""
    length = min(len(item.features), round(EVAL_WINDOW_SECONDS * config.fps))
    hop = max(1, round(EVAL_HOP_SECONDS * config.fps))
    starts = range(0, len(item.features) - length + 1, hop)
    return np.stack([item.features[s:s + length] for s in starts])


def _balanced(confusion: np.ndarray, names: Sequence[str]) -> tuple[float, dict[str, float]]:
    per = {names[k]: float(confusion[k, k] / confusion[k].sum())
           for k in range(len(names)) if confusion[k].sum()}
    return (float(np.mean(list(per.values()))) if per else float("nan")), per


def measure(model: EmotionClassifier, items: Sequence[ClipFeatures]) -> dict:
    """Held-out results of ``model`` on clips (see the module docstring).

    Returns:
        Label results on the clips with a label: ``"clips"``, ``"windows"``,
        ``"window_accuracy"``, ``"clip_accuracy"`` (mean probability over the clip's
        windows), ``"balanced_accuracy"``, ``"per_label"``, ``"confusion"`` (rows: true
        label), ``"ece"`` (10 bins, calibrated) and ``"ece_uncalibrated"``; shared-style
        results on clips of a shared style: ``"style_windows"``, ``"style_accuracy"``,
        ``"style_balanced_accuracy"``, ``"per_style"``; on every clip: ``"va_sign_agreement"``
        (share of windows whose valence and arousal signs both match the style's, styles
        off the axes only), ``"unsure_rate"`` and ``"all_windows"``; ``"labels"``.
    """
    cfg = model.config
    n, s = len(model.labels), len(cfg.style_labels)
    confusion = np.zeros((n, n), dtype=np.int64)
    style_confusion = np.zeros((s, s), dtype=np.int64)
    clip_hits = labelled = 0
    logits, truth, signs, unsure = [], [], [], []
    for item in items:
        out = model.outputs(_eval_windows(item, cfg))
        unsure.append(out["unsure"])
        if item.label >= 0:
            np.add.at(confusion[item.label], out["probabilities"].argmax(-1), 1)
            clip_hits += int(out["probabilities"].mean(0).argmax() == item.label)
            labelled += 1
            logits.append(out["logits"])
            truth.append(np.full(len(out["logits"]), item.label))
        if item.style_index >= 0:
            np.add.at(style_confusion[item.style_index], out["style_logits"].argmax(-1), 1)
        if np.all(np.abs(item.valence_arousal) > 0.05):
            signs.append(np.all(np.sign(out["valence_arousal"])
                                == np.sign(item.valence_arousal), -1))
    balanced, per_label = _balanced(confusion, model.labels)
    style_balanced, per_style = _balanced(style_confusion, cfg.style_labels)
    windows = int(confusion.sum())
    logit = np.concatenate(logits) if logits else np.zeros((0, n))
    y = np.concatenate(truth) if truth else np.zeros(0, dtype=np.int64)
    z = logit / model.temperature
    prob = np.exp(z - z.max(-1, keepdims=True)) if len(z) else z
    prob = prob / prob.sum(-1, keepdims=True) if len(z) else prob
    raw = np.exp(logit - logit.max(-1, keepdims=True)) if len(z) else logit
    raw = raw / raw.sum(-1, keepdims=True) if len(z) else raw
    nan = float("nan")
    return {
        "labels": list(model.labels),
        "clips": labelled,
        "windows": windows,
        "window_accuracy": float(np.trace(confusion) / windows) if windows else nan,
        "clip_accuracy": clip_hits / labelled if labelled else nan,
        "balanced_accuracy": balanced,
        "per_label": per_label,
        "confusion": confusion.tolist(),
        "ece": expected_calibration_error(prob, y),
        "ece_uncalibrated": expected_calibration_error(raw, y),
        "style_labels": list(cfg.style_labels),
        "style_windows": int(style_confusion.sum()),
        "style_accuracy": (float(np.trace(style_confusion) / style_confusion.sum())
                           if style_confusion.sum() else nan),
        "style_balanced_accuracy": style_balanced,
        "per_style": per_style,
        "style_confusion": style_confusion.tolist(),
        "va_sign_agreement": float(np.concatenate(signs).mean()) if signs else nan,
        "all_windows": int(sum(len(u) for u in unsure)),
        "unsure_rate": float(np.concatenate(unsure).mean()) if unsure else nan,
    }


class WindowSampler:
    """Windows drawn from clips, every (data set, style) group equally likely."""

    def __init__(self, items: Sequence[ClipFeatures], config: ClassifierConfig) -> None:
        self.items = list(items)
        self.lengths = np.unique(np.round(np.linspace(
            config.min_seconds, config.max_seconds, WINDOW_LENGTHS) * config.fps).astype(int))
        groups: dict[tuple[str, str], int] = {}
        for item in self.items:
            groups[(item.dataset, item.style)] = groups.get((item.dataset, item.style), 0) + 1
        self.weight = np.array([1.0 / groups[(i.dataset, i.style)] for i in self.items])
        self.sizes = np.array([len(i.features) for i in self.items])
        n = len(config.labels)
        share = np.zeros(n)
        for item, w in zip(self.items, self.weight, strict=True):
            if item.label >= 0:
                share[item.label] += w
        self.label_weight = np.where(share > 0, share.sum() / np.maximum(share, 1e-12) / n, 0.0)

    def draw(self, rng: np.random.Generator, batch: int) -> tuple[np.ndarray, ...]:
        """``(B, L, F)`` windows and their ``(B,)`` labels, ``(B,)`` styles, ``(B, 2)`` points."""
        length = int(rng.choice(self.lengths))
        fits = self.sizes >= length
        w = self.weight * fits
        picks = rng.choice(len(self.items), batch, p=w / w.sum())
        x = np.empty((batch, length, self.items[0].features.shape[1]), dtype=np.float32)
        for b, k in enumerate(picks):
            start = rng.integers(0, self.sizes[k] - length + 1)
            x[b] = self.items[k].features[start:start + length]
        chosen = [self.items[k] for k in picks]
        return (x, np.array([i.label for i in chosen]), np.array([i.style_index for i in chosen]),
                np.stack([i.valence_arousal for i in chosen]))


def selection_score(result: dict) -> float:
    """The score that picks the best epoch: mean of the emotion and style balanced accuracies."""
    parts = [v for v in (result["balanced_accuracy"], result["style_balanced_accuracy"])
             if not math.isnan(v)]
    return float(np.mean(parts)) if parts else 0.0


def _training_embeddings(model: EmotionClassifier, sampler: WindowSampler,
                         rng: np.random.Generator) -> np.ndarray:
    """``(N, E)`` embeddings of :data:`UNSURE_FIT_WINDOWS` training windows of every length."""
    batches = math.ceil(UNSURE_FIT_WINDOWS / model.config.batch_size)
    return np.concatenate([
        model.outputs(sampler.draw(rng, model.config.batch_size)[0])["embedding"]
        for _ in range(batches)]).astype(np.float64)


def fit_unsure(model: EmotionClassifier, sampler: WindowSampler, rng: np.random.Generator) -> None:
    """Embedding mean and precision of training windows; the distance at the quantile.

    The quantile is taken over fresh training windows (other draws than the fit's), batch by
    batch, so every window length counts.
    """
    e = _training_embeddings(model, sampler, rng)
    cov = np.cov(e, rowvar=False)
    cov += np.eye(len(cov)) * 1e-3 * np.trace(cov) / len(cov)
    model.embedding_mean = e.mean(0)
    model.embedding_precision = np.linalg.inv(cov)
    d = _training_embeddings(model, sampler, rng) - model.embedding_mean
    distance = np.sqrt(np.einsum("ne,ef,nf->n", d, model.embedding_precision, d))
    model.unsure_distance = float(np.quantile(distance, model.config.unsure_quantile))


def _calibration_windows(item: ClipFeatures, config: ClassifierConfig) -> list[np.ndarray]:
    """Windows of every training length (1 s hop) of a clip, ``[(K, L, F), ...]``."""
    hop = max(1, round(EVAL_HOP_SECONDS * config.fps))
    out = []
    for seconds in np.linspace(config.min_seconds, config.max_seconds, WINDOW_LENGTHS):
        length = round(seconds * config.fps)
        if len(item.features) >= length:
            out.append(np.stack([item.features[s:s + length]
                                 for s in range(0, len(item.features) - length + 1, hop)]))
    return out


def calibrate_temperature(model: EmotionClassifier, items: Sequence[ClipFeatures]) -> None:
    """Fit the temperature on the labelled validation windows of every length (0.8-4 s).

    Short windows are where the network errs; 4 s windows alone are often all right on the
    few validation clips, which would drive the temperature to its floor.
    """
    logits, labels = [], []
    for item in items:
        if item.label >= 0:
            for windows in _calibration_windows(item, model.config):
                out = model.outputs(windows)
                logits.append(out["logits"])
                labels.append(np.full(len(out["logits"]), item.label))
    if logits:
        model.temperature = fit_temperature(np.concatenate(logits), np.concatenate(labels))


def train_classifier(config: ClassifierConfig | None = None, progress: bool = False,
                     data: dict[str, list[ClipFeatures]] | None = None,
                     description: str = "classifier") -> EmotionClassifier:
    """Train the classifier on real data, calibrate it and record its held-out results.

    Args:
        config: settings (default :class:`ClassifierConfig`).
        progress: progress bars (epochs and batches) and one line per epoch on stderr.
        data: features by split, when already made (:func:`split_features`).
        description: what is trained, for the progress output.

    Returns:
        The classifier with ``metrics["val"]``, ``metrics["test"]`` and ``metrics["test_by_
        dataset"]`` from :func:`measure` (on process 0 of several: the others' model is
        unfinished, :mod:`emotive.models.distributed`). Deterministic for a config on CPU.
    """
    config, world = config or ClassifierConfig(), current_world()
    progress = progress and world.is_main
    if data is None:
        data = split_features(load_tracks(config.datasets, progress), config, progress)
    if not data["train"]:
        raise ValueError(f"no training clips in {config.datasets}")
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed + 1)
    frames = np.concatenate([item.features for item in data["train"]])
    mean = frames.mean(0).astype(np.float32)
    std = np.maximum(frames.std(0), 1e-3).astype(np.float32)
    net = build_net(config)
    model = EmotionClassifier(config, net, mean, std)
    sampler = WindowSampler(data["train"], config)
    label_loss = nn.CrossEntropyLoss(
        weight=torch.tensor(sampler.label_weight, dtype=torch.float32), ignore_index=-1)
    style_loss = nn.CrossEntropyLoss(ignore_index=-1)
    opt = torch.optim.Adam(net.parameters(), lr=config.learning_rate,
                           weight_decay=config.weight_decay)
    best: float | None = None
    best_state = None
    bars = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TextColumn("{task.fields[info]}"),
                    console=Console(stderr=True), disable=not progress, transient=True)
    with bars, world.batch_dropout(net, config.batch_size):
        epochs_task = bars.add_task(f"{description}: epochs", total=config.epochs, info="")
        batch_task = bars.add_task("batches", total=config.steps_per_epoch, info="")
        for epoch in range(config.epochs):
            bars.reset(batch_task, total=config.steps_per_epoch)
            score = _train_epoch(model, sampler, data["val"], opt, (label_loss, style_loss), rng,
                                 lambda: bars.advance(batch_task))
            # Later epochs win ties (and, without validation clips, the last epoch is kept).
            improved = best is None or score >= best
            if improved:
                best = score
                best_state = {k: v.clone() for k, v in net.state_dict().items()}
            summary = f"validation score {score:.3f}" + ("  (best)" if improved else "")
            bars.update(epochs_task, advance=1, info=summary)
            if progress:
                bars.console.print(f"{description}: epoch {epoch + 1}/{config.epochs}: {summary}")
    assert best_state is not None
    if not world.is_main:
        return model
    net.load_state_dict(best_state)
    net.eval()
    calibrate_temperature(model, data["val"])
    fit_unsure(model, sampler, rng)
    model.metrics = {split: measure(model, data[split]) for split in ("val", "test")}
    model.metrics["test_by_dataset"] = {
        d: measure(model, [i for i in data["test"] if i.dataset == d]) for d in config.datasets
    }
    return model


def _train_epoch(model: EmotionClassifier, sampler: WindowSampler, val: Sequence[ClipFeatures],
                 opt: torch.optim.Optimizer, losses: tuple[nn.Module, nn.Module],
                 rng: np.random.Generator, batch_done: Callable[[], None]) -> float:
    """One epoch of updates, then the validation score (0 without clips)."""
    config, net, mean, std = model.config, model.net, model.mean, model.std
    label_loss, style_loss, world = *losses, current_world()
    net.train()
    for _ in range(config.steps_per_epoch):
        x, y, style, va = sampler.draw(rng, config.batch_size)
        mine, part = world.split(len(y), sampler.label_weight[y] * (y >= 0), style >= 0)
        x, y, style, va = x[mine], y[mine], style[mine], va[mine]
        _, logits, va_out, style_out = net.heads(torch.from_numpy((x - mean) / std))
        y, style, va = torch.from_numpy(y), torch.from_numpy(style), torch.from_numpy(va)
        loss = part[0] * config.valence_arousal_weight * ((va_out - va) ** 2).mean()
        if (y >= 0).any():
            loss = loss + part[1] * label_loss(logits, y)
        if (style >= 0).any():
            loss = loss + part[2] * config.style_weight * style_loss(style_out, style)
        opt.zero_grad()
        loss.backward()
        world.sum_gradients(net.parameters(), 1.0)
        opt.step()
        batch_done()
    net.eval()
    return selection_score(measure(model, val)) if val and world.is_main else 0.0


def train_on_one_studio(config: ClassifierConfig, data: dict[str, list[ClipFeatures]],
                        dataset: str, progress: bool = False) -> EmotionClassifier:
    """The recipe of ``config`` trained on the clips of one data set of ``data`` only."""
    cfg = replace(config, datasets=(dataset,))
    return train_classifier(cfg, progress, data={s: [i for i in v if i.dataset == dataset]
                                                 for s, v in data.items()},
                            description=f"{dataset} alone")


def leave_one_studio_out(config: ClassifierConfig, data: dict[str, list[ClipFeatures]],
                         progress: bool = False
                         ) -> tuple[dict[str, dict], dict[str, EmotionClassifier]]:
    """Train on one data set, measure on every clip of the other's shared styles.

    Args:
        config: the recipe (its two ``datasets`` are the studios).
        data: features of both by split (:func:`split_features`).
        progress: progress output of each training on stderr.

    Returns:
        ``{"train-on-<a>": {"trained_on", "tested_on", "result" (:func:`measure` over the
        other data set's clips of shared styles, every split, unaugmented),
        "mean_probabilities" ({style: {label: mean probability}} over those windows)}}`` and
        the models by trained data set.
    """
    out, models = {}, {}
    for trained, tested in (config.datasets, config.datasets[::-1]):
        model = models[trained] = train_on_one_studio(config, data, trained, progress)
        other = [i for s in ("train", "val", "test") for i in data[s]
                 if i.dataset == tested and i.style in SHARED_STYLE_OF and not i.variant]
        out[f"train-on-{trained}"] = {
            "trained_on": trained, "tested_on": tested, "result": measure(model, other),
            "mean_probabilities": mean_probabilities(model, other),
        }
    return out, models


def mean_probabilities(model: EmotionClassifier, items: Sequence[ClipFeatures]
                       ) -> dict[str, dict[str, float]]:
    """``{style: {label: mean calibrated probability}}`` over the held-out windows of items."""
    by_style: dict[str, list[np.ndarray]] = {}
    for item in items:
        by_style.setdefault(item.style, []).append(
            model.predict_features(_eval_windows(item, model.config)))
    return {s: dict(zip(model.labels, map(float, np.concatenate(p).mean(0)), strict=True))
            for s, p in sorted(by_style.items())}


def unsure_rates(model: EmotionClassifier, tracks: Sequence[ClipTrack], seed: int = 0) -> dict:
    """Share of unsure windows on held-out clips and on clearly out-of-distribution inputs.

    Held-out: the test-split clips of every data set of ``tracks``, in 4 s and in 0.8 s
    windows (1 s hop). Out of distribution (:mod:`emotive.eval.classifier_probes`), one of
    each per test clip at 30 fps: its first pose standing still and spinning one turn a
    second for 6 s, and 6 s of random joint noise; 4 s windows.

    Returns:
        ``{"clips", "held_out": {"4s": rate, "0.8s": rate}, "held_out_by_dataset":
        {dataset: 4 s rate}, "spinning": rate, "joint_noise": rate}``.
    """
    rng = np.random.default_rng(seed)
    test = [t for t in tracks if t.split == "test"]
    cfg = model.config

    def rate(points: np.ndarray, fps: float, window: float) -> np.ndarray:
        feats = track_features(points, fps, cfg)
        return model.outputs(model.windows(feats, window, EVAL_HOP_SECONDS)[1])["unsure"]

    held = {w: [rate(t.points, t.fps, w) for t in test] for w in (EVAL_WINDOW_SECONDS, 0.8)}
    by_dataset = {d: float(np.concatenate([u for u, t in zip(held[EVAL_WINDOW_SECONDS], test,
                                                            strict=True) if t.dataset == d]).mean())
                  for d in dict.fromkeys(t.dataset for t in test)}
    spin = [rate(spinning_figure(t.points[0], 30.0, 6.0), 30.0, EVAL_WINDOW_SECONDS) for t in test]
    noise = [rate(joint_noise(rng, 180), 30.0, EVAL_WINDOW_SECONDS) for _ in test]
    return {
        "clips": len(test),
        "held_out": {f"{w:g}s": float(np.concatenate(u).mean()) for w, u in held.items()},
        "held_out_by_dataset": by_dataset,
        "spinning": float(np.concatenate(spin).mean()),
        "joint_noise": float(np.concatenate(noise).mean()),
    }


def studio_proxy(model: EmotionClassifier, tracks: Sequence[ClipTrack], dataset: str,
                 variants: int = 2, seed: int = 1234) -> dict[str, dict[str, float]]:
    """Mean probabilities of ``dataset``'s exhausted, normal and active clips on other rigs.

    Every such clip is put on ``variants`` random proportions, layouts, heights, mirror images
    and frame rates (:func:`emotive.eval.classifier_augment.augment`, seeded by ``seed``, other
    draws than training's) before it is judged in 4 s windows.

    Returns:
        ``{style: {label: mean calibrated probability}}``.
    """
    rng = np.random.default_rng(seed)
    items = [clip_features(t, model.config, *augment(t.points, t.fps, rng, model.config.augment),
                           variant=k + 1)
             for t in tracks if t.dataset == dataset and t.style in ("exhausted", "normal",
                                                                     "active")
             for k in range(variants)]
    return mean_probabilities(model, items)


def read_config(path: str | Path) -> ClassifierConfig:
    """A :class:`ClassifierConfig` from a TOML file of its fields (``[augment]`` a table).

    Raises:
        ConfigError: the file is missing, not TOML, or holds an unknown or bad field.
    """
    path = Path(path)
    try:
        values = tomllib.loads(path.read_text())
    except OSError as exc:
        raise ConfigError(f"classifier config {path} cannot be read ({exc.strerror}): "
                          "check the path") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"classifier config {path} is not valid TOML ({exc})") from None
    try:
        return ClassifierConfig.from_dict(values)
    except TypeError as exc:
        raise ConfigError(f"classifier config {path}: {exc}; see configs/classifier.toml for "
                          "the fields") from None
