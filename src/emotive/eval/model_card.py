"""Model cards: what a committed model was trained on, how, and what it measured."""

from __future__ import annotations

from dataclasses import asdict

from emotive.data.registry import get_dataset
from emotive.eval.classifier import EmotionClassifier

#: How the card's first sentence names each architecture.
_NETWORKS = {
    "tcn": "A temporal convolution network",
    "stgcn": "A spatial-temporal graph convolution network over the joint-role skeleton "
             "(in the spirit of STEP and ST-GCN)",
}


def _table(result: dict) -> list[str]:
    labels = result["labels"]
    lines = [
        f"- windows: {result['windows']} from {result['clips']} clips",
        f"- window accuracy: {result['window_accuracy']:.3f}; clip accuracy: "
        f"{result['clip_accuracy']:.3f}; balanced accuracy: {result['balanced_accuracy']:.3f}",
        "- per label: " + ", ".join(f"{k} {v:.2f}" for k, v in result["per_label"].items()),
        "",
        "| true \\ perceived | " + " | ".join(labels) + " |",
        "|---|" + "---:|" * len(labels),
    ]
    for label, row in zip(labels, result["confusion"], strict=True):
        lines.append(f"| {label} | " + " | ".join(str(v) for v in row) + " |")
    return lines


def _comparison(results: dict[str, dict], chosen: str) -> list[str]:
    """Table of :func:`~emotive.eval.classifier_training.compare_architectures` results."""
    first = next(iter(results.values()))
    seeds = ", ".join(str(s) for s in first["seeds"])
    lines = [
        f"### Architectures compared ({first['folds']}-fold cross-validation, same folds, "
        f"seeds {seeds})",
        "",
        "| architecture | CV window accuracy | CV balanced accuracy | per label | "
        "seconds to train |",
        "|---|---:|---:|---|---:|",
    ]

    def cell(result: dict, key: str) -> str:
        each = ", ".join(f"{r[key]:.3f}" for r in result["runs"])
        return f"{result[key]:.3f} ({each})" if len(result["runs"]) > 1 else f"{result[key]:.3f}"

    for name, result in results.items():
        mark = " (this model)" if name == chosen else ""
        per_label = ", ".join(f"{k} {v:.2f}" for k, v in result["per_label"].items())
        lines.append(
            f"| {name}{mark} | {cell(result, 'window_accuracy')} | "
            f"{cell(result, 'balanced_accuracy')} | {per_label} | "
            f"{result['train_seconds']:.1f} |"
        )
    return [
        *lines, "",
        "Accuracies: the mean over the seeds, then each seed's (the first seed's run of this "
        "model's architecture is the cross-validation above); per label: means over the seeds. "
        "Seconds to train: mean wall-clock time of one fold's model on the CPU that wrote this "
        "card. The default architecture (`ClassifierConfig.architecture`) is the one with the "
        "higher mean CV window accuracy here when the choice was made.",
        "",
    ]


def classifier_card(model: EmotionClassifier, clips: dict[str, list[str]]) -> str:
    """Markdown model card of a trained perceived-emotion classifier.

    Args:
        model: the classifier with its ``metrics`` (``test``, ``val``, optionally
            ``cross_validation`` and ``architectures``, the latter from
            :func:`~emotive.eval.classifier_training.compare_architectures`).
        clips: clip names by split, as trained.
    """
    cfg = model.config
    data = [get_dataset(name) for name in cfg.datasets]
    out = [
        "# Perceived-emotion classifier",
        "",
        f"{_NETWORKS.get(cfg.architecture, cfg.architecture)} that reads 2-10 s of motion "
        "(joint positions of the 21 joint roles in the body frame, their velocities, the 18 "
        "affective features and 8 movement features, at "
        f"{cfg.fps:g} fps) and gives probabilities over {', '.join(cfg.labels)}. It stands in "
        "for human observers when the project's generators are evaluated; it was trained on "
        "real motion only. Code: `emotive.eval.classifier`; retrain with "
        "`emotive train classifier --out DIR`.",
        "",
        "## Training data and license",
        "",
    ]
    for info in data:
        out.append(f"- {info.attribution}")
    out += [
        "",
        f"Clips whose emotion label is one of {', '.join(cfg.labels)} "
        f"({'locomotion only' if cfg.locomotion_only else 'all contents'}; Bandai `normal` is "
        "`neutral`), split by clip with the project's deterministic split (seed 0, 10 % "
        "validation, 10 % test per style); clips shorter than "
        f"{cfg.min_seconds:g} s are left out. The weights are derived from CC BY-NC 4.0 data: "
        "use them for non-commercial purposes only.",
        "",
    ]
    for split, names in clips.items():
        out.append(f"- {split} ({len(names)} clips): {', '.join(names)}")
    out += ["", "## Config", "", "```"]
    out += [f"{k} = {v!r}" for k, v in asdict(cfg).items()]
    out += ["```", "", "## Measured", ""]
    for key, title in (("test", "Held-out test clips (4 s windows, 1 s hop)"),
                       ("val", "Validation clips (used to pick the epoch)"),
                       ("cross_validation", "Cross-validation over all clips")):
        if key in model.metrics:
            result = model.metrics[key]
            extra = f", {result['folds']} folds" if key == "cross_validation" else ""
            out += [f"### {title}{extra}", "", *_table(result), ""]
    if "architectures" in model.metrics:
        out += _comparison(model.metrics["architectures"], cfg.architecture)
    out += [
        "## Limits",
        "",
        "The data holds little motion per emotion (dataset 1: a few minutes each, one actor "
        "per style), and the held-out test split a handful of clips, so the test numbers are "
        "uncertain by several points; the cross-validation numbers are the better estimate. "
        "Windows shorter than the training windows (2-4 s) and motion far from walking, "
        "running and the dataset's gestures are outside what it has seen.",
        "",
    ]
    return "\n".join(out)
