"""``synthesize``: make (or finish) a synthetic data set folder from a recipe.

The main paper's augmented data set (Bhattacharya et al. 2020, section 5.2) made end to end:

1. the inputs are checked before anything is written: the recipe (:class:`Recipe`), the
   model (:func:`emotive.models.registry.get_model`), the rig, and that a cluster answers at
   ``address``;
2. the folder is opened (:func:`emotive.synth.store.open_folder`): locked, its recipe
   compared, a killed run's temporary files removed;
3. the trajectories are drawn, each again while it coincides with the data
   (:mod:`emotive.synth.novelty`; the draws and the check kept in ``novelty.json``, and
   checked again by a later run while the data was missing); then ``recipe.json`` is
   written;
4. the shards not yet there are made on Ray (:mod:`emotive.synth.engine`), each written as it
   comes back, so a run that is stopped (Ctrl-C, SIGKILL, a full disk, a lost cluster) keeps
   what it finished and a rerun continues;
5. ``manifest.parquet`` and ``README.md`` are written (all or none) from the shards.

A rerun of a finished folder makes nothing and rewrites nothing; it takes seconds.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import sys
import time
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

import emotive
from emotive.io.atomic import atomic_output, output_transaction
from emotive.io.motion_files import read_motion
from emotive.models.registry import ModelError, get_model, model_names
from emotive.retarget import resolve_rig
from emotive.synth import card, emotions, engine, manifest, novelty, store, trajectories
from emotive.synth.recipe import Recipe, SynthError
from emotive.synth.shards import make_shard, shard_name
from emotive.synth.walkers import check_walker, load_walker

#: Help for a recipe's ``model`` that is unknown or makes no motion.
GENERATORS_HINT = "see `emotive models`"


@dataclass(frozen=True)
class SynthReport:
    """What :func:`synthesize` did.

    Attributes:
        out: the folder.
        walks: walks in the data set.
        shards: shards in the data set.
        made: shards made by this run.
        kept: shards already there.
        seconds: wall time of this run, seconds.
        walks_per_second: walks made per second of the engine's time (0 if none made).
        where: where they were made (``local Ray, 2 workers``, a cluster's address).
        steady_walks_per_second: walks per second once the workers had started (after the
            first shard; 0 with one shard).
    """

    out: Path
    walks: int
    shards: int
    made: int
    kept: int
    seconds: float
    walks_per_second: float
    where: str
    steady_walks_per_second: float = 0.0

    def summary(self) -> str:
        """One line for the command line."""
        rate = f", {self.walks_per_second:.1f} walks/s on {self.where}" if self.made else ""
        return (f"wrote {self.out}: {self.walks} walks in {self.shards} shards ({self.made} "
                f"made now, {self.kept} already there) in {self.seconds:.1f} s{rate}")


def model_facts(model: str) -> dict[str, Any]:
    """The recipe's entries about ``model``: its weights (with their sha256) and its emotions.

    Raises:
        ModelError: an unknown model or one that makes no motion.
    """
    entry = get_model(model)
    if "generator" not in entry.kinds:
        raise ModelError(f"--model {model}: it makes no new motion (it is a "
                         f"{', '.join(entry.kinds)}); use one of "
                         f"{', '.join(model_names('generator'))} ({GENERATORS_HINT})")
    weights = entry.weights
    if weights.startswith("assets/"):
        data = (resources.files("emotive") / weights).read_bytes()
        weights = f"{weights} (sha256 {hashlib.sha256(data).hexdigest()[:16]})"
    adapter = importlib.import_module(entry.loaders["generator"].partition(":")[0])
    caps = getattr(adapter, "CAPABILITIES", None)
    return {"weights": weights,
            "valence_arousal_model": bool(caps is not None and caps.valence_arousal)}


def recipe_values(recipe: Recipe) -> dict[str, Any]:
    """The folder's ``recipe.json``: the recipe, the ranges, the model's facts, the version."""
    return recipe.to_dict({"trajectories": trajectories.ranges(),
                           "emotion_draws": emotions.ranges(),
                           "emotive": emotive.__version__, **model_facts(recipe.model)})


def read_rig(rig: str | os.PathLike, roles: str | None) -> tuple[Any, dict[str, str]]:
    """The ``--rig`` clip and its identity (name, sha256).

    Raises:
        BVHError, MotionFileError: the file cannot be read. RigError: it lacks roles.
    """
    path = Path(rig)
    motion = read_motion(path)
    resolve_rig(motion.skeleton, roles, f"--rig {path}: target", "--rig-roles")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()[:16]
    return motion, {"name": path.name, "sha256": digest}


def synthesize(out: str | os.PathLike, recipe: Recipe | None = None, *,
               rig: str | os.PathLike | None = None, workers: int | None = None,
               address: str | None = None, progress: bool | None = None) -> SynthReport:
    """Make the data set of ``recipe`` in ``out``, or finish it (module docstring).

    Args:
        out: the folder: new, empty, or one made with the same recipe.
        recipe: what to make (default: the paper's recipe, :class:`Recipe`).
        rig: a rig file (``.bvh``, ``.glb``, ``.fbx``) to retarget every walk onto.
        workers: shards made at once (default: this machine's CPUs, or the cluster's).
        address: a Ray cluster's address (``HOST:PORT``), or ``None`` for a local Ray.
        progress: show progress on stderr (default: a bar on a terminal, else a line per
            shard).

    Returns:
        What the run did.

    Raises:
        SynthError: a bad recipe, folder or cluster (the subclasses name the input and fix).
        ModelError: an unknown model or one that makes no motion.
        OutputError: a file that could not be written (a full disk, ...); what was finished
            is kept and a rerun continues.
        EmotiveError: a bad rig, or the model's own error on this recipe.
    """
    begin = time.perf_counter()
    recipe = recipe or Recipe()
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise SynthError(f"--workers {workers!r}: give a whole number of workers, 1 or more")
    rig_motion = None
    if rig is not None:
        rig_motion, identity = read_rig(rig, recipe.rig_roles)
        recipe = replace(recipe, rig=identity)
    values = recipe_values(recipe)
    if address is not None:
        engine.check_reachable(address)
    folder = store.open_folder(out, values)
    try:
        done = folder.done_shards(recipe.shards)
        todo = [s for s in range(recipe.shards) if s not in done]
        paths, report, fresh = _trajectories(folder, recipe)
        if todo:
            _check_model(recipe)
        store.write_recipe(folder, report.to_dict(), replace_novelty=fresh)
        stats = None
        if todo:
            show = _Progress(recipe, len(done), progress)
            try:
                stats = engine.run_shards(
                    todo, make_shard, (values, rig_motion, report.draws(recipe.paths)),
                    lambda result: folder.write_files(result.files), workers, address,
                    show.update)
            finally:
                show.close()
        if todo or fresh or not (folder.has(store.MANIFEST) and folder.has(store.CARD)):
            finish(folder, recipe, [p.summary() for p in paths])
    except BaseException:
        if not folder.has(store.RECIPE):
            store.discard(folder)
        raise
    finally:
        folder.close()
    return SynthReport(folder.root, recipe.total, recipe.shards, len(todo), len(done),
                       time.perf_counter() - begin,
                       stats.walks_per_second if stats else 0.0, stats.where if stats else "",
                       stats.steady_walks_per_second if stats else 0.0)


def _trajectories(folder: Any, recipe: Recipe) -> tuple[list[trajectories.Trajectory],
                                                         novelty.NoveltyReport, bool]:
    """The folder's trajectories, their novelty report, and whether ``novelty.json`` is stale.

    A new folder draws them (:func:`emotive.synth.novelty.novel_trajectories`); a folder keeps
    the draws its ``novelty.json`` names, and a check skipped there for want of the data (or
    made with other thresholds) runs again on them, in case the data is there now.

    Raises:
        NoveltyError: a trajectory that is not novel (see the module it comes from).
    """
    if not folder.has(store.NOVELTY):
        paths, report = novelty.novel_trajectories(recipe.seed, recipe.paths, recipe.seconds)
        return paths, report, False
    stored = folder.read_json(store.NOVELTY)
    report = novelty.NoveltyReport.from_dict(stored)
    paths = [trajectories.trajectory(recipe.seed, p, recipe.seconds, draw)
             for p, draw in enumerate(report.draws(recipe.paths))]
    if report.checked and novelty.same_thresholds(stored):
        return paths, report, False
    report = novelty.check_trajectories(paths)
    novelty.raise_if_coinciding(report)
    return paths, report, report.checked


def _check_model(recipe: Recipe) -> None:
    """Raise for a recipe the model cannot make, before any shard (loads the model here).

    Raises:
        SynthError: transitions for a model of constant emotions, or walks too long.
        EmotiveError: the model cannot be loaded (its data missing, ...).
    """
    check_walker(load_walker(recipe.model), recipe.model, recipe.transitions, recipe.seconds)


def finish(folder: Any, recipe: Recipe, paths: list[dict[str, Any]]) -> None:
    """Write ``manifest.parquet`` and ``README.md`` from the shards (all or none)."""
    rows = []
    for shard in range(recipe.shards):
        with np.load(folder.root / shard_name(shard), allow_pickle=False) as data:
            rows += json.loads(str(data["rows"]))
    table = manifest.table(rows, folder.values)
    text = card.card_text(folder.values, folder.read_json(store.NOVELTY), table, paths,
                          folder.recipe_id)
    with output_transaction():
        manifest.write_manifest(table, folder.root / store.MANIFEST)
        with atomic_output(folder.root / store.CARD) as tmp:
            tmp.write_text(text, encoding="utf-8")


class _Progress:
    """Progress on stderr: a bar on a terminal, else a line per shard."""

    def __init__(self, recipe: Recipe, done: int, show: bool | None) -> None:
        self.console = Console(stderr=True)
        self.show = True if show is None else show
        self.bar = self.show and self.console.is_terminal
        self.total = recipe.total
        self.before = sum(len(recipe.shard_range(s)) for s in range(done))
        self.shards = recipe.shards
        self.done_before = done
        self.start = time.perf_counter()
        self.progress: Any = None
        self.task: Any = None

    def update(self, event: str, shards: int, walks: int) -> None:
        if not self.show:
            return
        if event.startswith("start:"):
            self.start = time.perf_counter()
            self.console.print(f"synth: {self.total} walks in {self.shards} shards, "
                               f"{self.done_before} already there; {event[6:]}",
                               highlight=False, soft_wrap=True)
            if self.bar:
                self._start_bar()
            return
        done = self.before + walks
        elapsed = time.perf_counter() - self.start
        rate = walks / elapsed if elapsed > 0 else 0.0
        if self.progress is not None:
            self.progress.update(self.task, completed=done, rate=f"{rate:.1f} walks/s")
            return
        eta = (self.total - done) / rate if rate > 0 else float("nan")
        self.console.print(f"synth: {done}/{self.total} walks ({done / self.total:.0%}), "
                           f"{rate:.1f} walks/s, ETA {_clock(eta)}", highlight=False,
                           soft_wrap=True)
        sys.stderr.flush()

    def _start_bar(self) -> None:
        self.progress = Progress(
            TextColumn("synth"), BarColumn(), MofNCompleteColumn(), TextColumn("walks"),
            TextColumn("{task.fields[rate]}"), TimeRemainingColumn(), console=self.console)
        self.task = self.progress.add_task("synth", total=self.total, completed=self.before,
                                           rate="")
        self.progress.start()

    def close(self) -> None:
        if self.progress is not None:
            self.progress.stop()


def _clock(seconds: float) -> str:
    if not seconds == seconds or seconds == float("inf"):
        return "-"
    s = round(seconds)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"
