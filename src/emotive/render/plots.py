"""Static plots of per-frame features (matplotlib, Agg canvas; no pyplot global state).

Legend: ``T`` frames.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from emotive.io.atomic import atomic_output

#: Colours of the left and right foot contact shading.
CONTACT_COLOURS = ("tab:blue", "tab:orange")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` frame ranges where a ``(T,)`` bool mask is set (stop exclusive)."""
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def plot_features(
    path: str | os.PathLike,
    times: np.ndarray,
    affective: np.ndarray,
    affective_names: Sequence[str],
    affective_kinds: Sequence[str],
    movement: np.ndarray,
    movement_names: Sequence[str],
    contacts: np.ndarray,
    title: str = "",
) -> Path:
    """Plot affective and movement features over time, with foot contacts shaded.

    Panels: affective angles; affective distance and area ratios; root features (height,
    speed, low-passed speed, curvature); orientation difference and stepping phase; stepping
    frequency. Left / right contacts are shaded in :data:`CONTACT_COLOURS` on every panel.
    The image is written atomically (a temporary file renamed into place); its format
    follows the suffix of ``path`` (``.png``, ``.pdf``, ``.svg``).

    Args:
        path: output image.
        times: ``(T,)`` seconds.
        affective: ``(T, 18)`` affective features.
        affective_names: 18 names.
        affective_kinds: 18 kinds (``"angle"``, ``"distance_ratio"``, ``"area_ratio"``).
        movement: ``(T, C)`` movement features.
        movement_names: ``C`` names.
        contacts: ``(T, 2)`` bool, left and right foot.
        title: figure title.

    Returns:
        The written path.

    Raises:
        ValueError: the arrays' shapes do not agree with each other or with the names.
    """
    n = len(times)
    if (
        affective.shape != (n, len(affective_names))
        or len(affective_kinds) != len(affective_names)
        or movement.shape != (n, len(movement_names))
        or contacts.shape != (n, 2)
    ):
        raise ValueError(
            f"shapes do not agree: times ({n},), affective {affective.shape} with "
            f"{len(affective_names)} names, movement {movement.shape} with "
            f"{len(movement_names)} names, contacts {contacts.shape}"
        )
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415 (heavy: matplotlib)
    from matplotlib.figure import Figure  # noqa: PLC0415 (heavy: matplotlib)

    path = Path(path)
    kinds = np.asarray(affective_kinds)
    mcol = {n: k for k, n in enumerate(movement_names)}
    panels: list[tuple[str, list[tuple[str, np.ndarray]]]] = [
        ("affective angles (rad)",
         [(n, affective[:, k]) for k, n in enumerate(affective_names) if kinds[k] == "angle"]),
        ("affective ratios",
         [(n, affective[:, k]) for k, n in enumerate(affective_names) if kinds[k] != "angle"]),
        ("root (m, m/frame)",
         [(n, movement[:, mcol[n]]) for n in
          ("root_height", "root_speed", "root_speed_lowpass", "curvature") if n in mcol]),
        ("angles (rad)",
         [(n, movement[:, mcol[n]]) for n in ("orientation_difference", "step_phase")
          if n in mcol]),
        ("step frequency (rad/frame)",
         [(n, movement[:, mcol[n]]) for n in ("step_frequency",) if n in mcol]),
    ]
    panels = [p for p in panels if p[1]]
    fig = Figure(figsize=(12, 2.6 * len(panels) + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    dt = float(times[1] - times[0]) if len(times) > 1 else 1.0
    for ax, (label, series) in zip(axes, panels, strict=True):
        for foot, colour in enumerate(CONTACT_COLOURS):
            for start, stop in _runs(np.asarray(contacts[:, foot], dtype=bool)):
                ax.axvspan(times[start], times[stop - 1] + dt, color=colour, alpha=0.12, lw=0)
        for name, values in series:
            ax.plot(times, values, lw=1.0, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, ncol=4 if len(series) > 6 else 2, loc="upper right")
    axes[-1].set_xlabel("time (s); shading: contacts, blue left, orange right")
    if title:
        fig.suptitle(title)
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=100, format=path.suffix.lstrip(".") or "png")
    return path
