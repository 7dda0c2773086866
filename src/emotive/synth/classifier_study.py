"""Does the synthetic data set help emotion recognition? Two training arms, measured.

The main paper releases "Synthesized Emotive Gaits" (Bhattacharya et al. 2020, section 5.2)
"to facilitate more research in emotion prediction". This study trains the perceived-emotion
classifier's recipe (:mod:`emotive.eval.classifier_training`, the shipped weights' recipe)
twice per seed:

* ``real``: the real training clips only (the recipe as shipped; ``share`` 0);
* ``real+synthetic``: the same recipe, budget (epochs x steps x batch size), seed and real
  clips, with a fixed share of every batch drawn from the synthetic walks
  (:mod:`emotive.synth.classifier_mix`, :mod:`emotive.synth.classifier_data`).

Synthetic walks enter the training split only. Validation (epoch choice, temperature) and
test clips are real and the same in both arms and every seed (the test features are not
augmented; their digest is recorded per run and checked). Each arm is measured on the held-out
real test clips of each data set (:mod:`emotive.synth.classifier_stats`): window accuracy,
balanced accuracy, macro-F1, ECE and the unsure rate; the arms are compared per data set and
pooled (``"all"``) with paired tests over seeds and on the windows pooled over seeds.

Decision rule, fixed before the numbers (:func:`decide`): real+synthetic is *better* only when
it fixes more pooled held-out windows than it breaks with McNemar's exact ``p < alpha``, its
paired clip bootstrap interval of the accuracy difference lies above 0, and its mean window
accuracy is not lower on either data set. Only then would it replace the shipped classifier.

The report (:func:`run_study`) is a JSON object; ``emotive synth classifier-study`` writes it
atomically and prints a one-line summary last on stdout.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from rich.console import Console

from emotive.eval.classifier import ClassifierConfig
from emotive.eval.classifier_training import ClipFeatures, ClipTrack, load_tracks, split_features
from emotive.synth.classifier_data import SynthMix, describe, synthetic_clips
from emotive.synth.classifier_mix import train_mixed
from emotive.synth.classifier_stats import METRICS, compare, held_out
from emotive.synth.recipe import SynthError

#: The two arms, in the order they are trained.
ARMS = ("real", "real+synthetic")
#: Most seeds a study takes.
MAX_SEEDS = 100


def parse_seeds(text: str) -> tuple[int, ...]:
    """Seeds from ``"0,1,2"`` or a range ``"0-4"`` (or both, ``"0-2,7"``).

    Raises:
        SynthError: anything else, a repeated seed, or more than :data:`MAX_SEEDS`.
    """
    seeds: list[int] = []
    for part in str(text).replace(" ", "").split(","):
        m = re.fullmatch(r"(\d+)(?:-(\d+))?", part)
        if m is None or (m[2] is not None and int(m[2]) < int(m[1])):
            raise SynthError(f"--seeds {text!r}: give whole numbers 0 or more, comma-separated, "
                             "or a range, e.g. --seeds 0,1,2 or --seeds 0-4")
        seeds += range(int(m[1]), int(m[2] or m[1]) + 1)
    if len(set(seeds)) != len(seeds) or len(seeds) > MAX_SEEDS:
        raise SynthError(f"--seeds {text!r}: give each seed once, at most {MAX_SEEDS} seeds")
    return tuple(seeds)


@dataclass(frozen=True)
class StudyConfig:
    """Settings of a study.

    Attributes:
        seeds: training seeds; every arm is trained once per seed.
        mix: how synthetic walks enter the second arm (share of each batch, target).
        resamples: resamples of the paired clip bootstrap.
        alpha: significance level of the decision rule.
    """

    seeds: tuple[int, ...] = (0, 1, 2)
    mix: SynthMix = field(default_factory=SynthMix)
    resamples: int = 10_000
    alpha: float = 0.05

    def __post_init__(self) -> None:
        if not self.seeds:
            raise SynthError("--seeds: give at least one seed, e.g. --seeds 0,1,2")
        if self.mix.share <= 0:
            raise SynthError(f"--share {self.mix.share}: the synthetic arm needs a share above "
                             "0 (0 is the real arm)")


def held_out_digest(items: Sequence[ClipFeatures]) -> str:
    """sha256 of the held-out clips' names, labels and features (the same in every arm)."""
    h = hashlib.sha256()
    for item in sorted(items, key=lambda i: (i.dataset, i.name)):
        h.update(f"{item.dataset}/{item.name}/{item.label}/{item.features.shape}".encode())
        h.update(np.ascontiguousarray(item.features).tobytes())
    return h.hexdigest()


