"""``emotive train gait | quaternet | fcrbm | classifier``: train a model on the real data.

Every model is trained from a TOML config (``--config``: a file, or the name of a recipe
shipped in :mod:`emotive.configs`, by default the model's own) into a folder (``--out``)
holding ``last.pt``, ``best.pt`` and ``log.csv``; Ctrl-C keeps the last finished epoch and
``--resume`` continues exactly. The classifier trains from the ``classifier`` recipe into
one file and its model card, optionally with the leave-one-studio-out models for the card.
``gait`` and ``classifier`` train data parallel on ``--nproc`` processes, or on several
machines under torchrun (:mod:`emotive.models.distributed`).

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import (
    SEED_MAX,
    ConfigOpt,
    EpochsOpt,
    ForceOpt,
    NprocOpt,
    ResumeOpt,
    SeedOpt,
    TrainOutOpt,
    check_training,
    run_training,
)

if TYPE_CHECKING:
    from emotive.eval.classifier import ClassifierConfig

#: The file ``train classifier`` writes into its folder.
CLASSIFIER_FILE = "emotion-classifier.pt"

app = typer.Typer(help="Train models on the real data sets.", no_args_is_help=True,
                  add_completion=False)


def _report(result, out: Path, key: str, loss: str, val: str) -> None:
    """One line: the files written, epochs, the last epoch's ``key`` and the best validation.

    Nothing for ``None``, a process of a torchrun job other than the first.
    """
    from rich.console import Console

    if result is None:
        return
    last = result.history[-1] if result.history else {}
    Console(stderr=True).print(
        f"wrote {out / 'last.pt'}, {out / 'best.pt'} and {out / 'log.csv'}: "
        f"{len(result.history)} epochs, last {loss} {last.get(key, float('nan')):.4g}, "
        f"best {val} {result.best_val:.4g}", highlight=False,
    )


@app.command("gait")
def train_gait_command(
    config: ConfigOpt = "gait",
    out: TrainOutOpt = Path("models/gait"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
    nproc: NprocOpt = 1,
    force: ForceOpt = False,
) -> None:
    """Train the emotive gait network (Ctrl-C keeps the last epoch; --resume continues)."""
    check_training(config, out, resume, force)
    from emotive.models.gait.training import load_gait_settings, train_gait

    result = run_training(load_gait_settings, train_gait, config, out, resume, seed, epochs,
                          nproc)
    _report(result, out, "train_total", "train loss", "validation loss")


@app.command("quaternet")
def train_quaternet_command(
    config: ConfigOpt = "quaternet",
    out: TrainOutOpt = Path("models/quaternet"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
    force: ForceOpt = False,
) -> None:
    """Train the QuaterNet baseline on the gait data (Ctrl-C keeps the last epoch; --resume)."""
    check_training(config, out, resume, force)
    from emotive.models.gait.quaternet.training import load_quaternet_settings, train_quaternet

    result = run_training(load_quaternet_settings, train_quaternet, config, out, resume, seed,
                          epochs)
    _report(result, out, "train_total", "train loss", "validation loss")


@app.command("fcrbm")
def train_fcrbm_command(
    config: ConfigOpt = "fcrbm",
    out: TrainOutOpt = Path("models/fcrbm"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
    force: ForceOpt = False,
) -> None:
    """Train the FCRBM by contrastive divergence.

    Train the FCRBM by contrastive divergence on walks of every style with a valence/arousal
    entry (Ctrl-C keeps the last finished epoch; --resume continues exactly).
    """
    check_training(config, out, resume, force)
    from emotive.models.fcrbm.training import load_fcrbm_settings, train_fcrbm

    result = run_training(load_fcrbm_settings, train_fcrbm, config, out, resume, seed, epochs)
    _report(result, out, "train_reconstruction", "reconstruction error",
            "validation one-step error")


@app.command("classifier")
def train_classifier_command(
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the classifier file and its model card.")
    ] = Path("models/classifier"),
    config: Annotated[
        str, typer.Option("--config", help="TOML file of the classifier's config fields, or "
                          "the name of a shipped recipe.")
    ] = "classifier",
    seed: Annotated[
        int | None, typer.Option("--seed", help="Random seed (default: the config's).",
                                 min=0, max=SEED_MAX, show_default=False)
    ] = None,
    epochs: Annotated[
        int | None, typer.Option("--epochs", help="Training epochs (default: the config's).",
                                 min=1, show_default=False)
    ] = None,
    studios: Annotated[
        bool, typer.Option("--studios/--no-studios", metavar="",
                           help="Also train on each data set alone and test on the other "
                                "(leave one studio out) for the card.")
    ] = True,
    nproc: NprocOpt = 1,
    force: ForceOpt = False,
) -> None:
    """Train the perceived-emotion classifier on real data, measure it, write it and its card."""
    recipe = check_training(config, out, False, force, CLASSIFIER_FILE)

    from dataclasses import replace

    from emotive.eval.classifier_training import read_config
    from emotive.io.atomic import output_error
    from emotive.models.distributed import run_parallel

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(out, exc) from exc
    cfg = read_config(recipe)
    cfg = replace(cfg, seed=cfg.seed if seed is None else seed,
                  epochs=cfg.epochs if epochs is None else epochs)
    run_parallel(train_classifier_job, cfg, out, studios, nproc=nproc)


def train_classifier_job(cfg: ClassifierConfig, out: Path, studios: bool) -> None:
    """The classifier command's work in one of its processes; process 0 prints and writes.

    Args:
        cfg: the :class:`~emotive.eval.classifier.ClassifierConfig`.
        out: the folder of the classifier file and its card.
        studios: also the leave-one-studio-out models.
    """
    import hashlib
    import time

    from rich.console import Console

    from emotive.eval.classifier_card import classifier_card
    from emotive.eval.classifier_training import (
        leave_one_studio_out,
        load_tracks,
        split_features,
        studio_proxy,
        train_classifier,
        unsure_rates,
    )
    from emotive.io.atomic import atomic_output
    from emotive.models.distributed import current_world

    main = current_world().is_main
    console = Console(stderr=True, quiet=not main)
    start = time.perf_counter()
    tracks = load_tracks(cfg.datasets, progress=main)
    data = split_features(tracks, cfg, progress=main)
    model = train_classifier(cfg, progress=True, data=data)
    studios = studios and len(cfg.datasets) == 2
    if studios:
        console.print("leave one studio out: training on each data set alone ...")
        loso, models = leave_one_studio_out(cfg, data, progress=True)
    if not main:
        return
    if studios:
        model.metrics["leave_one_studio_out"] = loso
        model.metrics["studio_proxy"] = studio_proxy(models[cfg.datasets[0]], tracks,
                                                     cfg.datasets[1])
    console.print("measuring the unsure rates of the held-out clips ...")
    model.metrics["unsure"] = unsure_rates(model, tracks)
    model.metrics["train_seconds"] = time.perf_counter() - start
    path = model.save(out / CLASSIFIER_FILE)
    names = {s: sorted({i.name for i in v}) for s, v in data.items()}
    weights = (path.name, hashlib.sha256(path.read_bytes()).hexdigest())
    with atomic_output(out / "MODEL_CARD.md") as tmp:
        tmp.write_text(classifier_card(model, names, weights))
    test = model.metrics["test"]
    console.print(
        f"wrote {path} and {out / 'MODEL_CARD.md'}: test window accuracy "
        f"{test['window_accuracy']:.3f} on {test['windows']} windows of {test['clips']} "
        f"labelled clips"
    )
