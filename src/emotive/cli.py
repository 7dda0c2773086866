"""The ``emotive`` command line: one entry point with sub-commands.

Each group of commands lives in :mod:`emotive.commands`; this module registers them and turns
every :class:`~emotive.errors.EmotiveError` into a one-line message and a non-zero exit.
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

import emotive
from emotive.commands import inspect as _inspect
from emotive.commands.classify import classify, evaluate, train_app
from emotive.commands.data import app as data_app
from emotive.commands.fcrbm import app as fcrbm_app
from emotive.commands.generate import generate
from emotive.commands.reconstruct import reconstruct
from emotive.commands.render import preview
from emotive.commands.resample import resample
from emotive.commands.transfer import transfer
from emotive.errors import EmotiveError

app = typer.Typer(
    name="emotive",
    help="Make virtual agents move with emotion.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)



def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"emotive {emotive.__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_print_version, is_eager=True,
                     help="Print the version and exit."),
    ] = False,
) -> None:
    """Make virtual agents move with emotion."""


app.command("info")(_inspect.info)
app.command("features")(_inspect.features)
app.command("preview")(preview)
app.command("generate")(generate)
app.command("reconstruct")(reconstruct)
app.command("resample")(resample)
app.command("transfer")(transfer)
app.command("classify")(classify)
app.command("evaluate")(evaluate)
app.add_typer(train_app, name="train")
app.add_typer(data_app, name="data")
app.add_typer(fcrbm_app, name="fcrbm")


def main() -> None:
    """Console entry point."""
    try:
        app()
    except EmotiveError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        sys.exit(2)