def _summary(runs: list[dict], datasets: Sequence[str]) -> dict:
    out: dict[str, Any] = {}
    for d in datasets:
        out[d] = {}
        for m in (*METRICS, "windows"):
            out[d][m] = {}
            for arm in ARMS:
                v = np.array([r["held_out"][d][m] for r in runs if r["arm"] == arm], float)
                out[d][m][arm] = {"mean": float(v.mean()) if len(v) else math.nan,
                                  "sd": float(v.std(ddof=1)) if len(v) > 1 else math.nan,
                                  "values": v.tolist()}
    return out


def decide(paired: dict, summary: dict, datasets: Sequence[str], alpha: float) -> dict:
    """Whether real+synthetic is better on held-out real walks (module docstring rule)."""
    pooled = paired["all"]
    mc, boot = pooled["mcnemar"], pooled["clip_bootstrap"]
    gains = mc["only_b_right"] > mc["only_a_right"] and mc["p"] < alpha
    interval = boot["low"] > 0
    worse = [d for d in datasets if summary[d]["window_accuracy"]["real+synthetic"]["mean"]
             < summary[d]["window_accuracy"]["real"]["mean"]]
    better = bool(gains and interval and not worse)
    reasons = []
    reasons.append(f"pooled windows: real+synthetic right where real was wrong "
                   f"{mc['only_b_right']}, the reverse {mc['only_a_right']}, McNemar p "
                   f"{mc['p']:.3g}")
    reasons.append(f"clip bootstrap of the accuracy difference: {boot['difference']:+.3f} "
                   f"[{boot['low']:+.3f}, {boot['high']:+.3f}]")
    if worse:
        reasons.append("lower mean window accuracy on " + ", ".join(worse))
    return {"better": better, "alpha": alpha,
            "rule": "McNemar p < alpha with more windows fixed than broken, clip bootstrap "
                    "interval above 0, and no data set's mean window accuracy lower",
            "reasons": reasons}


