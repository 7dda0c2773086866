"""MkDocs hook: the benchmarks page, generated from the committed bench result file.

``docs/benchmarks.md`` holds the marker ``<!-- emotive-bench-results -->``; this hook replaces
it with the machine description and one table of every benchmark in ``docs/bench/latest.json``
(the JSON that ``python -m bench.run`` writes under ``bench/results/``; copy a new run there to
update the page).
"""

from __future__ import annotations

import json
from pathlib import Path

MARKER = "<!-- emotive-bench-results -->"
RESULT = Path(__file__).resolve().parents[1] / "bench" / "latest.json"


def _number(value: float) -> str:
    if value != value:  # NaN
        return "n/a"
    return f"{value:,.0f}" if abs(value) >= 100 else f"{value:.3g}"


def _ratio(value: float) -> str:
    return "n/a" if value != value else f"{value:.2f}"


def _cell(text: object) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def bench_tables(path: Path = RESULT) -> str:
    """Markdown tables of one ``bench/run.py`` result file."""
    record = json.loads(path.read_text())
    machine = record.get("machine", {})
    lines = [f"Run of {record.get('time', '?')}"
             + (f" (`{record['command']}`)" if record.get("command") else "") + "."
             + (f" {record['note'][0].upper()}{record['note'][1:]}" if record.get("note") else ""),
             ""]
    if machine:
        lines += ["| machine | |", "| --- | --- |"]
        lines += [f"| {_cell(k)} | {_cell(v)} |" for k, v in machine.items()]
        lines.append("")
    lines += ["| benchmark | unit | emotive | baseline | ratio | baseline is |",
              "| --- | --- | ---: | ---: | ---: | --- |"]
    for r in record["results"]:
        lines.append(f"| {_cell(r['name'])} | {_cell(r['unit'])} | {_number(r['ours'])} | "
                     f"{_number(r['baseline'])} | {_ratio(r['ratio'])} | "
                     f"{_cell(r['baseline_name'])} |")
    return "\n".join(lines) + "\n"


def on_page_markdown(markdown, page, config, files):
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, bench_tables())
    return markdown
