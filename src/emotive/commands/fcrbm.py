"""``emotive fcrbm train`` and ``emotive fcrbm generate``: deprecated spellings.

``emotive fcrbm train`` and ``emotive fcrbm generate``: deprecated spellings of
``emotive train fcrbm`` and ``emotive generate --model fcrbm``, kept for one release.

Each prints one deprecation line on stderr and then does what the new command does.
``--valence`` and ``--arousal`` now take the toolkit's -1..1 circumplex; a value of the old
1..3 scale is an error that shows the conversion.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    ConfigOpt,
    EpochsOpt,
    ForceOpt,
    PreviewOpt,
    PrimerOpt,
    ResumeOpt,
    SecondsOpt,
    SeedOpt,
    TrainOutOpt,
    deprecated,
    out_option,
)

app = typer.Typer(help="Deprecated: use `emotive train fcrbm` and `emotive generate --model "
                  "fcrbm`.", no_args_is_help=True, add_completion=False)


@app.command("train")
def train(
    config: ConfigOpt = "fcrbm",
    out: TrainOutOpt = Path("models/fcrbm"),
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    epochs: EpochsOpt = None,
    force: ForceOpt = False,
) -> None:
    """Deprecated: `emotive train fcrbm`."""
    from emotive.commands.train import train_fcrbm_command

    deprecated("fcrbm train", "train fcrbm")
    train_fcrbm_command(config, out, resume, seed, epochs, force)


@app.command("generate")
def generate(
    out: Annotated[Path, out_option("Output .bvh on the training rig.")],
    valence: Annotated[
        float | None,
        typer.Option(help="Valence, -1 low .. 0 neutral .. 1 high.", show_default=False),
    ] = None,
    arousal: Annotated[
        float | None,
        typer.Option(help="Arousal, -1 low .. 0 neutral .. 1 high.", show_default=False),
    ] = None,
    emotion: Annotated[
        str | None,
        typer.Option(help='An emotion instead, e.g. "sad" or "happy=0.5,angry=0.5".',
                     show_default=False),
    ] = None,
    schedule: Annotated[
        Path | None,
        typer.Option(help='JSON keyframes [{"t": 0, "valence": 1, "arousal": -1}, '
                          '{"t": 10, "emotion": "sad"}] (seconds).', show_default=False),
    ] = None,
    seconds: SecondsOpt = 20.0,
    primer: PrimerOpt = None,
    model: Annotated[
        Path | None,
        typer.Option("--model", help="FCRBM checkpoint (default: the built-in one).",
                     show_default=False),
    ] = None,
    gibbs: Annotated[
        int | None,
        typer.Option(help="Gibbs iterations per frame (default: the model's).", min=1,
                     show_default=False),
    ] = None,
    seed: SeedOpt = 0,
    root: Annotated[
        str | None,
        typer.Option(help="'feet' (default) or 'model' root path.", show_default=False),
    ] = None,
    preview: PreviewOpt = None,
    force: ForceOpt = False,
) -> None:
    """Deprecated: `emotive generate --model fcrbm`."""
    from emotive.commands.generate import run_generate
    from emotive.errors import EmotionError

    deprecated("fcrbm generate", "generate --model fcrbm")
    given = [name for name, value in (("--valence/--arousal", valence if valence is not None
                                       else arousal), ("--emotion", emotion),
                                      ("--schedule", schedule)) if value is not None]
    if len(given) != 1:
        raise EmotionError("give exactly one of --valence and --arousal, --emotion or "
                           "--schedule" + (f" (got {' and '.join(given)})" if given else ""))
    if (valence is None) != (arousal is None):
        raise EmotionError("give both --valence and --arousal (-1 low, 0 neutral, 1 high)")
    wanted: str | Path | None = schedule if schedule is not None else emotion
    flag = given[0]
    if valence is not None:
        wanted = f"valence={valence!r},arousal={arousal!r}"
    run_generate("fcrbm", out, wanted, seconds, preview=preview, primer=primer, seed=seed,
                 checkpoint=model, force=force, flags={"emotion": flag, "checkpoint": "--model"},
                 gibbs=gibbs, root=root)
