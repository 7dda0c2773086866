"""``emotive study``: perceptual studies with real observers (:mod:`emotive.study`).

``init`` makes a study folder from one of the papers' designs, ``serve`` runs the web study,
``simulate`` sends simulated participants through its HTTP API, ``export`` writes every
response as CSV and ``analyze`` writes the report with the papers' statistics. The server,
SQLAlchemy and torch load inside each command, so ``emotive study --help`` stays fast.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import SeedOpt

app = typer.Typer(help="Perceptual studies: make, serve, simulate, export and analyze web "
                  "studies with real observers.", no_args_is_help=True)

FolderArg = Annotated[Path, typer.Argument(help="The study folder.", show_default=False)]
DbOpt = Annotated[str | None, typer.Option(
    "--db", help="Database URL: sqlite:///PATH or postgresql://USER@HOST/DB (default: "
    "DIR/study.db, SQLite in WAL mode).", show_default=False)]


def _missing(exc: ModuleNotFoundError) -> None:
    from emotive.study.errors import StudyError

    if (exc.name or "").startswith("emotive"):
        raise exc
    raise StudyError(f"emotive study needs the study extra ({exc.name} is missing): "
                     "pip install 'emotive[study]'") from None


@app.command("init")
def init(
    folder: FolderArg,
    template: Annotated[str, typer.Option("--template", help="The design: gaits (emotion "
                                          "scales and naturalness), affect-grid (valence and "
                                          "arousal on a grid) or sources (forced choice over "
                                          "mocap, IK reconstruction and LGB).")] = "gaits",
    stimuli: Annotated[Path | None, typer.Option(
        "--stimuli", help="A folder of BVH/GLB files to show instead of generated ones (with a "
        "labels.json or Bandai Namco names for their intended emotion).",
        show_default=False)] = None,
    count: Annotated[int | None, typer.Option(
        "--count", help="Stimuli to generate (gaits 8, affect-grid 9 plus 4 recorded, sources 1 "
        "per label and source).", show_default=False)] = None,
    seconds: Annotated[float, typer.Option("--seconds", help="Length of every stimulus, "
                                           "seconds (it loops).")] = 10.0,
    seed: SeedOpt = 0,
) -> None:
    """Make a study folder: study.toml, the stimuli (GLB) and the classifier's readings."""
    from rich.progress import Progress

    try:
        from emotive.study.create import create_study
    except ModuleNotFoundError as exc:
        _missing(exc)
    with Progress(transient=True, console=None) as bar:
        task = bar.add_task("making stimuli", total=None)
        out = create_study(folder, template, stimuli, count, seconds, seed,
                           advance=lambda _sid: bar.advance(task),
                           on_total=lambda n: bar.update(task, total=n))
    typer.echo(f"wrote {out} ({template} template): edit {out / 'study.toml'}, then "
               f"`emotive study serve {out}`")


@app.command("serve")
def serve(
    folder: FolderArg,
    db: DbOpt = None,
    host: Annotated[str, typer.Option("--host", help="Address to bind; any other than "
                                      "127.0.0.1/localhost needs --admin-token.")] = "127.0.0.1",
    port: Annotated[int, typer.Option("--port", help="TCP port (0: any free one).")] = 8000,
    admin_token: Annotated[str | None, typer.Option(
        "--admin-token", help="Secret of the admin page and API (progress, exclusions, "
        "export); without it they are off.", show_default=False)] = None,
    log_level: Annotated[str, typer.Option("--log-level", help="uvicorn's log level.")]
    = "warning",
) -> None:
    """Serve the study: the participant page at /, the admin page at /admin."""
    from emotive.serve.settings import is_loopback
    from emotive.study.errors import StudyError

    if not is_loopback(host) and not admin_token:
        raise StudyError(f"--host {host} lets other machines in: set --admin-token too, so "
                         "that only you can reach the admin API")
    if admin_token is not None and len(admin_token) < 12:
        raise StudyError("--admin-token must be at least 12 characters")
    try:
        from emotive.serve.server import base_url, bind, bound_port
        from emotive.study.app import create_app
        from emotive.study.server import study_uvicorn
    except ModuleNotFoundError as exc:
        _missing(exc)
    sock = bind(host, port)
    try:
        app_ = create_app(folder, db_url=db, admin_token=admin_token)
        state = app_.state.study
        url = base_url(host, bound_port(sock))
        typer.echo(f"emotive study: {state.study.title!r}, {len(state.study.stimuli)} stimuli, "
                   f"{state.engine.dialect.name} database")
        typer.echo(f"  participants: {url}/")
        typer.echo(f"  admin:        {url}/admin" + ("" if admin_token else
                                                     " (off: start with --admin-token)"))
        typer.echo("  Ctrl-C stops the server.")
        sys.stdout.flush()
        try:
            study_uvicorn(app_, log_level=log_level).run(sockets=[sock])
        except KeyboardInterrupt:
            pass
        typer.echo("emotive study: stopped")
    finally:
        sock.close()


