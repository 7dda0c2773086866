"""Checks of output file names, run by every command before any work is done."""

from __future__ import annotations

from pathlib import Path

from emotive.errors import OutputError
from emotive.io.atomic import check_writable

#: Suffixes of the stick-figure previews.
PREVIEW_SUFFIXES = (".mp4", ".gif")


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
    if not path.parent.is_dir():
        raise OutputError(f"{option} {path}: folder {path.parent} does not exist; create it first")
    try:
        check_writable(path.parent)
    except OutputError as exc:
        raise OutputError(f"{option} {exc}") from exc.__cause__


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
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise OutputError(f"{option} {folder}: {existing} is a file, not a folder; choose "
                          "another folder name")
    try:
        check_writable(existing)
    except OutputError as exc:
        raise OutputError(f"{option} {exc}") from exc.__cause__
