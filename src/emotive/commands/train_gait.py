"""``emotive train gait``: train the emotive gait network from a TOML config.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import ConfigOpt, EpochsOpt, ResumeOpt, TrainOutOpt, run_training


def train_gait_command(
    config: ConfigOpt = Path("configs/gait.toml"),
    out: TrainOutOpt = Path("models/gait"),
    resume: ResumeOpt = False,
    seed: Annotated[int, typer.Option(help="Seed of initialization, batches and curriculum.")] = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the emotive gait network on the real data (Ctrl-C saves; --resume continues)."""
    from rich.console import Console

    from emotive.models.gait.training import load_settings, train_gait

    result = run_training(load_settings, train_gait, config, out, resume, seed, epochs)
    last = result.history[-1] if result.history else {}
    Console(stderr=True).print(
        f"wrote {result.last_path}, {result.best_path} and {out / 'log.csv'}: "
        f"{len(result.history)} epochs, last train loss {last.get('train_total', float('nan')):.4g}"
        f", best validation loss {result.best_val:.4g}"
    )
