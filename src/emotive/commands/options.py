"""Command-line options shared by several commands, so that each has one name and help text,
and the shared body of the training commands (:func:`run_training`).

Use the options as parameter annotations with the command's own default, e.g.
``config: ConfigOpt = Path("configs/gait.toml")``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

ConfigOpt = Annotated[
    Path, typer.Option("--config", help=r"TOML file with \[model] and \[train] sections.")
]
TrainOutOpt = Annotated[
    Path, typer.Option("--out", help="Folder for last.pt, best.pt and log.csv.")
]
ResumeOpt = Annotated[bool, typer.Option("--resume", help="Continue from the folder's last.pt.")]
EpochsOpt = Annotated[
    int | None,
    typer.Option(help=r"Epochs in all (default: the config's \[train] epochs).", min=1,
                 show_default=False),
]
PreviewOpt = Annotated[
    Path | None,
    typer.Option("--preview", help="Also write a stick-figure video: .mp4 or .gif.",
                 show_default=False),
]


def run_training(load: Callable[[Path], tuple[Any, Any]], train: Callable[..., Any],
                 config: Path, out: Path, resume: bool, seed: int, epochs: int | None) -> Any:
    """Read a TOML config, override its epochs if given, and train with progress bars.

    Args:
        load: reads ``config`` into ``(model config, training settings)``.
        train: ``train(model_config, settings, progress=, out_dir=, resume=, seed=)``.
        config, out, resume, seed, epochs: the command's options.

    Returns:
        What ``train`` returns.

    Raises:
        typer.Exit: code 130 after Ctrl-C (``train`` has saved ``last.pt``).
    """
    from dataclasses import replace

    model_config, settings = load(config)
    if epochs is not None:
        settings = replace(settings, epochs=epochs)
    try:
        return train(model_config, settings, progress=True, out_dir=out, resume=resume,
                     seed=seed)
    except KeyboardInterrupt:
        raise typer.Exit(130) from None
