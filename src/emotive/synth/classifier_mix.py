"""The perceived-emotion classifier's recipe trained on real clips plus synthetic walks.

:func:`train_mixed` is :func:`emotive.eval.classifier_training.train_classifier` with one
change: every training batch of ``B`` windows holds ``n = round(share * B)`` windows of
synthetic walks (:mod:`emotive.synth.classifier_data`; the main paper's augmented data set,
Bhattacharya et al. 2020, section 5.2) and ``B - n`` real windows, so both arms of a
comparison get the same budget (epochs x steps x batch size) and the same real draws when
``share`` is 0: then it *is* the real-only recipe, weight for weight (a test checks it).

Per step (:class:`MixedSampler`): the real sampler of the recipe draws ``B - n`` windows
(one window length for the step, every (data set, style) group equally likely); then ``n``
synthetic clips are drawn uniformly among those at least that long, each with a uniform
start. A synthetic window's targets are its frames' means of the walk's emotion weights and
valence/arousal (the emotion at the window; :mod:`~emotive.synth.classifier_data`).

Loss (the recipe's, extended). The label term is one weighted mean over the labelled windows:
a real window weighs its label's class weight (the recipe's weighted cross-entropy, whose
weights average 1 over the real draws), a synthetic window weighs 1 and its loss is the
cross-entropy against its soft target ``q`` (``-sum_c q_c log p_c``; one-hot for
``target = "heaviest"``). The valence/arousal squared error is a mean over every window; the
style cross-entropy sees the real windows of shared styles only. The features are
standardized with the real training frames' statistics in both arms.

Everything after training is the recipe's: the epoch with the best validation score on the
real validation clips, the temperature fitted on them, and the unsure distance from the
embeddings of training windows drawn as training drew them (so synthetic windows count at
``share``). Validation and test clips are real only.

Legend: ``B`` windows per batch, ``L`` window frames, ``F`` features, ``C`` labels.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from torch import nn
from torch.nn import functional

from emotive.eval.classifier import ClassifierConfig, EmotionClassifier
from emotive.eval.classifier_nets import build_net
from emotive.eval.classifier_training import (
    ClipFeatures,
    WindowSampler,
    calibrate_temperature,
    fit_unsure,
    measure,
    selection_score,
)
from emotive.synth.classifier_data import SynthClip, SynthMix
from emotive.synth.recipe import SynthError


class MixedSampler:
    """Training windows: the recipe's real draws, then a share of synthetic windows.

    Args:
        real: the real training clips.
        synthetic: the synthetic training clips (empty: the real-only recipe).
        config: the classifier's recipe.
        mix: the share and the target (:class:`~emotive.synth.classifier_data.SynthMix`).
    """

    def __init__(self, real: Sequence[ClipFeatures], synthetic: Sequence[SynthClip],
                 config: ClassifierConfig, mix: SynthMix) -> None:
        self.real = WindowSampler(real, config)
        self.synthetic = list(synthetic)
        self.share = mix.share if self.synthetic else 0.0
        self.hard = mix.target == "heaviest"
        self.labels = len(config.labels)
        self.label_weight = self.real.label_weight
        self.sizes = np.array([len(c.features) for c in self.synthetic], dtype=np.int64)

    def synthetic_rows(self, batch: int) -> int:
        """``n``, the synthetic windows of a batch of ``batch``."""
        return round(self.share * batch)

    def draw(self, rng: np.random.Generator, batch: int) -> tuple[np.ndarray, ...]:
        """One batch, real rows first.

        Returns:
            ``(B, L, F)`` windows, ``(B,)`` hard labels (-1: none; synthetic rows are -1),
            ``(B,)`` shared styles (-1: none), ``(B, 2)`` valence/arousal targets and
            ``(B, C)`` soft label targets (zero rows for real windows).
        """
        n = self.synthetic_rows(batch)
        x, y, style, va = self.real.draw(rng, batch - n)
        length = x.shape[1]
        fits = np.flatnonzero(self.sizes >= length) if n else np.zeros(0, dtype=np.int64)
        if not len(fits):
            # No synthetic walk is this long (never for walks of 4 s or more): all real.
            if n:
                more = self.real.draw(rng, n)
                x, y, style, va = (np.concatenate((a, b)) for a, b in
                                   zip((x, y, style, va), more, strict=True))
            return x, y, style, va, np.zeros((len(y), self.labels), dtype=np.float32)
        picks = fits[rng.integers(0, len(fits), n)]
        xs = np.empty((n, length, x.shape[2]), dtype=np.float32)
        qs = np.empty((n, self.labels), dtype=np.float32)
        vas = np.empty((n, 2), dtype=np.float32)
        for b, k in enumerate(picks):
            clip = self.synthetic[k]
            start = rng.integers(0, self.sizes[k] - length + 1)
            xs[b] = clip.features[start:start + length]
            qs[b] = clip.emotion[start:start + length].mean(0)
            vas[b] = clip.valence_arousal[start:start + length].mean(0)
        if self.hard:
            qs = np.eye(self.labels, dtype=np.float32)[qs.argmax(-1)]
        else:
            qs /= qs.sum(-1, keepdims=True)
        q = np.concatenate((np.zeros((len(y), self.labels), dtype=np.float32), qs))
        return (np.concatenate((x, xs)), np.concatenate((y, np.full(n, -1, dtype=y.dtype))),
                np.concatenate((style, np.full(n, -1, dtype=style.dtype))),
                np.concatenate((va, vas.astype(va.dtype))), q)


def label_loss(logits: torch.Tensor, y: torch.Tensor, q: torch.Tensor,
               weight: torch.Tensor, hard_loss: nn.Module) -> torch.Tensor | None:
    """The label term of a mixed batch (module docstring), ``None`` without labelled rows.

    Args:
        logits: ``(B, C)`` label logits.
        y: ``(B,)`` hard labels of real rows (-1: none).
        q: ``(B, C)`` soft targets of synthetic rows (zero rows elsewhere).
        weight: ``(C,)`` class weights of the real labels.
        hard_loss: the recipe's weighted cross-entropy (used as it is without synthetic rows).
    """
    soft = q.sum(-1) > 0
    real = y >= 0
    if not soft.any():
        return hard_loss(logits, y) if real.any() else None
    logp = functional.log_softmax(logits, -1)
    total = -(q[soft] * logp[soft]).sum()
    mass = torch.tensor(float(soft.sum()))
    if real.any():
        w = weight[y[real]]
        total = total + (w * functional.nll_loss(logp[real], y[real], reduction="none")).sum()
        mass = mass + w.sum()
    return total / mass


def train_mixed(config: ClassifierConfig, data: dict[str, list[ClipFeatures]],
                synthetic: Sequence[SynthClip] = (), mix: SynthMix | None = None,
                progress: bool = False, description: str = "classifier") -> EmotionClassifier:
    """Train the recipe on real training clips and a share of synthetic walks.

    Args:
        config: the classifier's recipe.
        data: real features by split (:func:`emotive.eval.classifier_training.split_features`).
        synthetic: synthetic training clips (none: the real-only recipe).
        mix: the share and target (default :class:`SynthMix`; ignored without clips).
        progress: progress bars on stderr.
        description: what is trained, for the progress output.

    Returns:
        The classifier with ``metrics["val"]``, ``metrics["test"]`` and
        ``metrics["test_by_dataset"]`` (:func:`emotive.eval.classifier_training.measure` on
        real clips) and ``metrics["synthetic"]`` (share, target, clips). On one process, for
        a config on CPU, deterministic; with no synthetic clips, the same weights as
        ``train_classifier(config, data=data)``.

    Raises:
        SynthError: a synthetic clip among the real splits.
    """
    mix = mix or SynthMix()
    if any(getattr(i, "dataset", "") == "synthetic" for s in data.values() for i in s):
        raise SynthError("synthetic clips belong in the `synthetic` argument, not in the real "
                         "splits (validation and test stay real)")
    if not data["train"]:
        raise ValueError(f"no training clips in {config.datasets}")
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed + 1)
    frames = np.concatenate([item.features for item in data["train"]])
    mean = frames.mean(0).astype(np.float32)
    std = np.maximum(frames.std(0), 1e-3).astype(np.float32)
    net = build_net(config)
    model = EmotionClassifier(config, net, mean, std)
    sampler = MixedSampler(data["train"], synthetic, config, mix)
    hard_loss = nn.CrossEntropyLoss(
        weight=torch.tensor(sampler.label_weight, dtype=torch.float32), ignore_index=-1)
    style_loss = nn.CrossEntropyLoss(ignore_index=-1)
    opt = torch.optim.Adam(net.parameters(), lr=config.learning_rate,
                           weight_decay=config.weight_decay)
    best: float | None = None
    best_state = None
    bars = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), console=Console(stderr=True), disable=not progress,
                    transient=True)
    with bars:
        task = bars.add_task(f"{description}: steps", total=config.epochs * config.steps_per_epoch)
        for _ in range(config.epochs):
            score = _epoch(model, sampler, data["val"], opt, (hard_loss, style_loss), rng,
                           lambda: bars.advance(task))
            # Later epochs win ties, as in the recipe.
            if best is None or score >= best:
                best = score
                best_state = {k: v.clone() for k, v in net.state_dict().items()}
    assert best_state is not None
    net.load_state_dict(best_state)
    net.eval()
    calibrate_temperature(model, data["val"])
    fit_unsure(model, sampler, rng)
    model.metrics = {split: measure(model, data[split]) for split in ("val", "test")}
    model.metrics["test_by_dataset"] = {
        d: measure(model, [i for i in data["test"] if i.dataset == d]) for d in config.datasets
    }
    model.metrics["synthetic"] = {
        "share": sampler.share, "target": mix.target, "clips": len(sampler.synthetic),
        "walks": len({c.sample_id for c in sampler.synthetic}),
        "windows_per_batch": sampler.synthetic_rows(config.batch_size),
    }
    return model


def _epoch(model: EmotionClassifier, sampler: MixedSampler, val: Sequence[ClipFeatures],
           opt: torch.optim.Optimizer, losses: tuple[nn.Module, nn.Module],
           rng: np.random.Generator, step_done: Callable[[], None]) -> float:
    """One epoch of updates, then the validation score (0 without validation clips).

    The loss terms are written as the recipe's ``_train_epoch`` writes them on one process,
    so that the real-only arm matches it bit for bit.
    """
    config, net, mean, std = model.config, model.net, model.mean, model.std
    hard_loss, style_loss = losses
    weight = torch.tensor(sampler.label_weight, dtype=torch.float32)
    net.train()
    for _ in range(config.steps_per_epoch):
        x, y, style, va, q = sampler.draw(rng, config.batch_size)
        _, logits, va_out, style_out = net.heads(torch.from_numpy((x - mean) / std))
        y, style, va, q = (torch.from_numpy(a) for a in (y, style, va, q))
        loss = 1.0 * config.valence_arousal_weight * ((va_out - va) ** 2).mean()
        label = label_loss(logits, y, q, weight, hard_loss)
        if label is not None:
            loss = loss + 1.0 * label
        if (style >= 0).any():
            loss = loss + 1.0 * config.style_weight * style_loss(style_out, style)
        opt.zero_grad()
        loss.backward()
        opt.step()
        step_done()
    net.eval()
    return selection_score(measure(model, val)) if val else 0.0
