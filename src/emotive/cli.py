"""The ``emotive`` command line: one entry point, verb-first sub-commands.

``generate``, ``crowd``, ``train``, ``transfer``, ``reconstruct``, ``retarget``, ``evaluate``,
``models``, ``info``, ``features``, ``preview``, ``classify``, ``data``, ``serve``, ``export``,
``study`` and ``synth``; each lives in :mod:`emotive.commands` and this module registers
them. The old spellings ``fcrbm train|generate`` and ``resample`` work for one release, with
one deprecation line.

:func:`main` runs the app without click's own error handling, so that every invalid value,
click's usage and range errors as well as every :class:`~emotive.errors.EmotiveError`, prints
one ``error: ...`` line on stderr and exits with code 2 (130 after Ctrl-C).
"""

from __future__ import annotations

import sys
from typing import Annotated

import typer

# Typer (0.29 on) carries its own copy of click; its errors are these, not click's.
from typer._click.exceptions import NoArgsIsHelpError, UsageError

import emotive
from emotive.commands.classify import classify
from emotive.commands.crowd import crowd
from emotive.commands.data import app as data_app
from emotive.commands.evaluate import evaluate
from emotive.commands.export import app as export_app
from emotive.commands.fcrbm import app as fcrbm_app
from emotive.commands.generate import generate
from emotive.commands.info import features, info
from emotive.commands.models import models
from emotive.commands.reconstruct import reconstruct
from emotive.commands.render import preview
from emotive.commands.resample import resample
from emotive.commands.retarget import retarget
from emotive.commands.serve import serve
from emotive.commands.study import app as study_app
from emotive.commands.synth import app as synth_app
from emotive.commands.train import app as train_app
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
        typer.Option("--version", callback=_print_version, is_eager=True, metavar="",
                     help="Print the version and exit."),
    ] = False,
) -> None:
    """Make virtual agents move with emotion."""


app.command("generate")(generate)
app.command("crowd")(crowd)
app.add_typer(train_app, name="train")
app.command("transfer")(transfer)
app.command("reconstruct")(reconstruct)
app.command("retarget")(retarget)
app.command("evaluate")(evaluate)
app.command("models")(models)
app.command("info")(info)
app.command("features")(features)
app.command("preview")(preview)
app.command("classify")(classify)
app.add_typer(data_app, name="data")
app.command("serve")(serve)
app.add_typer(export_app, name="export")
app.add_typer(study_app, name="study")
app.add_typer(synth_app, name="synth")
app.command("resample", hidden=True)(resample)
app.add_typer(fcrbm_app, name="fcrbm", hidden=True)


def _usage_line(exc: UsageError) -> str:
    """Click's usage or range error as one line, with where to read the command's help."""
    message = " ".join(exc.format_message().split())
    where = exc.ctx.command_path if exc.ctx is not None else "emotive"
    return f"error: {message} (see `{where} --help`)"


def main(argv: list[str] | None = None) -> None:
    """Console entry point: run the command line and exit with its status.

    Args:
        argv: the arguments (default: ``sys.argv[1:]``).

    Raises:
        SystemExit: always; 0 on success, 2 after an invalid value or input (one ``error:``
            line on stderr), 130 after Ctrl-C.
    """
    try:
        code = app(args=argv, prog_name="emotive", standalone_mode=False)
    except NoArgsIsHelpError as exc:
        typer.echo(exc.ctx.get_help() if exc.ctx is not None else "", err=True)
        code = 2
    except UsageError as exc:
        typer.secho(_usage_line(exc), err=True, fg=typer.colors.RED)
        code = 2
    except (typer.Abort, KeyboardInterrupt):
        code = 130
    except EmotiveError as exc:
        typer.secho(f"error: {' '.join(str(exc).splitlines())}", err=True, fg=typer.colors.RED)
        code = 2
    sys.exit(code if isinstance(code, int) else 0)
