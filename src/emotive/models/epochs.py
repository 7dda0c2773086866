"""The epoch loop shared by the trainers (gait network, QuaterNet, FCRBM).

A trainer gives its epoch (the updates over one pass of the batches), its checkpoint and its
random state; the loop keeps the log (one row per epoch, ``log.csv`` rewritten atomically),
writes ``best.pt`` when the epoch's score improves and ``last.pt`` after every epoch, draws the
progress bars, and on Ctrl-C saves the weights reached in ``last.pt`` with the random state of
the interrupted epoch's start, so that ``--resume`` reruns that epoch with the same batch order.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch


@dataclass(frozen=True)
class EpochOutcome:
    """What one epoch reports.

    Attributes:
        row: logged values (``epoch`` and ``seconds`` are added by the loop).
        score: lower is better; decides ``best.pt``.
        summary: one line for the bar and the printed line of the epoch.
        detail: more text for the printed line only.
    """

    row: dict[str, float | None]
    score: float
    summary: str
    detail: str = ""


@dataclass
class TrainingLog:
    """The state the loop carries across epochs (and a checkpoint saves).

    Attributes:
        history: one row per finished epoch.
        best_val: best score so far (``inf`` before the first epoch).
        start_epoch: epochs already done (``0``, or the resumed checkpoint's epoch).
    """

    history: list[dict[str, Any]] = field(default_factory=list)
    best_val: float = math.inf
    start_epoch: int = 0


def resumed_log(checkpoint: dict[str, Any]) -> TrainingLog:
    """The loop's state saved in a ``last.pt``."""
    epoch = int(checkpoint["epoch"])
    return TrainingLog(list(checkpoint["history"])[:epoch], float(checkpoint["best_val"]), epoch)


def save_checkpoint(path: Path, checkpoint: dict[str, Any]) -> None:
    """``torch.save`` to ``path`` atomically."""
    from emotive.io.atomic import atomic_output

    with atomic_output(path) as tmp:
        torch.save(checkpoint, tmp)


def write_log(path: Path, history: list[dict[str, Any]], columns: tuple[str, ...]) -> None:
    """The training log, one row per epoch (a missing value left empty), atomically."""
    from emotive.io.atomic import atomic_output

    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: "" if row.get(k) is None else row[k] for k in columns})
    with atomic_output(path) as tmp:
        tmp.write_text(text.getvalue())


def run_epochs(
    log: TrainingLog,
    epochs: int,
    n_batches: int,
    out_dir: Path,
    columns: tuple[str, ...],
    run_epoch: Callable[[int, Callable[[str], None]], EpochOutcome],
    checkpoint: Callable[[int, Any], dict[str, Any]],
    rng_state: Callable[[], Any],
    progress: bool,
) -> None:
    """Epochs ``log.start_epoch`` to ``epochs``, updating ``log`` and the files of ``out_dir``.

    Args:
        log: history and best score so far (updated in place).
        epochs: the epoch count to reach.
        n_batches: batches per epoch (the inner bar's length).
        out_dir: folder of ``last.pt``, ``best.pt`` and ``log.csv``.
        columns: the columns of ``log.csv``.
        run_epoch: ``run_epoch(epoch, batch_done)`` trains epoch ``epoch`` (0-based), calling
            ``batch_done(info)`` after every update, and returns its :class:`EpochOutcome`.
        checkpoint: ``checkpoint(epochs_done, rng_state)``, the dict to save (it reads ``log``).
        rng_state: the trainer's random state now.
        progress: progress bars and one line per epoch on stderr.

    Raises:
        KeyboardInterrupt: after writing ``last.pt`` (Ctrl-C).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    last_path, best_path, csv_path = out_dir / "last.pt", out_dir / "best.pt", out_dir / "log.csv"
    console = Console(stderr=True)
    bars = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TextColumn("{task.fields[info]}"), console=console,
                    disable=not progress, transient=True)
    epoch, epoch_state = log.start_epoch, rng_state()
    # Whether the weights moved since last.pt was written (Ctrl-C then has something to save).
    dirty = False

    try:
        with bars:
            epochs_task = bars.add_task("epochs", total=epochs, completed=log.start_epoch,
                                        info="")
            batch_task = bars.add_task("batches", total=n_batches, info="")

            def batch_done(info: str) -> None:
                nonlocal dirty
                dirty = True
                bars.update(batch_task, advance=1, info=info)

            for epoch in range(log.start_epoch, epochs):
                epoch_state, began = rng_state(), time.perf_counter()
                bars.reset(batch_task, total=n_batches)
                outcome = run_epoch(epoch, batch_done)
                log.history.append({"epoch": epoch + 1, **outcome.row,
                                    "seconds": round(time.perf_counter() - began, 3)})
                improved = outcome.score < log.best_val
                log.best_val = min(log.best_val, outcome.score)
                done = checkpoint(epoch + 1, rng_state())
                if improved:
                    save_checkpoint(best_path, done)
                save_checkpoint(last_path, done)
                dirty = False
                write_log(csv_path, log.history, columns)
                summary = outcome.summary + ("  (best)" if improved else "")
                bars.update(epochs_task, advance=1, info=summary)
                if progress:
                    bars.console.print(f"epoch {epoch + 1}/{epochs}: {summary}"
                                       + (f"  {outcome.detail}" if outcome.detail else ""))
    except KeyboardInterrupt:
        if dirty:
            del log.history[epoch:]
            save_checkpoint(last_path, checkpoint(epoch, epoch_state))
            write_log(csv_path, log.history, columns)
        console.print(f"interrupted: wrote {last_path}; continue with --resume")
        raise
