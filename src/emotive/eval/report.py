"""Evaluation reports: ``report.md``, ``metrics.json`` and PNG plots in one folder.

The files are made in a temporary folder beside the destination, flushed to the disk and moved
in only when all of them are written (:func:`emotive.io.atomic.output_transaction`), so a
failed run leaves the destination as it was; a write fault is one
:class:`~emotive.errors.OutputError`.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from emotive.io.atomic import atomic_output, output_error, output_transaction

#: Keys of suite results that feed the plots but are too bulky for ``metrics.json``.
_PLOT_ONLY = ("trajectory", "path")


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "n/a" if math.isnan(value) else f"{value:.{digits}f}"
    return str(value)


def _strip(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in _PLOT_ONLY}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _figure(width: float, height: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib)

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _plot_emotion(result: dict, folder: Path) -> list[str]:
    labels = result["labels"]
    files = []
    confusion = np.array(result["confusion"], dtype=float)
    if confusion.sum():
        fig = _figure(4.5, 4.0)
        ax = fig.add_subplot()
        rate = confusion / np.maximum(confusion.sum(1, keepdims=True), 1)
        ax.imshow(rate, cmap="Blues", vmin=0, vmax=1)
        for (i, j), count in np.ndenumerate(confusion):
            ax.text(j, i, f"{int(count)}", ha="center", va="center",
                    color="white" if rate[i, j] > 0.5 else "black")
        ax.set_xticks(range(len(labels)), labels)
        ax.set_yticks(range(len(labels)), labels)
        ax.set_xlabel("perceived (classifier)")
        ax.set_ylabel("intended")
        ax.set_title("windows by dominant label")
        fig.tight_layout()
        fig.savefig(folder / "confusion.png")
        files.append("confusion.png")
    items = result["items"]
    if items:
        fig = _figure(min(2.0 + 1.6 * len(items), 24), 3.5)
        ax = fig.add_subplot()
        x = np.arange(len(items))
        width = 0.8 / (2 * len(labels))
        for k, label in enumerate(labels):
            ax.bar(x + (2 * k) * width - 0.4, [r["intended"][label] for r in items], width,
                   color=f"C{k}", label=f"{label} intended")
            ax.bar(x + (2 * k + 1) * width - 0.4, [r["perceived"][label] for r in items], width,
                   color=f"C{k}", alpha=0.45, hatch="//", label=f"{label} perceived")
        ax.set_xticks(x, [r["name"] for r in items], rotation=20, ha="right", fontsize=7)
        ax.set_ylabel("weight / probability")
        ax.set_ylim(0, 1)
        ax.legend(fontsize=6, ncol=len(labels))
        fig.tight_layout()
        fig.savefig(folder / "intended_vs_perceived.png")
        files.append("intended_vs_perceived.png")
    return files


def _plot_path(result: dict, folder: Path) -> list[str]:
    items = result["items"]
    if not items:
        return []
    cols = min(4, len(items))
    rows = math.ceil(len(items) / cols)
    fig = _figure(3.2 * cols, 3.2 * rows)
    for k, item in enumerate(items):
        ax = fig.add_subplot(rows, cols, k + 1)
        path, track = np.array(item["path"]), np.array(item["trajectory"])
        ax.plot(path[:, 0], path[:, 1], color="#2a9d4b", lw=1.5, label="path")
        ax.plot(track[:, 0], track[:, 1], color="#333333", lw=1.0, label="root")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{item['name']}\nmean {item['mean_position_deviation']:.2f} m", fontsize=8)
        ax.tick_params(labelsize=6)
    fig.axes[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(folder / "path_following.png")
    return ["path_following.png"]


def _plot_longrun(result: dict, folder: Path) -> list[str]:
    items = result["items"]
    if not items:
        return []
    fig = _figure(8, 3.5)
    ax = fig.add_subplot()
    for k, item in enumerate(items):
        energy = np.array(item["energy"])
        ax.plot(np.arange(len(energy)) + 0.5, energy, color=f"C{k % 10}", lw=1.2,
                label=item["name"])
    bands = next((i["real_energy_band"] for i in items if "real_energy_band" in i), {})
    for k, (label, (lo, hi)) in enumerate(bands.items()):
        ax.axhspan(lo, hi, color=f"C{k % 10}", alpha=0.06)
        ax.text(0.0, hi, f"real {label} 95 %", fontsize=6, va="bottom")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("mean joint speed (m/s)")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(folder / "energy.png")
    return ["energy.png"]


_PLOTS: dict[str, Callable[[dict, Path], list[str]]] = {
    "emotion": _plot_emotion, "path": _plot_path, "longrun": _plot_longrun,
}


def _table1_lines(result: dict) -> list[str]:
    """The body of the ``table1`` section."""
    return result.get("markdown", "").splitlines()


def _emotion_lines(result: dict) -> list[str]:
    """The body of the ``emotion`` section."""
    out = [
        f"Windows: {result['windows']}; accuracy of the dominant label: "
        f"{_fmt(result['window_accuracy'])} (the classifier on real held-out motion: "
        f"{_fmt(result['real_window_accuracy'])}; share: "
        f"{_fmt(result['share_of_real_accuracy'])}). Table-3 tests rejected: "
        f"{result['table3_rejected']} of {len(result['items'])}.",
        "",
        "| item | intended | perceived | window accuracy | AD statistic | p | reject |",
        "|---|---|---|---:|---:|---:|---|",
    ]
    for r in result["items"]:
        intended = max(r["intended"], key=r["intended"].get)
        perceived = max(r["perceived"], key=r["perceived"].get)
        t3 = r["table3"]
        p = _fmt(t3["p_value"]) + (" (bound)" if t3.get("p_value_bounded") else "")
        out.append(f"| {r['name']} | {intended} | {perceived} | "
                   f"{_fmt(r['window_accuracy'])} | {_fmt(t3['statistic'])} | {p} | "
                   f"{_fmt(t3['reject'])} |")
    if result["skipped"]:
        out += ["", f"Not judged (labels unknown to the classifier or too short): "
                f"{', '.join(result['skipped'])}"]
    return out


def _transition_lines(result: dict) -> list[str]:
    """The body of the ``transition`` section."""
    out = ["| item | change (s) | intended start -> end | perceived start -> end | "
            "jerk percentile | smooth |", "|---|---|---|---|---|---|"]
    for r in result["items"]:
        out.append(
            f"| {r['name']} | {', '.join(f'{t:.1f}' for t in r['change_seconds'])} | "
            f"{r['initial_intended']} -> {r['final_intended']} | "
            f"{r['initial_perceived']} -> {r['final_perceived']} | "
            f"{', '.join(f'{p:.0f}' for p in r.get('jerk_percentile', []))} | "
            f"{_fmt(r.get('smooth'))} |")
    return out


def _path_lines(result: dict) -> list[str]:
    """The body of the ``path`` section."""
    out = ["| item | mean deviation (m) | max deviation (m) | mean heading deviation (deg) |",
            "|---|---:|---:|---:|"]
    for r in result["items"]:
        out.append(f"| {r['name']} | {_fmt(r['mean_position_deviation'])} | "
                   f"{_fmt(r['max_position_deviation'])} | "
                   f"{_fmt(r['mean_heading_deviation'], 1)} |")
    return out


def _longrun_lines(result: dict) -> list[str]:
    """The body of the ``longrun`` section."""
    out = ["| item | seconds | stable | collapsed at | exploded at | share in real band |",
            "|---|---:|---|---|---|---:|"]
    for r in result["items"]:
        out.append(f"| {r['name']} | {len(r['energy'])} | {_fmt(r['stable'])} | "
                   f"{_fmt(r['collapsed_at'])} | {_fmt(r['exploded_at'])} | "
                   f"{_fmt(r.get('share_in_real_band'))} |")
    return out


def _quality_lines(result: dict) -> list[str]:
    """The body of the ``quality`` section."""
    out = [f"Mean skate speed {_fmt(result['mean_skate_speed'])} m/s; real motion "
            f"{_fmt(result['real_skate_speed'])} m/s; ratio {_fmt(result['skate_vs_real'])}. "
            f"Mean jerk {_fmt(result['mean_jerk'], 1)} m/s^3; real motion "
            f"{_fmt(result['real_jerk'], 1)}; ratio {_fmt(result['jerk_vs_real'])}.",
            "", "| item | skate (m/s) | skating share | max penetration (m) | jerk (m/s^3) |",
            "|---|---:|---:|---:|---:|"]
    for r in result["items"]:
        out.append(f"| {r['name']} | {_fmt(r['skate_speed'])} | {_fmt(r['skate_ratio'])} | "
                   f"{_fmt(r['penetration_max'])} | {_fmt(r['jerk'], 1)} |")
    return out


def _affect_lines(result: dict) -> list[str]:
    """The body of the ``affect`` section."""
    out = ["Fréchet distance of the 18 affective + 8 movement features per frame against "
            "real held-out motion of the same emotion; the last column is the same distance "
            "from real training motion (the level of real data).", "",
            "| emotion | items | frames | Fréchet to real | real train to real | diversity |",
            "|---|---:|---:|---:|---:|---:|"]
    for r in result["labels"]:
        out.append(f"| {r['label']} | {len(r['items'])} | {r['frames']} | "
                   f"{_fmt(r.get('frechet_to_real'), 2)} | "
                   f"{_fmt(r.get('frechet_real_train_to_real'), 2)} | "
                   f"{_fmt(r.get('diversity'), 2)} |")
    return out


def _speed_lines(result: dict) -> list[str]:
    """The body of the ``speed`` section."""
    out = ["Requests made one at a time through `generate` (crowds stepped together: "
           "`make bench`).", "", "| requests | frames | seconds | agent-frames/s |",
           "|---:|---:|---:|---:|"]
    for r in result["rows"]:
        out.append(f"| {r['agents']} | {r['frames']} | {_fmt(r['seconds'])} | "
                   f"{_fmt(r['agent_frames_per_second'], 0)} |")
    return out


#: The body of each suite's section, by suite name.
_SECTION_BODIES: dict[str, Callable[[dict], list[str]]] = {
    "table1": _table1_lines,
    "emotion": _emotion_lines,
    "transition": _transition_lines,
    "path": _path_lines,
    "longrun": _longrun_lines,
    "quality": _quality_lines,
    "affect": _affect_lines,
    "speed": _speed_lines,
}


def _section(name: str, result: dict) -> list[str]:
    out = [f"## {name}", ""]
    if name in _SECTION_BODIES:
        out += _SECTION_BODIES[name](result)
    if result.get("reference"):
        out += ["", f"Real reference: {result['reference']}."]
    for figure in result.get("figures", []):
        out += ["", f"![{figure}]({figure})"]
    return [*out, ""]


def _write_into(out: Path, title: str, results: dict[str, dict], info: dict[str, Any]) -> None:
    """The body of :func:`write_report`; any :class:`OSError` propagates."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        for name, result in results.items():
            plot = _PLOTS.get(name)
            result["figures"] = plot(result, tmp) if plot else []
        lines = [f"# Evaluation of {title}", ""]
        lines += [f"- {key}: {value}" for key, value in info.items()] + [""]
        for name, result in results.items():
            lines += _section(name, result)
        (tmp / "report.md").write_text("\n".join(lines))
        (tmp / "metrics.json").write_text(json.dumps(
            {"title": title, "info": info,
             "suites": {name: _strip(result) for name, result in results.items()}},
            indent=2, default=float,
        ))
        out.mkdir(exist_ok=True)
        # All or none: every file is on the disk before any replaces an older one.
        with output_transaction():
            for file in sorted(tmp.iterdir()):
                with atomic_output(out / file.name) as staged:
                    os.replace(file, staged)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def write_report(out: str | Path, title: str, results: dict[str, dict],
                 info: dict[str, Any]) -> Path:
    """Write ``report.md``, ``metrics.json`` and the plots of suite results into ``out``.

    Args:
        out: destination folder (made if missing; files of the same names are replaced).
        title: the report's heading (the evaluated model).
        results: suite name -> suite result.
        info: facts printed at the top and saved in ``metrics.json`` (model, classifier, ...).

    Returns:
        The folder.

    Raises:
        OutputError: the folder or a file in it cannot be written (full disk, read-only or
            forbidden folder, a file of the folder's name); no temporary folder is left.
    """
    out = Path(out)
    try:
        _write_into(out, title, results, info)
    except OSError as exc:
        raise output_error(out, exc) from exc
    return out
