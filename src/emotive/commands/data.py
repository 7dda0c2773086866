"""``emotive data``: list, fetch and describe the motion data sets.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from typing import Annotated

import typer

from emotive.commands.options import flag

app = typer.Typer(
    help="List, fetch and describe the motion data sets.",
    no_args_is_help=True,
    add_completion=False,
)


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
    """Download or copy a data set's archive, check its sha256 and unpack it into the cache."""
    from emotive.data.registry import get_dataset
    from emotive.data.store import fetch as fetch_dataset
    from emotive.data.store import is_cached

    info = get_dataset(name)
    typer.echo(f"{info.title}: {info.attribution}")
    if is_cached(info) and not force:
        typer.echo(f"{info.name} is already in the cache; use --force to fetch it again")
    folder = fetch_dataset(info, source, force=force, progress=True)
    typer.echo(f"{info.name} ready in {folder}")


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
