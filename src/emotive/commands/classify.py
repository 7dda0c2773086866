"""``emotive classify``, ``emotive evaluate`` and ``emotive train classifier``.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.train_gait import train_gait_command
from emotive.commands.train_quaternet import train_quaternet_command

train_app = typer.Typer(help="Train models on the real data sets.", no_args_is_help=True,
                        add_completion=False)
train_app.command("gait")(train_gait_command)
train_app.command("quaternet")(train_quaternet_command)

ModelOpt = Annotated[
    Path | None,
    typer.Option("--model", help="Classifier file (default: the built-in one).",
                 show_default=False),
]


def classify(
    file: Annotated[Path, typer.Argument(help="BVH file.", show_default=False)],
    model: ModelOpt = None,
    window: Annotated[float, typer.Option(help="Seconds per judged window.")] = 4.0,
    hop: Annotated[float, typer.Option(help="Seconds between windows.")] = 1.0,
    roles: Annotated[
        str | None,
        typer.Option("--roles", help='Role map: "bandai", "cmu" or a JSON file.',
                     show_default=False),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print JSON instead of a table.")] = False,
) -> None:
    """Print the perceived emotion of a clip over time (probabilities per window)."""
    from rich.console import Console
    from rich.table import Table

    from emotive.eval.classifier import EmotionClassifier, load_default_classifier
    from emotive.io.bvh import read_bvh

    clf = EmotionClassifier.load(model) if model is not None else load_default_classifier()
    motion = read_bvh(file)
    times, prob = clf.classify(motion, window_seconds=window, hop_seconds=hop, role_map=roles)
    mean = prob.mean(0)
    if as_json:
        typer.echo(json.dumps({
            "file": str(file), "labels": list(clf.labels),
            "windows": [{"t": float(t), "emotion": dict(zip(clf.labels, map(float, p),
                                                             strict=True))}
                        for t, p in zip(times, prob, strict=True)],
            "mean": dict(zip(clf.labels, map(float, mean), strict=True)),
            "perceived": clf.labels[int(mean.argmax())],
        }, indent=2))
        return
    table = Table(title=f"perceived emotion of {file.name} ({window:g} s windows)")
    table.add_column("time (s)", justify="right")
    for label in clf.labels:
        table.add_column(label, justify="right")
    table.add_column("perceived")
    for t, p in zip(times, prob, strict=True):
        table.add_row(f"{t:.1f}", *(f"{v:.2f}" for v in p), clf.labels[int(p.argmax())])
    table.add_row("mean", *(f"{v:.2f}" for v in mean), clf.labels[int(mean.argmax())],
                  style="bold")
    Console().print(table)


@train_app.command("classifier")
def train_classifier_command(
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the classifier file and its model card.")
    ] = Path("models/classifier"),
    seed: Annotated[int, typer.Option(help="Seed of initialization and batching.")] = 0,
    epochs: Annotated[int, typer.Option(help="Training epochs.", min=1)] = 40,
    folds: Annotated[
        int, typer.Option(help="Also cross-validate over this many folds (0: skip).", min=0)
    ] = 5,
    architecture: Annotated[
        str | None,
        typer.Option(help='Network: "tcn" or "stgcn" (default: the project\'s choice).',
                     show_default=False),
    ] = None,
    compare_seeds: Annotated[
        int,
        typer.Option(help="Cross-validate every architecture on the same folds with this many "
                          "seeds for the card's comparison (0: only the trained one).", min=0),
    ] = 3,
) -> None:
    """Train the perceived-emotion classifier on real data, measure it, write it and its card."""
    from dataclasses import replace

    from rich.console import Console

    from emotive.eval.classifier import ClassifierConfig
    from emotive.eval.classifier_training import (
        compare_architectures,
        cross_validate,
        load_split_features,
        train_classifier,
    )
    from emotive.eval.model_card import classifier_card

    console = Console(stderr=True)
    out.mkdir(parents=True, exist_ok=True)
    config = replace(ClassifierConfig(), seed=seed, epochs=epochs)
    if architecture is not None:
        config = replace(config, architecture=architecture)
    data = load_split_features(config, progress=True)
    model = train_classifier(config, progress=True, data=data)
    if folds and compare_seeds:
        console.print(f"cross-validating every architecture over {folds} folds and "
                      f"{compare_seeds} seeds ...")
        results = compare_architectures(config, folds, compare_seeds, data=data)
        model.metrics["architectures"] = results
        model.metrics["cross_validation"] = results[config.architecture]["runs"][0]
    elif folds:
        console.print(f"cross-validating over {folds} folds ...")
        model.metrics["cross_validation"] = cross_validate(config, folds, data=data)
    path = model.save(out / "emotion-classifier.pt")
    card = classifier_card(model, {s: [i.name for i in v] for s, v in data.items()})
    from emotive.io.atomic import atomic_output

    with atomic_output(out / "MODEL_CARD.md") as tmp:
        tmp.write_text(card)
    test = model.metrics["test"]
    console.print(
        f"wrote {path} and {out / 'MODEL_CARD.md'}: test window accuracy "
        f"{test['window_accuracy']:.3f} on {test['windows']} windows of {test['clips']} clips"
    )


def evaluate(
    model: Annotated[
        str, typer.Option("--model", help="A folder of BVH files with intended emotions, a "
                          "model name (emotive-gait, gait-no-affective, gait-no-root-loss, "
                          "quaternet, zero-velocity) or a gait checkpoint (.pt).",
                          show_default=False)
    ],
    suite: Annotated[
        str, typer.Option("--suite", help="table1, emotion, transition, path, longrun, quality, "
                          "speed or all.")
    ] = "all",
    out: Annotated[Path | None, typer.Option("--out", help="Report folder.",
                                             show_default=False)] = None,
    classifier: Annotated[
        Path | None, typer.Option("--classifier", help="Classifier file (default: built-in).",
                                  show_default=False),
    ] = None,
) -> None:
    """Evaluate a model or a folder of BVH files: report.md, metrics.json and plots."""
    from rich.console import Console

    from emotive.eval.classifier import EmotionClassifier, load_default_classifier
    from emotive.eval.evaluate import resolve_subject, run_suites
    from emotive.eval.report import write_report

    clf = EmotionClassifier.load(classifier) if classifier else load_default_classifier()
    subject = resolve_subject(model, clf.labels)
    out = out or Path("reports") / subject.name
    results, info = run_suites(subject, suite, clf, progress=True)
    folder = write_report(out, subject.name, results, info)
    Console(stderr=True).print(f"wrote {folder / 'report.md'}, {folder / 'metrics.json'} and "
                               f"{sum(len(r.get('figures', [])) for r in results.values())} plots")