def run_study(synth: str | Path, config: ClassifierConfig, study: StudyConfig,
              progress: bool = False, tracks: Sequence[ClipTrack] | None = None) -> dict:
    """Train both arms for every seed and compare them (module docstring).

    Args:
        synth: a finished synthetic data set folder (``emotive synth --out``).
        config: the classifier's recipe (its ``seed`` is replaced by each study seed).
        study: seeds, mix and test settings.
        progress: progress on stderr (a line per training, bars).
        tracks: the real role tracks (default: :func:`load_tracks` of ``config.datasets``).

    Returns:
        The report: ``"synthetic"`` (folder, recipe, counts), ``"config"``, ``"mix"``,
        ``"seeds"``, ``"test_set"``, ``"runs"`` (per seed and arm: ``held_out`` per data set
        and ``"all"``, validation score inputs, seconds), ``"summary"`` (per data set and
        metric, per arm: mean, sd, values), ``"paired"`` (per data set:
        :func:`emotive.synth.classifier_stats.compare`), ``"decision"`` and ``"seconds"``.

    Raises:
        SynthError: a missing or unfinished folder, or one without the classifier's labels.
        DataError: the real data is missing.
    """
    console = Console(stderr=True, quiet=not progress)
    begin = time.perf_counter()
    torch.set_num_threads(1)
    synth = Path(synth)
    # Fail on a bad folder before the real data is read.
    synthetic_clips(synth, config, replace(study.mix, limit=1, copies=0), 0)
    if tracks is None:
        console.print(f"reading the real clips of {', '.join(config.datasets)} ...")
        tracks = load_tracks(config.datasets, progress)
    datasets = (*config.datasets, "all")
    runs: list[dict] = []
    digests: set[str] = set()
    first_synth: dict = {}
    for seed in study.seeds:
        cfg = replace(config, seed=seed)
        t0 = time.perf_counter()
        data = split_features(tracks, cfg, progress)
        synthetic = synthetic_clips(synth, cfg, study.mix, seed, progress)
        prepare = time.perf_counter() - t0
        first_synth = first_synth or describe(synthetic, cfg.labels)
        digests.add(held_out_digest(data["test"]))
        for arm in ARMS:
            t1 = time.perf_counter()
            model = train_mixed(cfg, data, synthetic if arm != "real" else (), study.mix,
                                progress, description=f"seed {seed}, {arm}")
            train_s = time.perf_counter() - t1
            result = {d: held_out(model, [i for i in data["test"] if i.dataset == d])
                      for d in config.datasets}
            result["all"] = held_out(model, data["test"])
            runs.append({"seed": seed, "arm": arm, "held_out": result,
                         "validation_window_accuracy": model.metrics["val"]["window_accuracy"],
                         "temperature": model.temperature,
                         "synthetic": model.metrics["synthetic"],
                         "train_seconds": train_s, "prepare_seconds": prepare})
            acc = ", ".join(f"{d} {result[d]['window_accuracy']:.3f}" for d in config.datasets)
            console.print(f"seed {seed}, {arm}: held-out window accuracy {acc} "
                          f"({train_s:.0f} s)", highlight=False)
    if len(digests) != 1:
        raise RuntimeError("the held-out clips differ between seeds; the study is not paired")
    summary = _summary(runs, datasets)
    paired = {d: compare([r["held_out"][d] for r in runs if r["arm"] == "real"],
                         [r["held_out"][d] for r in runs if r["arm"] == "real+synthetic"],
                         study.resamples) for d in datasets}
    test = next(r for r in runs if r["arm"] == "real")["held_out"]
    return {
        "study": "classifier trained on real clips vs real clips + synthetic walks",
        "paper": "Bhattacharya et al. 2020, section 5.2 (Synthesized Emotive Gaits)",
        "synthetic": {"folder": str(synth.resolve()), "recipe": _recipe(synth),
                      **first_synth},
        "config": {k: v for k, v in asdict(config).items() if k != "seed"},
        "mix": asdict(study.mix), "seeds": list(study.seeds), "arms": list(ARMS),
        "test_set": {"digest": digests.pop(),
                     **{d: {"labelled_clips": test[d]["clips"], "windows": test[d]["windows"],
                            "all_windows": test[d]["all_windows"]} for d in datasets}},
        "runs": runs, "summary": summary, "paired": paired,
        "decision": decide(paired, summary, config.datasets, study.alpha),
        "seconds": time.perf_counter() - begin,
    }


def _recipe(folder: Path) -> dict:
    """The folder's recipe (its main entries), or ``{}``."""
    try:
        values = json.loads((folder / "recipe.json").read_text())
    except (OSError, ValueError):
        return {}
    keys = ("paths", "emotions", "transitions", "seconds", "seed", "model", "weights")
    return {k: values[k] for k in keys if k in values}


def headline(report: dict) -> dict:
    """The one-line summary: mean window accuracy per arm and data set, the decision."""
    s = report["summary"]
    return {
        "better": report["decision"]["better"],
        "window_accuracy": {arm: {d: round(s[d]["window_accuracy"][arm]["mean"], 4)
                                  for d in s} for arm in ARMS},
        "mcnemar_p": report["paired"]["all"]["mcnemar"]["p"],
        "seeds": report["seeds"], "share": report["mix"]["share"],
        "seconds": round(report["seconds"], 1),
    }
