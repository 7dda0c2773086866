"""The folder of a synthetic data set: its recipe, its lock, its finished shards.

A data set folder (``emotive synth --out DIR``, section 5.2's augmented data set) holds:

* ``recipe.json``: the recipe it is made with (:meth:`Recipe.to_dict
  <emotive.synth.recipe.Recipe.to_dict>` with the ranges, the weights and the rig), written
  before the first shard; a run with another recipe is refused (:class:`FolderError`);
* ``novelty.json``: the check of the trajectories against the data
  (:mod:`emotive.synth.novelty`);
* ``shards/shard-NNNNN.npz`` (:mod:`emotive.synth.shards`) and, with ``--formats``,
  ``bvh/`` and ``glb/``: each shard's files are written together, the shard file last and
  all or none (:func:`emotive.io.atomic.output_transaction`), so a shard file that exists is
  finished and a rerun skips it;
* ``manifest.parquet`` and ``README.md`` when every shard is there.

One run at a time writes a folder: ``.synth.lock`` is locked (:func:`fcntl.flock`, released
by the kernel however the run ends); the run that holds it first removes the temporary files
a killed run left (names starting with ``.`` and holding ``.tmp`` or ``.old``, as
:mod:`emotive.io.atomic` makes them).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from emotive.io.atomic import atomic_output, output_error, output_transaction
from emotive.synth.recipe import SynthError, recipe_id
from emotive.synth.shards import SHARDS, shard_name

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

RECIPE = "recipe.json"
NOVELTY = "novelty.json"
MANIFEST = "manifest.parquet"
CARD = "README.md"
LOCK = ".synth.lock"
#: Sub-folders a data set writes into.
FOLDERS = (SHARDS, "bvh", "glb")
#: Temporary files of :mod:`emotive.io.atomic` (``.NAME.XXXX.tmp.SUFFIX``, ``.NAME.XXXX.old``).
_LEFTOVER = re.compile(r"^\..+\.(tmp|old)(\.[A-Za-z0-9]+)?$")


class FolderError(SynthError):
    """An ``--out`` folder that holds something else or is being written by another run."""


@dataclass
class Folder:
    """An open data set folder (use :func:`open_folder`).

    Attributes:
        root: the folder.
        values: the recipe it is made with.
        created: whether this run made the folder.
    """

    root: Path
    values: dict[str, Any]
    created: bool = False
    _lock: int | None = field(default=None, repr=False)

    @property
    def recipe_id(self) -> str:
        """The recipe's id."""
        return recipe_id(self.values)

    def has(self, name: str) -> bool:
        """Whether the file ``name`` (relative) is there."""
        return (self.root / name).is_file()

    def read_json(self, name: str) -> Any:
        """The JSON file ``name`` (relative)."""
        return json.loads((self.root / name).read_text(encoding="utf-8"))

    def write_files(self, files: dict[str, bytes]) -> None:
        """Write ``files`` (relative path -> bytes) all or none, in their order.

        Raises:
            OutputError: a file could not be written whole (a full disk, ...); then none is.
        """
        try:
            for name in files:
                (self.root / name).parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise output_error(self.root / name, exc) from exc
        with output_transaction():
            for name, data in files.items():
                with atomic_output(self.root / name) as tmp:
                    tmp.write_bytes(data)

    def done_shards(self, count: int) -> set[int]:
        """The shards among ``range(count)`` whose file is there and of this recipe."""
        done = set()
        for shard in range(count):
            path = self.root / shard_name(shard)
            if not path.is_file():
                continue
            try:
                with np.load(path, allow_pickle=False) as data:
                    if str(data["recipe_id"]) == self.recipe_id:
                        done.add(shard)
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
                continue  # unreadable: made again
        return done

    def close(self) -> None:
        """Release the lock (the kernel does when the process ends, however it ends)."""
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None


