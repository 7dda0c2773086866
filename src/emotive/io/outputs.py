"""Checks of output file names, run by every command before any work is done."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from emotive.errors import OutputError
from emotive.io.atomic import check_writable

#: Suffixes of the stick-figure previews.
PREVIEW_SUFFIXES = (".mp4", ".gif")


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


def check_output(path: Path, suffixes: tuple[str, ...] | None, option: str) -> None:
    """Fail early on an output of the wrong kind, a folder's name, or an unwritable folder.

    Args:
        path: the output file.
        suffixes: accepted suffixes, lower case with the dot (``(".bvh", ".npz")``); ``None``
            accepts any.
        option: the option that named it, for the message (``"--out"``).

    Raises:
        OutputError: naming the option, the file and the fix.
    """
    path = Path(path)
    example = f"{path / 'out'}{suffixes[0] if suffixes else ''}"
    if path.is_dir():
        raise OutputError(f"{option} {path}: that is a folder; name a file in it, e.g. "
                          f"{example}")
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise OutputError(f"{option} {path}: use a file ending in {' or '.join(suffixes)}")
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


def check_output_folder(folder: Path, option: str) -> None:
    """Fail early on an output folder that is a file or that cannot be made or written.

    A missing folder is fine (it is made later) when its nearest existing parent is writable.

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
    try:
        check_writable(existing)
    except OutputError as exc:
        raise OutputError(f"{option} {exc}") from exc.__cause__
