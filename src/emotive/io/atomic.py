"""Atomic output files: write to a temporary name in the same folder, then rename into place.

A reader never sees a half-written file, and a failure (an exception, Ctrl-C) leaves the
destination as it was: absent, or the previous complete version.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_output(path: str | os.PathLike, mode: int = 0o644) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success rename it to ``path``.

    The temporary file exists (empty) when the block starts and keeps ``path``'s suffix, so
    writers that choose a format by suffix work on it. On any exception it is deleted and the
    exception propagates.

    Args:
        path: the destination; its folder must exist.
        mode: permission bits of the finished file.

    Yields:
        The temporary path to write to.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}",
                               dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
