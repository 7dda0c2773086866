"""MkDocs hook: the CLI reference, generated from the typer app at build time.

``docs/cli.md`` holds the marker ``<!-- emotive-cli-reference -->``; this hook replaces it with
one section per command of ``emotive.cli:app`` (usage, help text, arguments and options, as
``emotive COMMAND --help`` has them), recursing into groups, so the reference cannot drift
from the code. Hidden commands are left out; deprecated ones are marked.
"""

from __future__ import annotations

import inspect

MARKER = "<!-- emotive-cli-reference -->"


def _cell(text: object) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _default(param) -> str:
    default = getattr(param, "default", None)
    if default is None or default is False or default == () or callable(default):
        return ""
    if isinstance(default, (list, tuple)):
        default = ", ".join(map(str, default))
    return _cell(default)


def _row(param, ctx) -> str | None:
    record = param.get_help_record(ctx)
    if record is None:  # a plain click argument: no help record
        record = (param.name, "")
    names, help_text = record
    if names.strip() == "--help":
        return None
    default = _default(param)
    if default and "[default:" not in help_text:
        help_text = f"{help_text} [default: {default}]"
    if param.required and "[required]" not in help_text:
        help_text = f"{help_text} [required]"
    return f"| `{_cell(names)}` | {_cell(help_text)} |"


def _section(command, path: list[str], parent) -> list[str]:
    ctx = command.context_class(command, info_name=path[-1], parent=parent)
    name = " ".join(path)
    title = f"`{name}`" + (" (deprecated)" if getattr(command, "deprecated", False) else "")
    lines = [f"{'#' * min(len(path) + 1, 6)} {title}", ""]
    usage = " ".join(command.collect_usage_pieces(ctx))
    lines += ["```text", f"{name} {usage}".rstrip(), "```", ""]
    if command.help:
        lines += [inspect.cleandoc(command.help).replace("\b\n", ""), ""]
    rows = [r for p in command.get_params(ctx)
            if not getattr(p, "hidden", False) and (r := _row(p, ctx)) is not None]
    if rows:
        lines += ["| argument / option | help |", "| --- | --- |", *rows, ""]
    if hasattr(command, "list_commands"):
        for sub in command.list_commands(ctx):
            child = command.get_command(ctx, sub)
            if child is not None and not getattr(child, "hidden", False):
                lines += _section(child, [*path, sub], ctx)
    return lines


def cli_reference() -> str:
    """Markdown for every command of the ``emotive`` app."""
    import typer.main

    from emotive.cli import app

    return "\n".join(_section(typer.main.get_command(app), ["emotive"], None))


def on_page_markdown(markdown, page, config, files):
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, cli_reference())
    return markdown
