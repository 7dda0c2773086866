"""``emotive models``: every registered model, what it can be loaded as, and its options.

Reads :data:`emotive.models.registry.REGISTRY` only: no model is loaded.
"""

from __future__ import annotations

import json
from typing import Annotated

import typer

from emotive.commands.options import flag
from emotive.models.registry import REGISTRY, ModelEntry


def entry_row(entry: ModelEntry) -> dict[str, object]:
    """One registry entry as a JSON-ready dict."""
    return {"name": entry.name, "kinds": list(entry.kinds), "weights": entry.weights,
            "summary": entry.summary, "paper": entry.paper,
            "options": {o.name: o.help for o in entry.options}, "card": entry.card}


def models(
    as_json: Annotated[bool, flag("json", "Print JSON instead of a table.")]
    = False,
) -> None:
    """List the registered models: name, kinds, default weights, summary and options."""
    if as_json:
        typer.echo(json.dumps([entry_row(e) for e in REGISTRY.values()], indent=2))
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title="registered models (use the name with --model; --json for papers, "
                  "option help and model cards)", show_lines=True)
    table.add_column("name", no_wrap=True)
    table.add_column("kinds")
    table.add_column("summary", ratio=3)
    table.add_column("default weights", ratio=2, overflow="fold")
    table.add_column("options")
    for entry in REGISTRY.values():
        options = "\n".join(f"--{o.name.replace('_', '-')}" for o in entry.options) or "-"
        table.add_row(entry.name, "\n".join(entry.kinds), entry.summary, entry.weights, options)
    Console().print(table)
