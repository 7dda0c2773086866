"""Training machinery shared by the trainers (gait network, QuaterNet, FCRBM).

* Config I/O: :class:`DictConfig` (a frozen dataclass to and from a JSON-safe dict, as saved
  in every checkpoint) and :func:`load_settings` (``[model]`` and ``[train]`` of a TOML file).
* Random state: :func:`seed_everything`, :func:`rng_state`, :func:`restore_rng_state`.
* Checkpoints: :func:`save_checkpoint` (atomic, a failed write an
  :class:`~emotive.errors.OutputError`), :func:`read_checkpoint` (typed one-line errors),
  :func:`slim_checkpoint` (the committed, optimizer-free copy).
* Checkpoint validation, for the loaders' ``build``: :func:`require_keys` (keys and types),
  :func:`check_values` (finite real numbers of a plausible size; standard deviations above 0)
  and :mod:`emotive.models.checkpoint_checks` (the weights tensor by tensor against the
  network of the config, the config's fields, the optimizer state); :func:`read_checkpoint`
  also checks a shipped file's fingerprint, the archive's CRC-32 and the checkpoint's
  top-level entries.
* Resume: :func:`training_paths`, :func:`check_resumable` (same config, settings and seed),
  :func:`resumed_log`.
* The epoch loop :func:`run_epochs`: a trainer gives its epoch (the updates over one pass of
  the batches), its checkpoint and its random state; the loop keeps the log (one row per
  epoch, ``log.csv`` rewritten atomically), writes ``best.pt`` when the epoch's score improves
  and ``last.pt`` after every epoch, and draws the progress bars. Ctrl-C leaves ``last.pt`` at
  the last finished epoch (the weights reached inside the interrupted epoch are dropped), so
  that ``--resume`` reruns that epoch from its start and gives the results of not stopping.
"""

from __future__ import annotations

import csv
import io
import json
import math
import pickle
import time
import tomllib
from collections.abc import Callable, Collection
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Self, TypeVar

import numpy as np
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from emotive.data.emotion import ALL_LABELS
from emotive.errors import ConfigError, EmotiveError, OutputError
from emotive.io.atomic import atomic_output
from emotive.models.checkpoint_checks import check_archive, check_entries, check_fingerprint

T = TypeVar("T")

#: Largest magnitude a saved weight, statistic or control may have. Trained values stay within
#: a few units; one beyond this comes from a diverged training or a corrupt file, and would
#: make every output NaN or absurd.
MAX_MAGNITUDE = 1e6


class DictConfig:
    """Mixin of a frozen dataclass config: dict and JSON conversions.

    Mixin of a frozen dataclass config: :meth:`to_dict`/:meth:`from_dict` (tuples stored as
    lists) and their JSON texts; a checkpoint holds ``config.to_dict()``.
    """

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        """The config saved by :meth:`to_dict`.

        Raises:
            ValueError: a key that is not a field (a checkpoint of another model or version).
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown {cls.__name__} fields {unknown}; known: {sorted(known)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})

    def to_json(self) -> str:
        """The config as a JSON text."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Self:
        """The config from :meth:`to_json` text."""
        return cls.from_dict(json.loads(text))


