"""An exclusive lock between processes that share one cache folder.

The lock is :func:`fcntl.flock` on a file beside what it guards. The kernel drops it when its
holder exits, however that happens, so a crashed process never leaves the cache locked. The
holder deletes the lock file before it lets go; a waiter that then wins a lock on the deleted
file sees that the path no longer names it and locks the new file instead, so at most one
process at a time holds the lock of a path.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from emotive.errors import DataError

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows: os.rename already refuses to replace
    fcntl = None  # type: ignore[assignment]

log = logging.getLogger(__name__)

#: How long a process waits for another one to finish with the cache before giving up.
LOCK_TIMEOUT_S = 3600.0
_POLL_S = 0.05


def _try_lock(path: Path) -> int | None:
    """Lock ``path`` without waiting; return the open descriptor, or ``None`` when it is held."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    except BaseException:
        os.close(fd)
        raise
    try:
        current = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        current = None
    mine = os.fstat(fd)
    if current is None or (current.st_dev, current.st_ino) != (mine.st_dev, mine.st_ino):
        # The previous holder deleted this file as it let go: lock the path's new file.
        os.close(fd)
        return None
    return fd


@contextmanager
def file_lock(
    path: str | os.PathLike, *, what: str, timeout_s: float | None = None
) -> Iterator[None]:
    """Hold an exclusive lock on ``path`` (created if absent, deleted on release).

    Args:
        path: the lock file; its folder must exist.
        what: what the lock guards, named in the log and in the timeout error.
        timeout_s: give up after this many seconds; default :data:`LOCK_TIMEOUT_S`.

    Yields:
        Nothing; the lock is held inside the block.

    Raises:
        DataError: another process held the lock for longer than ``timeout_s``.
        OSError: the lock file cannot be created (the caller names the folder in its error).
    """
    if fcntl is None:  # pragma: no cover
        yield
        return
    path = Path(path)
    limit = LOCK_TIMEOUT_S if timeout_s is None else timeout_s
    deadline = time.monotonic() + limit
    waited = False
    while (fd := _try_lock(path)) is None:
        if not waited:
            log.info("waiting for another process %s (lock %s)", what, path)
            waited = True
        if time.monotonic() > deadline:
            raise DataError(
                f"another process has been {what} for over {limit:.0f} s (lock {path}); wait "
                f"for it to finish, or stop it and run the command again"
            )
        time.sleep(_POLL_S)
    try:
        yield
    finally:
        try:
            path.unlink(missing_ok=True)
        finally:
            os.close(fd)


@contextmanager
def try_file_lock(path: str | os.PathLike) -> Iterator[bool]:
    """Hold the lock on ``path`` (see :func:`file_lock`) if nobody holds it now; never wait.

    Args:
        path: the lock file; its folder must exist.

    Yields:
        Whether the lock is held inside the block.

    Raises:
        OSError: the lock file cannot be created (a read-only cache).
    """
    if fcntl is None:  # pragma: no cover
        yield False
        return
    path = Path(path)
    fd = _try_lock(path)
    if fd is None:
        yield False
        return
    try:
        yield True
    finally:
        try:
            path.unlink(missing_ok=True)
        finally:
            os.close(fd)
