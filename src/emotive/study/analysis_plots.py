"""PNG plots of the study report (matplotlib's Agg canvas; no pyplot global state).

Each plot is written atomically (:func:`emotive.io.atomic.atomic_output`): inside the
:func:`~emotive.io.atomic.output_transaction` of :func:`emotive.study.analyze.analyze_study`
all files of the report appear together or none does.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from emotive.io.atomic import atomic_output

#: File names of the plots.
EMOTION_PLOT = "emotion_intended_vs_perceived.png"
CONFUSION_PLOT = "choice_confusion.png"
AFFECT_PLOT = "affect_grid.png"


def _figure(width: float, height: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib)

    fig = Figure(figsize=(width, height), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, format="png")
    return path


def plot_emotion_bars(out: Path, labels: Sequence[str],
                      items: Sequence[tuple[str, tuple[np.ndarray, np.ndarray] | None,
                                            np.ndarray]]) -> Path | None:
    """Intended and perceived emotion vectors, one panel per stimulus (the paper's Figure 9).

    Args:
        out: the output folder.
        labels: the ``C`` labels.
        items: ``(stimulus, intended (weights (C,), point (2,)) or None, perceived (C,))``.

    Returns:
        The PNG written, or ``None`` when there is nothing to draw.
    """
    if not items:
        return None
    cols = min(5, len(items))
    rows = math.ceil(len(items) / cols)
    fig = _figure(2.6 * cols, 2.3 * rows)
    x = np.arange(len(labels))
    for k, (sid, intended, perceived) in enumerate(items):
        ax = fig.add_subplot(rows, cols, k + 1)
        if intended is not None:
            ax.bar(x - 0.2, intended[0], 0.4, color="#4c72b0", label="intended")
        ax.bar(x + 0.2, perceived, 0.4, color="#dd8452", label="perceived")
        ax.set_xticks(x, list(labels), fontsize=7, rotation=30)
        ax.set_ylim(0, 1)
        ax.tick_params(axis="y", labelsize=7)
        ax.set_title(sid, fontsize=9)
    fig.axes[0].legend(fontsize=7)
    return _save(fig, out / EMOTION_PLOT)


def plot_confusion(out: Path, targets: Sequence[str], options: Sequence[str],
                   counts: np.ndarray) -> Path | None:
    """Confusion matrix of the forced choice: share of each answer per intended emotion.

    Args:
        out: the output folder.
        targets: the intended options, rows.
        options: the answer options, columns.
        counts: ``(len(targets), len(options))`` answer counts.
    """
    counts = np.asarray(counts, dtype=float).reshape(len(targets), len(options))
    if not counts.sum():
        return None
    share = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1.0)
    fig = _figure(1.2 + 0.9 * len(options), 1.0 + 0.8 * len(targets))
    ax = fig.add_subplot()
    ax.imshow(share, cmap="Blues", vmin=0, vmax=1)
    for (i, j), value in np.ndenumerate(share):
        ax.text(j, i, f"{100 * value:.0f}%", ha="center", va="center", fontsize=8,
                color="white" if value > 0.5 else "black")
    ax.set_xticks(range(len(options)), list(options), fontsize=8)
    ax.set_yticks(range(len(targets)), list(targets), fontsize=8)
    ax.set_xlabel("chosen")
    ax.set_ylabel("intended")
    return _save(fig, out / CONFUSION_PLOT)


def plot_affect(out: Path, items: Sequence[tuple[str, str, np.ndarray | None, np.ndarray]]
                ) -> Path | None:
    """Mean perceived against intended points on the valence/arousal grid (-1..1).

    Args:
        out: the output folder.
        items: ``(stimulus, source, intended (2,) or None, perceived mean (2,))``; a line
            joins each intended point (hollow) to its perceived mean (filled).
    """
    if not items:
        return None
    fig = _figure(5.2, 5.0)
    ax = fig.add_subplot()
    sources = sorted({source for _, source, _, _ in items})
    colors = {s: f"C{i % 10}" for i, s in enumerate(sources)}
    for sid, source, intended, perceived in items:
        color = colors[source]
        if intended is not None:
            ax.plot([intended[0], perceived[0]], [intended[1], perceived[1]], color=color,
                    lw=0.8, alpha=0.6)
            ax.scatter([intended[0]], [intended[1]], facecolors="none", edgecolors=color, s=40)
        ax.scatter([perceived[0]], [perceived[1]], color=color, s=30)
        ax.annotate(sid, (perceived[0], perceived[1]), fontsize=6, xytext=(3, 3),
                    textcoords="offset points")
    for source in sources:
        ax.scatter([], [], color=colors[source], label=source or "(none)")
    ax.scatter([], [], facecolors="none", edgecolors="gray", label="intended")
    ax.axhline(0, color="gray", lw=0.5)
    ax.axvline(0, color="gray", lw=0.5)
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_aspect("equal")
    ax.set_xlabel("valence")
    ax.set_ylabel("arousal")
    ax.legend(fontsize=7, loc="lower right")
    return _save(fig, out / AFFECT_PLOT)