def load_settings(path: str | Path, model_class: type, train_class: type,
                  model_defaults: dict[str, Any] | None = None) -> tuple[Any, Any]:
    """Read ``[model]`` and ``[train]`` from a TOML file.

    Read ``[model]`` (``model_class`` fields) and ``[train]`` (``train_class`` fields) from
    a TOML file.

    Missing keys keep their defaults, except that a ``[model] labels`` field defaults to
    :data:`~emotive.data.emotion.ALL_LABELS` (every style a label of the emotion vector) and
    ``model_defaults`` fills keys the file cannot give (e.g. sizes set by the data).

    Args:
        path: the TOML file.
        model_class: dataclass of the ``[model]`` section.
        train_class: dataclass of the ``[train]`` section.
        model_defaults: ``[model]`` values set by the program; the file may not give them.

    Returns:
        ``(model_class(...), train_class(...))``.

    Raises:
        ConfigError: the file is missing or not TOML, or has an unknown section, an unknown
            key or a bad value; the message names the file and the key.
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{path}: config file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the config file ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
    unknown = sorted(set(doc) - {"model", "train"})
    if unknown:
        raise ConfigError(f"{path}: unknown section [{unknown[0]}]; known: [model], [train]")
    built: list[Any] = []
    for section, cls in (("model", model_class), ("train", train_class)):
        values = doc.get(section, {})
        if not isinstance(values, dict):
            raise ConfigError(f"{path}: {section} must be a [{section}] table")
        known = [f.name for f in fields(cls)]
        for key in values:
            if key not in known:
                raise ConfigError(
                    f"{path}: unknown key [{section}] {key}; known: {', '.join(known)}"
                )
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        if cls is model_class and "labels" in known:
            values.setdefault("labels", ALL_LABELS)
        if cls is model_class:
            for key in model_defaults or {}:
                if key in values:
                    raise ConfigError(f"{path}: [model] {key} is set from the data; remove it")
            values.update(model_defaults or {})
        try:
            built.append(cls(**values))
        except (ValueError, TypeError, EmotiveError) as exc:
            message = str(exc).removeprefix(f"{cls.__name__}.")
            key = next((k for k in values if message.startswith(k)), None)
            where = f"[{section}] {key}" if key else f"[{section}]"
            raise ConfigError(f"{path}: {where}: {message}") from None
    return built[0], built[1]


def seed_everything(seed: int) -> np.random.Generator:
    """Seed torch's global generator and return a NumPy generator of the same seed.

    Seed torch's global generator (initial weights) and return a NumPy generator of the same
    seed (batch order and other draws), in that order.
    """
    torch.manual_seed(seed)
    return np.random.default_rng(seed)


def rng_state(rng: np.random.Generator, generator: torch.Generator | None = None
              ) -> dict[str, Any]:
    """The state of ``rng`` and of ``generator``, as a checkpoint saves it.

    ``{"numpy", "torch"}``: the state of ``rng`` and of ``generator`` (torch's global
    generator when ``None``), as a checkpoint saves it.
    """
    torch_state = torch.get_rng_state() if generator is None else generator.get_state()
    return {"numpy": rng.bit_generator.state, "torch": torch_state}


def restore_rng_state(rng: np.random.Generator, state: dict[str, Any],
                      generator: torch.Generator | None = None) -> None:
    """Put back a state of :func:`rng_state` into ``rng`` and ``generator``.

    Put back a state of :func:`rng_state` into ``rng`` and ``generator`` (torch's global
    generator when ``None``).
    """
    rng.bit_generator.state = state["numpy"]
    if generator is None:
        torch.set_rng_state(state["torch"])
    else:
        generator.set_state(state["torch"])


def one_line(exc: BaseException) -> str:
    """The first line of an exception's message (torch's run over several), or its type."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _write_failure(exc: BaseException) -> str:
    """Why a write failed, in one line: the system's reason, or torch's zip writer failing."""
    if isinstance(exc, OSError):
        return exc.strerror or one_line(exc)
    # torch's zip writer reports a short write (a full disk) as "[enforce fail at ...]".
    return "the write stopped part-way, as on a full disk"


def save_checkpoint(path: Path, checkpoint: dict[str, Any]) -> None:
    """``torch.save`` to ``path`` atomically: a failure leaves ``path`` as it was.

    Raises:
        OutputError: the file cannot be written (a full disk, no permission, no folder); no
            temporary file is left and a previous ``path`` is kept.
    """
    try:
        with atomic_output(path) as tmp:
            torch.save(checkpoint, tmp)
    except (OSError, RuntimeError) as exc:
        raise OutputError(f"{path}: cannot write the checkpoint ({_write_failure(exc)}); free "
                          "disk space or fix the folder's permissions, or give another --out"
                          ) from None


def require_keys(checkpoint: dict[str, Any], kinds: dict[str, type | tuple[type, ...]]) -> None:
    """Check that ``checkpoint`` has each key of ``kinds``, of that type.

    Raises:
        ValueError: the first missing key or value of another type, named.
    """
    for key, kind in kinds.items():
        if key not in checkpoint:
            raise ValueError(f"no {key!r} entry")
        if not isinstance(checkpoint[key], kind):
            names = " or ".join(k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,)))
            raise ValueError(f"{key!r} is a {type(checkpoint[key]).__name__}, not a {names}")


