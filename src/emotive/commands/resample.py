"""``emotive resample``: the deprecated spelling of ``emotive generate --model lgb``.

Kept for one release. It prints one deprecation line on stderr and then does what the new command
does.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    ForceOpt,
    PreviewOpt,
    SecondsOpt,
    SeedOpt,
    deprecated,
    out_option,
)


def resample(
    emotion: Annotated[
        str,
        typer.Option("--emotion", "-e", help="Emotion to resample: happy, sad, angry, neutral "
                     "or another style of the data set.", show_default=False),
    ],
    out: Annotated[Path, out_option("Output .bvh, on the data's rig.")],
    seconds: SecondsOpt = 60.0,
    seed: SeedOpt = 0,
    preview: PreviewOpt = None,
    fps: Annotated[
        float | None,
        typer.Option("--fps", help="Frame rate of the output (default: the data's, 30).",
                     min=1.0, max=240.0, show_default=False),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(help="Worker processes for the inverse kinematics; default: the idle "
                     "cores, at most 2.", min=1, show_default=False),
    ] = None,
    dataset: Annotated[
        str | None, typer.Option(help="Data set whose clips are resampled.",
                                 show_default=False)
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Deprecated: `emotive generate --model lgb`."""
    from emotive.commands.generate import run_generate

    deprecated("resample", "generate --model lgb")
    run_generate("lgb", out, emotion, seconds, preview=preview, seed=seed, force=force, fps=fps,
                 workers=workers, dataset=dataset)
