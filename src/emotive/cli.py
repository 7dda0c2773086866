"""The ``emotive`` command line: one entry point with sub-commands.

Each group of commands lives in :mod:`emotive.commands`; this module registers them and turns
every :class:`~emotive.errors.EmotiveError` into a one-line message and a non-zero exit.
"""

from __future__ import annotations

import sys

import typer

from emotive.errors import EmotiveError

app = typer.Typer(
    name="emotive",
    help="Make virtual agents move with emotion.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def main() -> None:
    """Console entry point."""
    try:
        app()
    except EmotiveError as exc:
        typer.secho(f"error: {exc}", err=True, fg=typer.colors.RED)
        sys.exit(2)
