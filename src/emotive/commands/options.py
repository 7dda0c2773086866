"""Command-line options shared by several commands, so that each has one name and help text.

Use them as parameter annotations with the command's own default, e.g.
``config: ConfigOpt = Path("configs/gait.toml")``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

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
