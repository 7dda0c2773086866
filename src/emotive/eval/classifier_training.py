"""Training and held-out measurement of the perceived-emotion classifier on real data.

Data: the clips of :attr:`ClassifierConfig.datasets` whose emotion label is one of the
classifier's labels, split by clip with :func:`emotive.data.splits.split_clips` (per data set).
Clips shorter than ``min_seconds`` are left out. Training windows of 2, 3 and 4 seconds (by
default) start every ``stride_seconds``; batches hold windows of one length. The loss is
cross-entropy weighted by the inverse window count of each label, so rare emotions count as
much as common ones. The kept weights are those of the epoch with the best validation
balanced accuracy (ties: lower validation loss, then the later epoch).

The held-out test split of the Bandai data holds only a few clips per emotion, so
:func:`cross_validate` also measures the same recipe by k-fold cross-validation over clips, and
:func:`compare_architectures` runs it for every network of
:data:`~emotive.eval.classifier.ARCHITECTURES` on the same folds with the same seed.

Measurement: every held-out clip is cut into 4-second windows with a 1-second hop (a clip
shorter than 4 s is one window); window accuracy, clip accuracy (the mean probability over the
clip's windows), per-label accuracy, balanced accuracy and the confusion matrix.

Legend: ``T`` frames, ``F`` features, ``B`` windows, ``C`` labels.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
import torch
from rich.console import Console
from rich.progress import track
from torch import nn

from emotive.data.clips import load_clips
from emotive.data.splits import SPLITS, split_clips
from emotive.eval.classifier import (
    ARCHITECTURES,
    ClassifierConfig,
    EmotionClassifier,
    build_net,
    motion_features,
)

#: Length and hop of the held-out windows, seconds.
EVAL_WINDOW_SECONDS = 4.0
EVAL_HOP_SECONDS = 1.0


@dataclass(frozen=True)
class LabelledFeatures:
    """One clip's features and label.

    Attributes:
        name: clip name.
        label: index into the classifier's labels.
        features: ``(T, F)`` features at the classifier's rate.
    """

    name: str
    label: int
    features: np.ndarray


def load_split_features(config: ClassifierConfig, progress: bool = False
                        ) -> dict[str, list[LabelledFeatures]]:
    """Features of every usable clip, by split (``train``, ``val``, ``test``)."""
    out: dict[str, list[LabelledFeatures]] = {s: [] for s in SPLITS}
    need = math.ceil(config.min_seconds * config.fps)
    for dataset in config.datasets:
        clips = [c for c in load_clips(dataset, locomotion=config.locomotion_only,
                                       progress=progress)
                 if c.info.emotion in config.labels]
        for split, members in split_clips(clips).items():
            for clip in members:
                feats = motion_features(clip.motion, config)
                if len(feats) >= need:
                    out[split].append(LabelledFeatures(
                        clip.name, config.labels.index(clip.info.emotion), feats
                    ))
    return out


def _cut(items: list[LabelledFeatures], length: int, stride: int
         ) -> tuple[np.ndarray, np.ndarray]:
    windows, labels = [], []
    for item in items:
        for start in range(0, len(item.features) - length + 1, stride):
            windows.append(item.features[start:start + length])
            labels.append(item.label)
    if not windows:
        return np.zeros((0, length, 0), dtype=np.float32), np.zeros(0, dtype=np.int64)
    return np.stack(windows), np.array(labels, dtype=np.int64)


def _eval_windows(item: LabelledFeatures, config: ClassifierConfig) -> np.ndarray:
    """``(K, L, F)`` held-out windows of one clip."""
    length = min(len(item.features), round(EVAL_WINDOW_SECONDS * config.fps))
    hop = max(1, round(EVAL_HOP_SECONDS * config.fps))
    starts = range(0, len(item.features) - length + 1, hop)
    return np.stack([item.features[s:s + length] for s in starts])


def measure(model: EmotionClassifier, items: list[LabelledFeatures]) -> dict:
    """Held-out results of ``model`` on clips (see the module docstring).

    Returns:
        ``{"windows", "clips", "window_accuracy", "clip_accuracy", "balanced_accuracy",
        "per_label": {label: window accuracy}, "confusion": C x C window counts (rows:
        true label), "labels"}``.
    """
    n = len(model.labels)
    confusion = np.zeros((n, n), dtype=np.int64)
    clip_hits = 0
    for item in items:
        prob = model.predict_features(_eval_windows(item, model.config))
        np.add.at(confusion[item.label], prob.argmax(-1), 1)
        clip_hits += int(prob.mean(0).argmax() == item.label)
    per_label = {
        model.labels[k]: float(confusion[k, k] / confusion[k].sum())
        for k in range(n) if confusion[k].sum()
    }
    windows = int(confusion.sum())
    return {
        "labels": list(model.labels),
        "clips": len(items),
        "windows": windows,
        "window_accuracy": float(np.trace(confusion) / windows) if windows else float("nan"),
        "clip_accuracy": clip_hits / len(items) if items else float("nan"),
        "balanced_accuracy": (
            float(np.mean(list(per_label.values()))) if per_label else float("nan")
        ),
        "per_label": per_label,
        "confusion": confusion.tolist(),
    }


def train_classifier(config: ClassifierConfig | None = None, progress: bool = False,
                     data: dict[str, list[LabelledFeatures]] | None = None) -> EmotionClassifier:
    """Train the classifier on real data and record its validation and test results.

    Args:
        config: settings (default :class:`ClassifierConfig`).
        progress: progress bars on stderr.
        data: features by split, when already loaded (:func:`load_split_features`).

    Returns:
        The classifier with ``metrics["val"]`` and ``metrics["test"]`` from :func:`measure`.
        Deterministic for a config on CPU.
    """
    config = config or ClassifierConfig()
    data = data if data is not None else load_split_features(config, progress)
    if not data["train"]:
        raise ValueError(f"no training clips for labels {config.labels} in {config.datasets}")
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    frames = np.concatenate([item.features for item in data["train"]])
    mean = frames.mean(0)
    std = np.maximum(frames.std(0), 1e-3).astype(np.float32)
    net = build_net(config)
    model = EmotionClassifier(config, net, mean.astype(np.float32), std)

    stride = max(1, round(config.stride_seconds * config.fps))
    lengths = sorted({round(s * config.fps) for s in np.arange(
        config.min_seconds, config.max_seconds + 1e-9, 1.0)})
    sets = [_cut(data["train"], length, stride) for length in lengths]
    sets = [(x, y) for x, y in sets if len(y)]
    counts = np.bincount(np.concatenate([y for _, y in sets]), minlength=len(config.labels))
    weight = np.where(counts > 0, counts.sum() / np.maximum(counts, 1) / len(config.labels), 0.0)
    loss_fn = nn.CrossEntropyLoss(weight=torch.tensor(weight, dtype=torch.float32))
    opt = torch.optim.Adam(net.parameters(), lr=config.learning_rate,
                           weight_decay=config.weight_decay)
    sets = [(torch.from_numpy((x - model.mean) / model.std), torch.from_numpy(y))
            for x, y in sets]

    best: tuple[float, float] | None = None
    best_state = None
    epochs = track(range(config.epochs), description="training classifier",
                   disable=not progress, console=Console(stderr=True), transient=True)
    for _ in epochs:
        net.train()
        batches = [(k, idx) for k, (_, y) in enumerate(sets)
                   for idx in np.array_split(rng.permutation(len(y)),
                                             max(1, len(y) // config.batch_size))]
        for b in rng.permutation(len(batches)):
            k, idx = batches[b]
            x, y = sets[k]
            opt.zero_grad()
            loss = loss_fn(net(x[idx]), y[idx])
            loss.backward()
            opt.step()
        net.eval()
        if data["val"]:
            result = measure(model, data["val"])
            score = (result["balanced_accuracy"], -_loss(model, data["val"], loss_fn))
        else:
            score = (0.0, 0.0)
        # Later epochs win ties (and, without validation clips, the last epoch is kept).
        if best is None or score >= best:
            best = score
            best_state = {k: v.clone() for k, v in net.state_dict().items()}
    assert best_state is not None
    net.load_state_dict(best_state)
    net.eval()
    model.metrics = {split: measure(model, data[split]) for split in ("val", "test")}
    return model


def _loss(model: EmotionClassifier, items: list[LabelledFeatures], loss_fn: nn.Module) -> float:
    with torch.no_grad():
        total = 0.0
        for item in items:
            x = torch.from_numpy((_eval_windows(item, model.config) - model.mean) / model.std)
            y = torch.full((len(x),), item.label, dtype=torch.int64)
            total += float(loss_fn(model.net(x), y)) * len(x)
    return total


def cross_validate(config: ClassifierConfig, folds: int = 5, progress: bool = False,
                   data: dict[str, list[LabelledFeatures]] | None = None) -> dict:
    """K-fold cross-validation over all clips of every split (stratified by label).

    Clips are ordered by label and then by name and dealt to the folds in turn, so every
    fold holds every label. Each fold's model trains on the other folds for the configured
    epochs (no model selection) and is measured on its own fold.

    Returns:
        ``{"architecture", "folds", "window_accuracy", "clip_accuracy", "balanced_accuracy"
        (pooled over the folds' windows), "fold_window_accuracy": [...], "confusion",
        "per_label", "labels", "train_seconds" (mean wall-clock seconds to train one fold's
        model)}``.
    """
    data = data if data is not None else load_split_features(config, progress)
    items = sorted((i for split in SPLITS for i in data[split]), key=lambda i: (i.label, i.name))
    n = len(config.labels)
    confusion = np.zeros((n, n), dtype=np.int64)
    fold_acc, clip_hits, seconds = [], 0, []
    for f in range(folds):
        held = [item for k, item in enumerate(items) if k % folds == f]
        rest = [item for k, item in enumerate(items) if k % folds != f]
        start = time.perf_counter()
        model = train_classifier(config, data={"train": rest, "val": [], "test": []})
        seconds.append(time.perf_counter() - start)
        result = measure(model, held)
        confusion += np.array(result["confusion"], dtype=np.int64)
        fold_acc.append(result["window_accuracy"])
        clip_hits += round(result["clip_accuracy"] * len(held))
    per_label = {config.labels[k]: float(confusion[k, k] / confusion[k].sum())
                 for k in range(n) if confusion[k].sum()}
    return {
        "architecture": config.architecture,
        "labels": list(config.labels),
        "folds": folds,
        "clips": len(items),
        "windows": int(confusion.sum()),
        "window_accuracy": float(np.trace(confusion) / confusion.sum()),
        "clip_accuracy": clip_hits / len(items),
        "balanced_accuracy": float(np.mean(list(per_label.values()))),
        "fold_window_accuracy": fold_acc,
        "per_label": per_label,
        "confusion": confusion.tolist(),
        "train_seconds": float(np.mean(seconds)),
    }


def compare_architectures(config: ClassifierConfig, folds: int = 5, seeds: int = 1,
                          progress: bool = False,
                          data: dict[str, list[LabelledFeatures]] | None = None) -> dict[str, dict]:
    """:func:`cross_validate` of ``config`` with each architecture, on the same folds and seeds.

    Only ``architecture`` and ``seed`` change between the runs (same data and recipe), so the
    differences are the networks' own; several seeds average out the luck of one
    initialization, which moves the CV numbers of this small data set by several points.

    Args:
        config: the recipe; its seed is the first of the seeds.
        folds: cross-validation folds.
        seeds: how many seeds, ``config.seed``, ``config.seed + 1``, ...
        progress: progress bars on stderr while the data loads.
        data: features by split, when already loaded (:func:`load_split_features`).

    Returns:
        ``{architecture: {"seeds", "runs" (one :func:`cross_validate` result per seed),
        "folds", "window_accuracy", "balanced_accuracy", "clip_accuracy", "train_seconds"
        (means over the seeds), "per_label" (means over the seeds)}}`` for every key of
        ``ARCHITECTURES``.
    """
    data = data if data is not None else load_split_features(config, progress)
    out = {}
    for name in ARCHITECTURES:
        ids = [config.seed + k for k in range(seeds)]
        runs = [cross_validate(replace(config, architecture=name, seed=s), folds, data=data)
                for s in ids]
        mean = {key: float(np.mean([r[key] for r in runs])) for key in (
            "window_accuracy", "balanced_accuracy", "clip_accuracy", "train_seconds")}
        out[name] = {
            "seeds": ids, "runs": runs, "folds": folds, **mean,
            "per_label": {label: float(np.mean([r["per_label"][label] for r in runs]))
                          for label in runs[0]["per_label"]},
        }
    return out