def open_folder(root: str | os.PathLike, values: dict[str, Any]) -> Folder:
    """Open ``root`` for the recipe ``values``: create it, lock it, check its recipe.

    The recipe file is not written here (:func:`write_recipe` writes it once the inputs are
    checked), and a folder this call created is removed again by :func:`discard` if the run
    stops before writing anything.

    Raises:
        FolderError: ``root`` is a file, holds another recipe or other files, or another run
            is writing it.
        OutputError: ``root`` cannot be created or written.
    """
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise FolderError(f"--out {root}: it is a file; give a folder (new, empty, or one "
                          "this command made)")
    created = not root.exists()
    lock_path = root / LOCK
    try:
        root.mkdir(parents=True, exist_ok=True)
        new_lock = not lock_path.exists()
        lock = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        raise output_error(root, exc) from exc
    folder = Folder(root, values, created, lock)
    held = False
    try:
        if fcntl is not None:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise FolderError(f"--out {root}: another emotive synth is writing it; wait "
                                  "for it to finish (or stop it), then run again") from None
        held = True
        _check_recipe(root, values)
        remove_leftovers(root)
    except BaseException:
        # A folder this run refuses keeps what it held: no lock file of ours is left in it.
        if held and new_lock:
            with contextlib.suppress(OSError):
                lock_path.unlink()
        folder.close()
        if created:
            with contextlib.suppress(OSError):
                root.rmdir()
        raise
    return folder


def _check_recipe(root: Path, values: dict[str, Any]) -> None:
    """Raise :class:`FolderError` unless ``root`` is empty (but for the lock) or of ``values``."""
    path = root / RECIPE
    if not path.is_file():
        others = sorted(p.name for p in root.iterdir()
                        if p.name != LOCK and not _LEFTOVER.match(p.name))
        if others:
            raise FolderError(f"--out {root}: it holds {', '.join(others[:3])}"
                              f"{' ...' if len(others) > 3 else ''} and no {RECIPE}; give a "
                              "new or empty folder")
        return
    try:
        theirs = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise FolderError(f"--out {root}: its {RECIPE} cannot be read ({exc}); give another "
                          "folder") from None
    if theirs != values:
        diff = [f"{k} {_short(theirs.get(k))} there, {_short(values.get(k))} here"
                for k in sorted(set(theirs) | set(values)) if theirs.get(k) != values.get(k)]
        raise FolderError(f"--out {root} holds another recipe ({'; '.join(diff[:4])}); give "
                          "the same options to continue it, or another folder")


def _short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= 40 else text[:37] + "..."


def write_recipe(folder: Folder, novelty: dict[str, Any], replace_novelty: bool = False
                 ) -> None:
    """Write ``recipe.json`` and ``novelty.json`` (all or none) unless they are there.

    ``replace_novelty`` writes ``novelty.json`` again (a check that ran where an earlier run
    had to skip it).
    """
    files = {}
    if not folder.has(RECIPE):
        files[RECIPE] = json.dumps(folder.values, indent=1, sort_keys=True).encode() + b"\n"
    if replace_novelty or not folder.has(NOVELTY):
        files[NOVELTY] = json.dumps(novelty, indent=1).encode() + b"\n"
    if files:
        folder.write_files(files)


def remove_leftovers(root: Path) -> list[Path]:
    """Remove the temporary files a killed run left in ``root`` and its sub-folders."""
    removed = []
    for folder in (root, *(root / name for name in FOLDERS)):
        if not folder.is_dir():
            continue
        for path in folder.iterdir():
            if _LEFTOVER.match(path.name) and (path.is_file() or path.is_symlink()):
                with contextlib.suppress(OSError):
                    path.unlink()
                    removed.append(path)
    return removed


def discard(folder: Folder) -> None:
    """Close ``folder`` of a run that wrote nothing: its lock file goes, and the folder if new."""
    with contextlib.suppress(OSError):
        (folder.root / LOCK).unlink()
    folder.close()
    if folder.created:
        with contextlib.suppress(OSError):
            folder.root.rmdir()