def _check_array(array: np.ndarray, name: str, positive: bool) -> None:
    """:func:`check_values` of one numeric array."""
    if array.dtype.kind == "c":
        raise ValueError(f"{name} holds complex numbers, not real ones")
    if array.dtype.kind not in "biuf" or array.size == 0:
        return
    values = array.astype(np.float64, copy=False).reshape(-1)
    bad = ~np.isfinite(values) | (np.abs(values) > MAX_MAGNITUDE)
    if bad.any():
        value = values[np.flatnonzero(bad)[0]]
        size = "" if not np.isfinite(value) else f", beyond the plausible {MAX_MAGNITUDE:g}"
        raise ValueError(f"{name} holds {value:g}{size}, as from a diverged training or a "
                         "corrupt file")
    if positive and not (values > 0).all():
        value = values[np.flatnonzero(values <= 0)[0]]
        raise ValueError(f"{name} holds {value:g}; a standard deviation must be above 0")


def check_values(value: Any, name: str, positive: bool = False) -> None:
    """Check that every number in ``value`` is real, finite and at most :data:`MAX_MAGNITUDE`.

    Args:
        value: a tensor, an array, a number, or a dict, list or tuple of them, as a checkpoint
            holds weights, statistics and controls (strings, booleans and ``None`` pass; a
            complex number or tensor and a bool tensor are refused).
        name: how the message names ``value`` (``"state['fc.weight']"``).
        positive: every number must also be above 0 (a standard deviation).

    Raises:
        ValueError: the first bad entry, named, in one line.
    """
    if isinstance(value, dict):
        for key, item in value.items():
            check_values(item, f"{name}[{key!r}]", positive)
    elif isinstance(value, torch.Tensor):
        if value.is_complex() or value.dtype == torch.bool:
            raise ValueError(f"{name} is a {value.dtype} tensor, not real numbers")
        if value.is_floating_point() or positive:
            _check_array(value.detach().cpu().double().numpy(), name, positive)
    elif isinstance(value, (list, tuple)):
        try:
            array = np.asarray(value)
        except ValueError:  # ragged
            array = np.asarray(None)
        if array.dtype.kind in "biuf":
            _check_array(array, name, positive)
        else:
            for k, item in enumerate(value):
                check_values(item, f"{name}[{k}]", positive)
    elif isinstance(value, (complex, np.complexfloating)):
        raise ValueError(f"{name} holds the complex number {value}, not a real one")
    elif isinstance(value, (int, float, np.ndarray, np.number)) and not isinstance(value, bool):
        _check_array(np.asarray(value), name, positive)


def _read_failure(exc: BaseException) -> str:
    """Why ``torch.load`` failed, in one line and in our words."""
    if isinstance(exc, pickle.UnpicklingError) and "Weights only" in str(exc):
        return "it holds Python objects, not only tensors, numbers and strings"
    if isinstance(exc, OSError):
        return f"cannot read it: {exc.strerror or one_line(exc)}"
    return "truncated, corrupt, or not a PyTorch file"


def read_checkpoint(path: str | Path, what: str, build: Callable[[dict[str, Any]], T],
                    fix: str, entries: Collection[str] | None = None
                    ) -> tuple[T, dict[str, Any]]:
    """A checkpoint dict and what ``build`` makes of it, every failure a :class:`ConfigError`.

    A shipped file (under ``emotive/assets``) must first match the sha256 of its model card
    (:func:`~emotive.models.checkpoint_checks.check_fingerprint`), and every file's zip
    records their CRC-32 (:func:`~emotive.models.checkpoint_checks.check_archive`). The
    message is one line:
    torch's multi-line reports are replaced by our words, and an exception of ``build`` gives
    its first line.

    Args:
        path: the checkpoint file.
        what: the kind of checkpoint expected, for the message (``"a gait checkpoint"``).
        build: makes the model of the dict, validating it (:func:`require_keys`,
            :func:`~emotive.models.checkpoint_checks.build_weights`, :func:`check_values`);
            any exception it raises means "not ``what``", its first line the reason.
        fix: how the user gets a good checkpoint, for the message.
        entries: the top-level keys a checkpoint of this kind may hold; any other, and
            oversized tensors beside the weights, are refused
            (:func:`~emotive.models.checkpoint_checks.check_entries`). ``None``: not checked.

    Returns:
        ``(build(checkpoint), checkpoint)``.

    Raises:
        ConfigError: ``path`` is a folder, is missing, is a damaged shipped file, cannot be
            read (truncated, not a torch file), or is not ``what``.
    """
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder; give the checkpoint file in it")
    if not path.is_file():
        raise ConfigError(f"{path}: checkpoint not found; {fix}")
    check_fingerprint(path)
    try:
        check_archive(path)
    except ValueError as exc:
        raise ConfigError(f"{path}: not {what} ({exc}); {fix}") from None
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many types on a file it cannot read
        raise ConfigError(f"{path}: not {what} ({_read_failure(exc)}); {fix}") from None
    try:
        if not isinstance(ckpt, dict):
            raise ValueError(f"holds a {type(ckpt).__name__}, not a dict")
        if entries is not None:
            check_entries(ckpt, entries)
        built = build(ckpt)
    except Exception as exc:  # any failure to build is the same problem for the user
        raise ConfigError(f"{path}: not {what} ({one_line(exc)}); {fix}") from None
    return built, ckpt