@app.command("simulate")
def simulate(
    folder: FolderArg,
    url: Annotated[str, typer.Option("--url", help="The study server, e.g. "
                                     "http://127.0.0.1:8000.")],
    participants: Annotated[int, typer.Option("--participants", min=1, max=100_000,
                                              help="Simulated participants.")] = 30,
    concurrency: Annotated[int, typer.Option("--concurrency", min=1, max=1000,
                                             help="Participants at once.")] = 10,
    seed: SeedOpt = 0,
    careless: Annotated[float, typer.Option("--careless", min=0.0, max=1.0,
                                            help="Share of careless raters (random answers).")]
    = 0.1,
    receipts: Annotated[Path | None, typer.Option(
        "--receipts", help="Write one JSON line per acknowledged submission here.",
        show_default=False)] = None,
    deadline: Annotated[float, typer.Option(
        "--deadline", min=0.001, help="Seconds to wait for a server that does not answer (or "
        "answers 502/503/504: restarting, or its database cannot store) before giving up; "
        "retries back off from 0.05 s to 2 s.")] = 60.0,
) -> None:
    """Simulated participants through the study's HTTP API; prints one JSON summary line.

    Giving up at the deadline mid-run prints the summary, then one error line (exit 2).
    """
    try:
        from emotive.study.config import load_study
        from emotive.study.errors import ServerUnavailable
        from emotive.study.simulate import run_simulation
        from emotive.study.stimuli import load_readings
    except ModuleNotFoundError as exc:
        _missing(exc)
    study = load_study(folder)
    summary = run_simulation(study, url, participants, concurrency, seed, careless=careless,
                             readings=load_readings(study.folder), receipts=receipts,
                             progress=sys.stderr.isatty(), deadline=deadline,
                             notify=lambda line: typer.echo(f"emotive study simulate: {line}",
                                                            err=True))
    typer.echo(json.dumps(summary))
    if summary["server_gone"]:
        raise ServerUnavailable(
            f"gave up on the study server at {url} ({summary['gave_up']}); the summary line "
            f"counts the {summary['acknowledged']} values it acknowledged: bring the server "
            "back and simulate again, or give a longer --deadline")


@app.command("export")
def export(
    folder: FolderArg,
    out: Annotated[Path, typer.Option("--out", help="The CSV file to write.")],
    db: DbOpt = None,
) -> None:
    """Every response as CSV: participant, condition, stimulus, question, value, time, ..."""
    try:
        from emotive.study.config import load_study
        from emotive.study.export import write_export
    except ModuleNotFoundError as exc:
        _missing(exc)
    rows = write_export(load_study(folder), db, out)
    typer.echo(f"wrote {out} ({rows} responses)")


@app.command("analyze")
def analyze(
    folder: FolderArg,
    out: Annotated[Path, typer.Option("--out", help="The report folder (report.md and plots).")],
    db: DbOpt = None,
) -> None:
    """The report: intended vs perceived, naturalness, ANOVA, agreement, careless raters."""
    try:
        import pandas as pd

        from emotive.study.analyze import analyze_study
        from emotive.study.config import load_study
        from emotive.study.db import open_database
        from emotive.study.export import export_csv
        from emotive.study.stimuli import load_readings
        from emotive.study.store import check_design
    except ModuleNotFoundError as exc:
        _missing(exc)
    import io

    study = load_study(folder)
    engine = open_database(study.folder, db, pool_size=1)
    try:
        check_design(engine, study)
        frame = pd.read_csv(io.StringIO(export_csv(engine, study)), dtype=str,
                            keep_default_na=False)
    finally:
        engine.dispose()
    summary = analyze_study(study, frame, load_readings(study.folder), out)
    typer.echo(f"wrote {out / 'report.md'} ({summary.participants} participants)")
