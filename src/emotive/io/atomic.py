"""Atomic output files: write to a temporary name in the same folder, then rename into place.

A reader never sees a half-written file, and a failure (an exception, Ctrl-C, a full disk, a
read-only folder) leaves the destination as it was: absent, or the previous complete version,
with no temporary file beside it. Before the rename the temporary file is flushed to the disk
(``fsync``), so that a disk that fills up late (delayed allocation, network file systems) is an
error here and not a truncated file later.

Every :class:`OSError` met while writing becomes an :class:`~emotive.errors.OutputError` that
names the file and the fix (:func:`output_error`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from tempfile import mkstemp

from emotive.errors import OutputError

#: errno -> (what is wrong, how to fix it), for the messages of :func:`output_error`.
_REASONS = {
    errno.ENOSPC: ("the disk is full", "free space on it or choose a folder on another disk"),
    errno.EDQUOT: ("the disk quota is used up", "free space or choose another folder"),
    errno.EFBIG: ("the file is larger than the file system or a limit allows",
                  "choose a folder on another disk or ask for a shorter output"),
    errno.EROFS: ("the folder is on a read-only file system", "choose another folder"),
    errno.EACCES: ("permission denied", "choose a folder you may write to"),
    errno.EPERM: ("the folder or file may not be changed (permissions or immutable)",
                  "choose another folder"),
    errno.EISDIR: ("a folder has that name", "name a file, not a folder"),
    errno.ENOENT: ("its folder does not exist (any more)", "create the folder first"),
    errno.ENOTDIR: ("a part of the path is a file, not a folder", "fix the path"),
    errno.ENAMETOOLONG: ("the name is too long", "choose a shorter name"),
    errno.EIO: ("the disk reported an input/output error", "check the disk or choose another"),
}


def output_error(path: str | os.PathLike, exc: OSError) -> OutputError:
    """The :class:`OutputError` for an :class:`OSError` met while writing ``path``.

    E.g. ``cannot write out.bvh: the disk is full (No space left on device); free space on it
    or choose a folder on another disk``.

    Args:
        path: the file (or folder) being written.
        exc: the error.
    """
    problem, fix = _REASONS.get(exc.errno, ("the system refused", "check the folder or choose "
                                            "another"))
    path = Path(path)
    if exc.errno == errno.ENOENT and (path.is_dir() or path.parent.is_dir()):
        # /proc and /sys answer "no such file" to a new file in a folder that exists.
        problem, fix = ("the folder takes no new files (a virtual file system such as /proc)",
                        "choose a folder on a disk")
    detail = exc.strerror or str(exc) or type(exc).__name__
    return OutputError(f"cannot write {path}: {problem} ({detail}); {fix}")


def check_writable(folder: str | os.PathLike) -> None:
    """Fail unless a file can be created in ``folder`` (tried, as ``root`` ignores modes).

    Args:
        folder: an existing folder.

    Raises:
        OutputError: naming the folder and the fix.
    """
    folder = Path(folder)
    try:
        fd, probe = mkstemp(prefix=".emotive-probe.", dir=folder)
    except OSError as exc:
        raise output_error(folder, exc) from exc
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)


def _finish(tmp: Path, path: Path, mode: int) -> None:
    """Flush ``tmp`` to the disk, check it is a complete regular file, and rename it."""
    fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OutputError(f"cannot write {path}: its temporary file {tmp} was replaced by "
                              "something that is not a file; write it again")
        os.fsync(fd)
        os.fchmod(fd, mode)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    # Durability of the rename itself; the file is complete and in place either way.
    with contextlib.suppress(OSError):
        dir_fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


@contextmanager
def atomic_output(path: str | os.PathLike, mode: int = 0o644) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success flush it and rename it to ``path``.

    The temporary file exists (empty) when the block starts and keeps ``path``'s suffix, so
    writers that choose a format by suffix work on it. On any exception it is deleted; an
    :class:`OSError` (full disk, read-only folder, ...) becomes an
    :class:`~emotive.errors.OutputError` naming ``path``, other exceptions propagate as they are.

    Args:
        path: the destination; its folder must exist.
        mode: permission bits of the finished file.

    Yields:
        The temporary path to write to.

    Raises:
        OutputError: the file could not be written whole.
    """
    path = Path(path)
    try:
        fd, name = mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    except OSError as exc:
        raise output_error(path, exc) from exc
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        _finish(tmp, path, mode)
    except OSError as exc:
        _remove(tmp)
        raise output_error(path, exc) from exc
    except BaseException:
        _remove(tmp)
        raise


def _remove(tmp: Path) -> None:
    """Delete ``tmp`` if it is there; a folder that refuses even that cannot be helped."""
    with contextlib.suppress(OSError):
        tmp.unlink(missing_ok=True)
