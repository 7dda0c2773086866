"""``emotive classify``: the perceived emotion of a clip over time.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import RolesOpt, positive

ModelOpt = Annotated[
    Path | None,
    typer.Option("--model", help="Classifier file (default: the built-in one).",
                 show_default=False),
]


def classify(
    file: Annotated[Path, typer.Argument(help="BVH file.", show_default=False)],
    model: ModelOpt = None,
    window: Annotated[
        float, typer.Option(help="Seconds per judged window.", callback=positive)
    ] = 4.0,
    hop: Annotated[
        float, typer.Option(help="Seconds between windows.", callback=positive)
    ] = 1.0,
    roles: RolesOpt = None,
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