def slim_checkpoint(source: str | Path, out: str | Path, keys: tuple[str, ...]) -> Path:
    """Copy the ``keys`` of a checkpoint (weights as float32) to ``out``, atomically.

    For committing checkpoints without optimizer state. The caller validates ``source``.
    """
    ckpt = torch.load(source, map_location="cpu", weights_only=True)
    slim: dict[str, Any] = {k: ckpt[k] for k in keys if k in ckpt}
    slim["state"] = {k: v.float() if v.is_floating_point() else v
                     for k, v in slim["state"].items()}
    out = Path(out)
    with atomic_output(out) as tmp:
        torch.save(slim, tmp)
    return out


def training_paths(out_dir: Path, resume: bool) -> Path:
    """``out_dir`` created, and its ``last.pt``.

    Raises:
        ConfigError: ``resume`` without a ``last.pt`` to resume from.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    last_path = out_dir / "last.pt"
    if resume and not last_path.exists():
        raise ConfigError(f"{last_path}: no checkpoint to resume from")
    return last_path


def check_resumable(path: Path, checkpoint: dict[str, Any], config: dict[str, Any],
                    train: dict[str, Any], seed: int) -> None:
    """Check that a run of ``config``, ``train`` and ``seed`` may continue ``checkpoint``.

    The same ``"config"``, the same ``"train"`` but for ``epochs``, and the same ``"seed"``.
    Another seed is refused rather than ignored: the resumed run restores the checkpoint's
    random state, so the new seed would have no effect, and the result would not be that of
    either seed run without a stop. A config's own ``seed`` field (the FCRBM's is the run's
    seed) is compared with the seeds, so that its message names both.

    Args:
        path: the checkpoint's file, for the message.
        checkpoint: the saved dict (its ``"config"`` and ``"train"`` as the trainer compares
            them, e.g. with new settings filled with their defaults; its ``"seed"``, when it
            has one).
        config: the run's ``config.to_dict()``.
        train: the run's ``settings.to_dict()``.
        seed: the run's ``--seed``.

    Raises:
        ConfigError: the seed, the model config or the training settings differ.
    """
    def unseeded(values: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in values.items() if k != "seed"}

    if unseeded(checkpoint["config"]) != unseeded(config):
        raise ConfigError(f"{path}: made with another [model] config; cannot resume (resume "
                          "with the config it was made with, or give a new --out)")
    saved = {k: v for k, v in checkpoint["train"].items() if k != "epochs"}
    if saved != {k: v for k, v in train.items() if k != "epochs"}:
        raise ConfigError(f"{path}: made with other [train] settings; cannot resume (only "
                          "epochs may change; or give a new --out)")
    saved_seed = checkpoint.get("seed")
    if saved_seed is None:
        saved_seed = checkpoint["config"].get("seed")
    if saved_seed is not None and saved_seed != seed:
        raise ConfigError(f"{path}: made with --seed {saved_seed}, resumed with --seed {seed}; "
                          f"cannot resume (resume with --seed {saved_seed}, or give a new --out "
                          f"to start over with --seed {seed})")
    if checkpoint["config"] != config:
        raise ConfigError(f"{path}: made with another [model] seed; cannot resume (resume "
                          "with the config it was made with, or give a new --out)")


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

    @property
    def best_or_nan(self) -> float:
        """The best score, ``nan`` when no epoch had a finite one."""
        return self.best_val if math.isfinite(self.best_val) else math.nan


def resumed_log(checkpoint: dict[str, Any]) -> TrainingLog:
    """The loop's state saved in a ``last.pt``."""
    epoch = int(checkpoint["epoch"])
    return TrainingLog(list(checkpoint["history"])[:epoch], float(checkpoint["best_val"]), epoch)


