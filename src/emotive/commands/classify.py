"""``emotive classify``: the perceived emotion of a clip over time.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    RolesOpt,
    UnitOpt,
    flag,
    input_file,
    positive,
    read_input,
    role_joints,
    roles_option,
)

#: Seconds per judged window when ``--window`` is not given.
DEFAULT_WINDOW = 4.0

ModelOpt = Annotated[
    Path | None,
    typer.Option("--model", help="Classifier file (default: the built-in one).",
                 show_default=False),
]


def classify(
    file: Annotated[Path, typer.Argument(help="Motion file: .bvh, .glb/.gltf or .fbx.",
                                            show_default=False)],
    model: ModelOpt = None,
    window: Annotated[
        float | None,
        typer.Option(help="Seconds per judged window: at least 0.8, at most the clip's length "
                     f"(default {DEFAULT_WINDOW:g}, or the whole clip when it is shorter).",
                     callback=positive, show_default=False)
    ] = None,
    hop: Annotated[
        float, typer.Option(help="Seconds between windows.", callback=positive)
    ] = 1.0,
    roles: RolesOpt = None,
    unit: UnitOpt = "auto",
    as_json: Annotated[bool, flag("json", "Print JSON instead of a table.")] = False,
) -> None:
    """Print the perceived emotion of a clip over time (probabilities per window).

    A window whose motion lies outside what the classifier was trained on is marked
    "unsure"; so is the clip when most of its windows are.
    """
    from emotive.errors import ConfigError

    input_file(file)
    if model is not None:
        input_file(model, "--model", None, ConfigError)
    roles_option(roles)

    from rich.console import Console
    from rich.table import Table

    from emotive.eval.classifier import (
        ClassifierError,
        EmotionClassifier,
        load_default_classifier,
    )

    clf = EmotionClassifier.load(model) if model is not None else load_default_classifier()
    motion = read_input(file, unit)
    role_joints(motion.skeleton, roles)
    if window is None:
        window = DEFAULT_WINDOW
    elif window > motion.duration + 1e-9:
        least = clf.config.min_seconds
        raise ClassifierError(f"--window {window:g} s is longer than {file} ({motion.duration:.2f}"
                              f" s); give a window from {least:g} s to the clip's "
                              f"{motion.duration:.2f} s")
    judged = clf.judge(motion, window_seconds=window, hop_seconds=hop, role_map=roles)
    mean = judged.probabilities.mean(0)
    overall = "unsure" if judged.clip_unsure else clf.labels[int(mean.argmax())]
    if as_json:
        typer.echo(json.dumps({
            "file": str(file), "labels": list(clf.labels),
            "windows": [{"t": float(t), "emotion": dict(zip(clf.labels, map(float, p),
                                                             strict=True)),
                         "valence": float(va[0]), "arousal": float(va[1]),
                         "unsure": bool(u), "distance": float(d), "perceived": label}
                        for t, p, va, u, d, label in zip(
                            judged.times, judged.probabilities, judged.valence_arousal,
                            judged.unsure, judged.distance, judged.perceived, strict=True)],
            "mean": dict(zip(clf.labels, map(float, mean), strict=True)),
            "unsure": judged.clip_unsure,
            "perceived": overall,
        }, indent=2))
        return
    table = Table(title=f"perceived emotion of {file.name} ({window:g} s windows)")
    table.add_column("time (s)", justify="right")
    for label in clf.labels:
        table.add_column(label, justify="right")
    table.add_column("valence", justify="right")
    table.add_column("arousal", justify="right")
    table.add_column("perceived")
    for t, p, va, label in zip(judged.times, judged.probabilities, judged.valence_arousal,
                               judged.perceived, strict=True):
        table.add_row(f"{t:.1f}", *(f"{v:.2f}" for v in p), f"{va[0]:+.2f}", f"{va[1]:+.2f}",
                      label)
    va = judged.valence_arousal.mean(0)
    table.add_row("mean", *(f"{v:.2f}" for v in mean), f"{va[0]:+.2f}", f"{va[1]:+.2f}",
                  overall, style="bold")
    Console().print(table)
    if judged.clip_unsure:
        Console().print(f"unsure: {int(judged.unsure.sum())} of {len(judged.unsure)} windows "
                        "lie outside the motion the classifier was trained on; its "
                        "probabilities there are not to be trusted")
