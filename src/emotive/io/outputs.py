"""Checks of output names, run by every command before any work is done.

One rule for every command's outputs (``docs/cli.md``):

* a file output is named with a suffix of a format the command writes; any other suffix is
  refused with the formats it does write (the format follows the name, never the reverse);
* a folder output (a report, a web page, a training run) is not named like a file
  (``--out agents.html`` is refused rather than made a folder of that name);
* an output that exists is replaced only with ``--force`` (then all or none, atomically:
  :mod:`emotive.io.atomic`); without it the command stops before any work, naming the file.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from emotive.errors import OutputError
from emotive.io.atomic import check_writable

#: Suffixes of the stick-figure previews.
PREVIEW_SUFFIXES = (".mp4", ".gif")

#: Suffixes of the file formats the toolkit reads or writes, and of the common formats a user
#: may mistake a folder output for: a folder output of one of these names is refused.
FILE_SUFFIXES = frozenset({
    ".bvh", ".glb", ".gltf", ".fbx", ".npz", ".npy", ".csv", ".json", ".md", ".txt", ".toml",
    ".png", ".pdf", ".svg", ".jpg", ".jpeg", ".gif", ".mp4", ".html", ".htm", ".js", ".onnx",
    ".pt", ".pth", ".zip", ".tar", ".gz", ".tgz", ".db", ".sqlite",
})


def existing_output(path: Path, option: str, force: bool) -> None:
    """The one rule for an output that exists already: replaced only with ``--force``.

    Args:
        path: the output file or folder.
        option: the option that named it, for the message (``"--out"``).
        force: the command's ``--force``.

    Raises:
        OutputError: ``path`` exists and ``force`` is off, naming it and the fix.
    """
    if not force and os.path.lexists(path):
        raise OutputError(f"{option} {path} exists already; add --force to replace it, or "
                          "choose another name")


def _nearest_existing(path: Path) -> Path:
    """``path`` itself or its nearest ancestor that exists (a file or a folder)."""
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def missing_folder(path: Path) -> str | None:
    """What is wrong with the folder of the output file ``path``, or ``None`` if it is one.

    E.g. ``"notes.txt is a file, not a folder; put the file in a folder, e.g. walk.bvh"`` for
    ``notes.txt/walk.bvh``, or ``"folder out does not exist; create it first"``.
    """
    path = Path(path)
    if path.parent.is_dir():
        return None
    existing = _nearest_existing(path.parent)
    if existing.exists() and not existing.is_dir():
        return (f"{existing} is a file, not a folder; put the file in a folder, e.g. "
                f"{existing.parent / path.name}")
    return f"folder {path.parent} does not exist; create it first"


def check_output(path: Path, suffixes: tuple[str, ...] | None, option: str,
                 force: bool | None = None) -> None:
    """Fail early on an output of the wrong kind, a folder's name, or an unwritable folder.

    Args:
        path: the output file.
        suffixes: accepted suffixes, lower case with the dot (``(".bvh", ".npz")``); ``None``
            accepts any.
        option: the option that named it, for the message (``"--out"``).
        force: the command's ``--force`` (:func:`existing_output`); ``None`` where the
            command has applied that rule already (a check again just before writing).

    Raises:
        OutputError: naming the option, the file and the fix.
    """
    path = Path(path)
    example = f"{path / 'out'}{suffixes[0] if suffixes else ''}"
    if path.is_dir():
        raise OutputError(f"{option} {path}: that is a folder; name a file in it, e.g. "
                          f"{example}")
    if suffixes is not None and path.suffix.lower() not in suffixes:
        given = f"{path.suffix!r} is not a format it writes" if path.suffix else "no suffix"
        raise OutputError(f"{option} {path}: {given}; use a file ending in "
                          f"{' or '.join(suffixes)}")
    if force is not None:
        existing_output(path, option, force)
    problem = missing_folder(path)
    if problem is not None:
        raise OutputError(f"{option} {path}: {problem}")
    try:
        check_writable(path.parent)
    except OutputError as exc:
        raise OutputError(f"{option} {exc}") from exc.__cause__


def check_distinct(outputs: Sequence[tuple[str, Path | None]]) -> None:
    """Fail when two options of one command name the same file.

    Args:
        outputs: ``(option, path)`` of each output option, ``path`` ``None`` when not given.

    Raises:
        OutputError: naming both options and the fix.
    """
    seen: dict[Path, str] = {}
    for option, path in outputs:
        if path is None:
            continue
        key = Path(os.path.realpath(path))
        if key in seen:
            raise OutputError(f"{option} {path}: the same file as {seen[key]}; give each "
                              "output its own file")
        seen[key] = option


def folder_name(folder: Path, option: str) -> None:
    """Fail on a new folder output named like a file (``--out agents.html``), before any work.

    A name that exists is left to the command's own checks (a file there is "a file, not a
    folder"; a folder of that name is taken as it is).

    Raises:
        OutputError: naming the option, the name and the fix.
    """
    folder = Path(folder)
    if folder.suffix.lower() in FILE_SUFFIXES and not folder.exists():
        raise OutputError(f"{option} {folder}: this command writes a folder, and "
                          f"{folder.suffix!r} names a file; name a folder, e.g. "
                          f"{folder.with_suffix('')}")


def check_output_folder(folder: Path, option: str) -> None:
    """Fail early on an output folder that is a file or that cannot be made or written.

    A missing folder is fine (it is made later) when its nearest existing parent is writable;
    a missing folder named like a file (:func:`folder_name`) is refused.

    Args:
        folder: the output folder.
        option: the option that named it, for the message (``"--out"``).

    Raises:
        OutputError: naming the option, the folder and the fix.
    """
    folder = Path(folder)
    existing = _nearest_existing(folder)
    if not existing.is_dir():
        raise OutputError(f"{option} {folder}: {existing} is a file, not a folder; choose "
                          "another folder name")
    folder_name(folder, option)
    try:
        check_writable(existing)
    except OutputError as exc:
        raise OutputError(f"{option} {exc}") from exc.__cause__
