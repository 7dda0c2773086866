"""``emotive train quaternet``: train the QuaterNet baseline from a TOML config.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import ConfigOpt, EpochsOpt, ResumeOpt, TrainOutOpt, run_training


def train_quaternet_command(
    config: ConfigOpt = Path("configs/quaternet.toml"),
    out: TrainOutOpt = Path("models/quaternet"),
    resume: ResumeOpt = False,
    seed: Annotated[int, typer.Option(help="Seed of initialization, batches and curriculum.")] = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the QuaterNet baseline on the gait data (Ctrl-C saves; --resume continues)."""
    from rich.console import Console

    from emotive.models.quaternet.training import load_quaternet_settings, train_quaternet

    result = run_training(load_quaternet_settings, train_quaternet, config, out, resume, seed,
                          epochs)
    last = result.history[-1] if result.history else {}
    Console(stderr=True).print(
        f"wrote {result.last_path}, {result.best_path} and {out / 'log.csv'}: "
        f"{len(result.history)} epochs, last train loss {last.get('train_total', float('nan')):.4g}"
        f", best validation loss {result.best_val:.4g}"
    )
