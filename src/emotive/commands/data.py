"""``emotive data``: list, fetch, verify and describe the motion data sets.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import flag

if TYPE_CHECKING:
    from emotive.data.store import Verification

app = typer.Typer(
    help="List, fetch, verify and describe the motion data sets.",
    no_args_is_help=True,
    add_completion=False,
)

#: The most problems `emotive data verify` lists one by one; the counts cover the rest.
MAX_ROWS = 50


@app.command("list")
def list_datasets() -> None:
    """Show each data set, whether it is cached, shared on this machine or missing, and where."""
    from rich.console import Console
    from rich.table import Table

    from emotive.data.registry import REGISTRY
    from emotive.data.store import dataset_state, emotive_home

    table = Table(title=f"Data sets (cache: {emotive_home()})")
    for column in ("name", "state", "location", "clips", "license"):
        table.add_column(column, overflow="fold")
    colours = {"cached": "green", "shared": "yellow", "missing": "red"}
    for info in REGISTRY.values():
        state = dataset_state(info)
        label = {"shared": "available in shared data"}.get(state.state, state.state)
        table.add_row(
            info.name, f"[{colours[state.state]}]{label}[/]",
            str(state.location) if state.location else f"run `emotive data fetch {info.name}`",
            str(info.clips), info.license,
        )
    Console().print(table)


@app.command()
def fetch(
    name: Annotated[str, typer.Argument(help="Data set name (see `emotive data list`).")],
    source: Annotated[
        str | None,
        typer.Option(
            "--source",
            help="URL of the archive, the archive file, or a folder holding it. Default: a "
            "shared data folder, else $EMOTIVE_DATA_URL.",
        ),
    ] = None,
    force: Annotated[
        bool, flag("force", "Fetch and unpack again even when cached.")
    ] = False,
) -> None:
    """Download or copy a data set's archive, check its sha256 and unpack it into the cache.

    A data set already in the cache is verified against its manifest instead, and damaged or
    missing files are unpacked again (extra ones removed).
    """
    from emotive.data.registry import get_dataset
    from emotive.data.store import fetch as fetch_dataset
    from emotive.data.store import is_cached, repair
    from emotive.errors import DataError

    info = get_dataset(name)
    if (source is not None and not source.startswith(("http://", "https://"))
            and not Path(source).expanduser().exists()):
        # Checked here, not only where the archive is read: a data set already in the cache
        # would never read it, and the command would end well on a source that is not there.
        raise DataError(f"--source {source} does not exist; check the path, or give the "
                        "archive's URL")
    typer.echo(f"{info.title}: {info.attribution}")
    if is_cached(info) and not force:
        found = repair(info, source, progress=True)
        if found.clean:
            typer.echo(f"{info.name} is already in the cache and all {found.files} files match "
                       "its archive; use --force to fetch it again")
        else:
            names = ", ".join(p.path for p in found.problems[:5])
            more = f" and {len(found.problems) - 5} more" if len(found.problems) > 5 else ""
            typer.echo(f"{info.name} repaired from its archive: {_summary(found)} ({names}{more})")
        folder = found.folder
    else:
        folder = fetch_dataset(info, source, force=force, progress=True)
    typer.echo(f"{info.name} ready in {folder}")



def _summary(found: Verification) -> str:
    """``"1 damaged, 2 missing, 0 extra"`` for a :class:`~emotive.data.store.Verification`."""
    return ", ".join(f"{found.count(kind)} {kind}" for kind in ("damaged", "missing", "extra"))


@app.command()
def verify(
    name: Annotated[str, typer.Argument(help="Data set name (see `emotive data list`).")],
) -> None:
    """Check every unpacked file of a data set against the sha256 manifest of its archive.

    Prints a table of the damaged, missing and extra files and exits with 1 when there are any
    (0 when the data set is intact); `emotive data fetch NAME` repairs them.
    """
    from rich.console import Console
    from rich.table import Table

    from emotive.data.store import verify as verify_dataset

    found = verify_dataset(name, progress=True)
    if found.clean:
        typer.echo(f"{found.name}: all {found.files} files in {found.folder} match its archive "
                   f"({found.hashed_bytes / 1e6:.1f} MB hashed)")
        return
    table = Table(title=f"{found.name}: {_summary(found)} of {found.files} files in "
                        f"{found.folder}")
    for column in ("problem", "file", "detail"):
        table.add_column(column, overflow="fold")
    colours = {"damaged": "red", "missing": "red", "extra": "yellow"}
    for problem in found.problems[:MAX_ROWS]:
        table.add_row(f"[{colours[problem.kind]}]{problem.kind}[/]", problem.path, problem.detail)
    if len(found.problems) > MAX_ROWS:
        table.add_row("...", f"{len(found.problems) - MAX_ROWS} more", "")
    Console().print(table)
    typer.echo(f"fix: run `emotive data fetch {found.name}` to unpack the damaged and missing "
               "files again and remove the extra ones")
    raise typer.Exit(1)


@app.command()
def path(
    name: Annotated[str, typer.Argument(help="Data set name (see `emotive data list`).")],
) -> None:
    """Print the unpacked folder of a data set (unpacking a shared archive on first use)."""
    from emotive.data.store import dataset_dir

    typer.echo(str(dataset_dir(name)))


@app.command()
def stats(
    name: Annotated[str, typer.Argument(help="Data set name (see `emotive data list`).")],
    locomotion: Annotated[
        bool, flag("locomotion", "Only the locomotion contents.")
    ] = False,
    markdown: Annotated[
        bool, flag("markdown", "Print Markdown tables (for the README).")
    ] = False,
    val_fraction: Annotated[float, typer.Option(help="Share of each style for validation.")] = 0.1,
    test_fraction: Annotated[float, typer.Option(help="Share of each style for testing.")] = 0.1,
    seed: Annotated[int, typer.Option(help="Seed of the split.", min=0, max=2**32 - 1)] = 0,
) -> None:
    """Frames per content and style (emotion) in each split (train/val/test) and in all."""
    from rich.console import Console
    from rich.table import Table

    from emotive.data.splits import SPLITS
    from emotive.data.stats import frame_stats

    result = frame_stats(
        name, locomotion=locomotion, val_fraction=val_fraction, test_fraction=test_fraction,
        seed=seed, progress=True,
    )
    splits = list(result.frames)
    header = ["content", "style", *splits, "clips"]
    rows = []
    for r, content in enumerate(result.contents):
        for c, style in enumerate(result.styles):
            if result.clips["all"][r, c]:
                rows.append([
                    content, style, *(str(int(result.frames[s][r, c])) for s in splits),
                    "/".join(str(int(result.clips[s][r, c])) for s in SPLITS),
                ])
        rows.append([
            content, "all", *(str(int(result.frames[s][r].sum())) for s in splits),
            "/".join(str(int(result.clips[s][r].sum())) for s in SPLITS),
        ])
    for c, style in enumerate(result.styles):
        rows.append([
            "all", style, *(str(int(result.frames[s][:, c].sum())) for s in splits),
            "/".join(str(int(result.clips[s][:, c].sum())) for s in SPLITS),
        ])
    rows.append([
        "all", "all", *(str(int(result.frames[s].sum())) for s in splits),
        "/".join(str(int(result.clips[s].sum())) for s in SPLITS),
    ])
    title = (
        f"{result.dataset}{' (locomotion)' if locomotion else ''}: frames per content, style "
        f"and split; clips as {'/'.join(SPLITS)}"
    )
    if markdown:
        typer.echo(f"{title}\n")
        typer.echo("| " + " | ".join(header) + " |")
        typer.echo("|" + "|".join("---" if i < 2 else "---:" for i in range(len(header))) + "|")
        for row in rows:
            typer.echo("| " + " | ".join(row) + " |")
        return
    table = Table(title=title)
    for column in header:
        table.add_column(column, justify="left" if column in ("content", "style") else "right",
                         no_wrap=True)
    for row in rows:
        table.add_row(*row, style="bold" if "all" in row[:2] else None)
    Console().print(table)
