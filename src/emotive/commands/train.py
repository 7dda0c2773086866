"""``emotive train gait | quaternet | fcrbm | classifier``: train a model on the real data.

Every model is trained from a TOML config (``--config``) into a folder (``--out``) holding
``last.pt``, ``best.pt`` and ``log.csv``; Ctrl-C keeps the last finished epoch and
``--resume`` continues exactly. The classifier has its own options (folds, architecture
comparison).

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    ConfigOpt,
    EpochsOpt,
    ResumeOpt,
    SeedOpt,
    TrainOutOpt,
    run_training,
)

app = typer.Typer(help="Train models on the real data sets.", no_args_is_help=True,
                  add_completion=False)


def _report(result, out: Path, key: str, loss: str, val: str) -> None:
    """One line: the files written, epochs, the last epoch's ``key`` and the best validation."""
    from rich.console import Console

    last = result.history[-1] if result.history else {}
    Console(stderr=True).print(
        f"wrote {out / 'last.pt'}, {out / 'best.pt'} and {out / 'log.csv'}: "
        f"{len(result.history)} epochs, last {loss} {last.get(key, float('nan')):.4g}, "
        f"best {val} {result.best_val:.4g}", highlight=False,
    )


@app.command("gait")
def train_gait_command(
    config: ConfigOpt = Path("configs/gait.toml"),
    out: TrainOutOpt = Path("models/gait"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the emotive gait network (Ctrl-C keeps the last epoch; --resume continues)."""
    from emotive.models.gait.training import load_gait_settings, train_gait

    result = run_training(load_gait_settings, train_gait, config, out, resume, seed, epochs)
    _report(result, out, "train_total", "train loss", "validation loss")


@app.command("quaternet")
def train_quaternet_command(
    config: ConfigOpt = Path("configs/quaternet.toml"),
    out: TrainOutOpt = Path("models/quaternet"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the QuaterNet baseline on the gait data (Ctrl-C keeps the last epoch; --resume)."""
    from emotive.models.gait.quaternet.training import load_quaternet_settings, train_quaternet

    result = run_training(load_quaternet_settings, train_quaternet, config, out, resume, seed,
                          epochs)
    _report(result, out, "train_total", "train loss", "validation loss")


@app.command("fcrbm")
def train_fcrbm_command(
    config: ConfigOpt = Path("configs/fcrbm.toml"),
    out: TrainOutOpt = Path("models/fcrbm"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the FCRBM by contrastive divergence.

    Train the FCRBM by contrastive divergence on walks of every style with a valence/arousal
    entry (Ctrl-C keeps the last finished epoch; --resume continues exactly).
    """
    from emotive.models.fcrbm.training import load_fcrbm_settings, train_fcrbm

    result = run_training(load_fcrbm_settings, train_fcrbm, config, out, resume, seed, epochs)
    _report(result, out, "train_reconstruction", "reconstruction error",
            "validation one-step error")


@app.command("classifier")
def train_classifier_command(
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the classifier file and its model card.")
    ] = Path("models/classifier"),
    seed: SeedOpt = 0,
    epochs: Annotated[int, typer.Option("--epochs", help="Training epochs.", min=1)] = 40,
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
    from emotive.io.atomic import atomic_output, output_error
    from emotive.io.outputs import check_output_folder

    console = Console(stderr=True)
    check_output_folder(out, "--out")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc) from exc
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
    with atomic_output(out / "MODEL_CARD.md") as tmp:
        tmp.write_text(card)
    test = model.metrics["test"]
    console.print(
        f"wrote {path} and {out / 'MODEL_CARD.md'}: test window accuracy "
        f"{test['window_accuracy']:.3f} on {test['windows']} windows of {test['clips']} clips"
    )