def write_log(path: Path, history: list[dict[str, Any]], columns: tuple[str, ...]) -> None:
    """The training log, one row per epoch (a missing value left empty), atomically.

    Raises:
        OutputError: the file cannot be written; a previous ``path`` is kept.
    """
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in history:
        writer.writerow({k: "" if row.get(k) is None else row[k] for k in columns})
    try:
        with atomic_output(path) as tmp:
            tmp.write_text(text.getvalue())
    except OSError as exc:
        raise OutputError(f"{path}: cannot write the training log ({_write_failure(exc)}); "
                          "free disk space or fix the folder's permissions") from None


def _kept(epochs_done: int | None) -> str:
    """What ``last.pt`` holds, for a message."""
    return "nothing of this run" if epochs_done is None else f"epoch {epochs_done}"


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
    write: bool = True,
) -> None:
    """Epochs ``log.start_epoch`` to ``epochs``, updating ``log`` and the files of ``out_dir``.

    ``last.pt`` only ever holds the end of a finished epoch (with the random state there), so
    resuming after Ctrl-C or kill -9 reruns the interrupted epoch from its start and gives the
    results of not stopping.

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
        write: write the files and messages (``False``: a training process other than the
            first, :mod:`emotive.models.distributed`).

    Raises:
        OutputError: a checkpoint or the log cannot be written; the message says which epoch
            ``last.pt`` keeps.
        KeyboardInterrupt: Ctrl-C, after putting ``log`` and ``log.csv`` back to the epoch
            ``last.pt`` keeps (the interrupted epoch's updates are dropped).
    """
    last_path, best_path, csv_path = out_dir / "last.pt", out_dir / "best.pt", out_dir / "log.csv"
    console = Console(stderr=True)
    bars = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TimeElapsedColumn(), TextColumn("{task.fields[info]}"), console=console,
                    disable=not progress, transient=True)
    # Epochs done in last.pt by this run or the one it resumes; None before either wrote one.
    kept: int | None = log.start_epoch or None
    epoch, best_before = log.start_epoch, log.best_val

    try:
        with bars:
            epochs_task = bars.add_task("epochs", total=epochs, completed=log.start_epoch,
                                        info="")
            batch_task = bars.add_task("batches", total=n_batches, info="")

            def batch_done(info: str) -> None:
                bars.update(batch_task, advance=1, info=info)

            for epoch in range(log.start_epoch, epochs):
                began, best_before = time.perf_counter(), log.best_val
                bars.reset(batch_task, total=n_batches)
                outcome = run_epoch(epoch, batch_done)
                log.history.append({"epoch": epoch + 1, **outcome.row,
                                    "seconds": round(time.perf_counter() - began, 3)})
                improved = outcome.score < log.best_val
                log.best_val = min(log.best_val, outcome.score)
                if not write:
                    continue
                done = checkpoint(epoch + 1, rng_state())
                try:
                    if improved:
                        save_checkpoint(best_path, done)
                    save_checkpoint(last_path, done)
                    kept = epoch + 1
                    write_log(csv_path, log.history, columns)
                except OutputError as exc:
                    raise OutputError(f"{exc}; training stopped after epoch {epoch + 1}, "
                                      f"{last_path} keeps {_kept(kept)}") from None
                summary = outcome.summary + ("  (best)" if improved else "")
                bars.update(epochs_task, advance=1, info=summary)
                if progress:
                    bars.console.print(f"epoch {epoch + 1}/{epochs}: {summary}"
                                       + (f"  {outcome.detail}" if outcome.detail else ""))
    except KeyboardInterrupt:
        if not write:
            raise
        if kept != epoch + 1:
            log.best_val = best_before
        if kept is None:
            del log.history[:]
            console.print(f"interrupted in epoch {epoch + 1}, before any epoch finished: "
                          f"nothing saved; run again to start over")
        else:
            del log.history[kept:]
            write_log(csv_path, log.history, columns)
            console.print(f"interrupted in epoch {epoch + 1}: {last_path} keeps epoch {kept}; "
                          "continue with --resume")
        raise
