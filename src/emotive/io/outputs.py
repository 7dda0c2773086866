"""Checks of output file names, run by every command before any work is done."""

from __future__ import annotations

from pathlib import Path

from emotive.errors import OutputError

#: Suffixes of the stick-figure previews.
PREVIEW_SUFFIXES = (".mp4", ".gif")


def check_output(path: Path, suffixes: tuple[str, ...], option: str) -> None:
    """Fail early on an output of the wrong kind or in a missing folder.

    Args:
        path: the output file.
        suffixes: accepted suffixes, lower case with the dot (``(".bvh", ".npz")``).
        option: the option that named it, for the message (``"--out"``).

    Raises:
        OutputError: naming the option, the file and the fix.
    """
    if path.suffix.lower() not in suffixes:
        raise OutputError(f"{option} {path}: use a file ending in {' or '.join(suffixes)}")
    if not path.parent.is_dir():
        raise OutputError(f"{option} {path}: folder {path.parent} does not exist; create it first")
