"""Atomic output files: write to a temporary name in the same folder, then rename into place.

A reader never sees a half-written file, and a failure (an exception, Ctrl-C, a full disk, a
read-only folder) leaves the destination as it was: absent, or the previous complete version,
with no temporary file beside it. Before the rename the temporary file is flushed to the disk
(``fsync``), so that a disk that fills up late (delayed allocation, network file systems) is an
error here and not a truncated file later.

The outputs of one command are all or none (:func:`output_transaction`): inside the
transaction every :func:`atomic_output` leaves its finished temporary file in place, and only
when the command's last output is written are they all renamed into place; a failure before
that, or while renaming, leaves every file that existed before as it was and removes every
temporary file.

Every :class:`OSError` met while writing becomes an :class:`~emotive.errors.OutputError` that
names the file and the fix (:func:`output_error`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from tempfile import mkstemp

from emotive.errors import OutputError

#: errno -> (what is wrong, how to fix it), for the messages of :func:`output_error`.
_REASONS = {
    errno.ENOSPC: ("the disk is full", "free space on it or choose a folder on another disk"),
    errno.EDQUOT: ("the disk quota is used up", "free space or choose another folder"),
    errno.EFBIG: ("the file is larger than the file system or the file-size limit (ulimit -f) "
                  "allows", "raise the limit, choose a folder on another disk or ask for a "
                  "shorter output"),
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


def _flush(tmp: Path, path: Path, mode: int) -> None:
    """Flush ``tmp`` to the disk, check it is a complete regular file, and set its mode."""
    fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OutputError(f"cannot write {path}: its temporary file {tmp} was replaced by "
                              "something that is not a file; write it again")
        os.fsync(fd)
        os.fchmod(fd, mode)
    finally:
        os.close(fd)


def _sync_folder(folder: Path) -> None:
    """Make the renames in ``folder`` durable; the files are complete and in place either way."""
    with contextlib.suppress(OSError):
        dir_fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(dir_fd)
        finally:
            os.close(dir_fd)


def _keep(dest: Path) -> Path | None:
    """A second name beside ``dest`` for the file it holds now, or ``None`` if it holds none.

    A hard link (nothing copied); where the file system has none, a copy.

    Raises:
        OSError: neither could be made.
    """
    if not os.path.lexists(dest):
        return None
    while True:
        keep = dest.with_name(f".{dest.name}.{secrets.token_hex(4)}.old")
        try:
            os.link(dest, keep, follow_symlinks=False)
        except FileExistsError:
            continue
        except OSError:
            # No hard links here (some network and FUSE file systems).
            if os.path.lexists(keep):
                continue
            try:
                shutil.copy2(dest, keep, follow_symlinks=False)
            except BaseException:
                _remove(keep)
                raise
        return keep


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` are names of one file (a link itself, not what it points to)."""
    try:
        sa, sb = os.lstat(a), os.lstat(b)
    except OSError:
        return False
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


class OutputTransaction:
    """The output files of one command, renamed into place together when all are written.

    Made by :func:`output_transaction`; every :func:`atomic_output` inside it hands its
    finished temporary file here instead of renaming it.

    Attributes:
        written: the destinations, in the order they were finished; complete after the commit.
    """

    def __init__(self) -> None:
        self._staged: dict[Path, tuple[Path, Path]] = {}
        self.written: list[Path] = []

    @staticmethod
    def _key(path: Path) -> Path:
        return Path(os.path.realpath(path.parent)) / path.name

    def claim(self, path: Path) -> None:
        """Fail if ``path`` is already an output of this transaction.

        Raises:
            OutputError: naming the file and the fix.
        """
        if self._key(path) in self._staged:
            raise OutputError(f"cannot write {path}: this command names it twice as an output; "
                              "give each output its own file")

    def add(self, path: Path, tmp: Path) -> None:
        """Hold the finished temporary file ``tmp`` of the destination ``path``."""
        self._staged[self._key(path)] = (path, tmp)

    def commit(self) -> list[Path]:
        """Rename every held file into place; on any failure put every old file back.

        Each destination's previous file keeps a second name (:func:`_keep`) until all the
        renames are done, so that a failure in the middle (or Ctrl-C) can restore it.

        Returns:
            The destinations, as given to :meth:`add`.

        Raises:
            OutputError: a file could not be renamed into place (then none is).
        """
        moved: list[tuple[Path, Path | None]] = []
        path = None
        try:
            for path, tmp in self._staged.values():
                moved.append((path, _keep(path)))
                os.replace(tmp, path)
        except BaseException as exc:
            self._restore(moved)
            self.discard()
            if isinstance(exc, OSError):
                raise output_error(path, exc) from exc
            raise
        for _, keep in moved:
            if keep is not None:
                _remove(keep)
        for folder in {path.parent for path, _ in moved}:
            _sync_folder(folder)
        self.written = [path for path, _ in self._staged.values()]
        self._staged.clear()
        return self.written

    @staticmethod
    def _restore(moved: list[tuple[Path, Path | None]]) -> None:
        """Undo the renames of :meth:`commit`: each old file back, each new one removed."""
        for path, keep in reversed(moved):
            with contextlib.suppress(OSError):
                if keep is None:
                    path.unlink(missing_ok=True)
                elif not _same_file(keep, path):
                    os.replace(keep, path)
            if keep is not None:
                _remove(keep)

    def discard(self) -> None:
        """Remove every held temporary file; no destination is touched."""
        for _, tmp in self._staged.values():
            _remove(tmp)
        self._staged.clear()


#: The transaction of the command running in this context, if any.
_CURRENT: ContextVar[OutputTransaction | None] = ContextVar("emotive_output_transaction",
                                                            default=None)


@contextmanager
def output_transaction() -> Iterator[OutputTransaction]:
    """All or none: the files written in the block are renamed into place when it ends well.

    Use as ``with output_transaction(): write_bvh(...); render_preview(...)``. Each writer's
    :func:`atomic_output` writes and flushes its temporary file as usual but leaves it under
    its temporary name; when the block ends without an exception, every file is renamed into
    place (:meth:`OutputTransaction.commit`). An exception in the block, or a failed rename,
    removes every temporary file and leaves every destination as it was before the block.
    Inside the block a destination is not yet in place: read back the temporary file, or read
    after the block. A transaction inside another joins it.

    Yields:
        The transaction; its ``written`` lists the destinations after the block.

    Raises:
        OutputError: the same file was named twice, or a file could not be renamed into place.
    """
    outer = _CURRENT.get()
    if outer is not None:
        yield outer
        return
    transaction = OutputTransaction()
    token = _CURRENT.set(transaction)
    try:
        yield transaction
        transaction.commit()
    except BaseException:
        transaction.discard()
        raise
    finally:
        _CURRENT.reset(token)


@contextmanager
def atomic_output(path: str | os.PathLike, mode: int = 0o644) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success flush it and rename it to ``path``.

    The temporary file exists (empty) when the block starts and keeps ``path``'s suffix, so
    writers that choose a format by suffix work on it. On any exception it is deleted; an
    :class:`OSError` (full disk, read-only folder, ...) becomes an
    :class:`~emotive.errors.OutputError` naming ``path``, other exceptions propagate as they are.
    Inside an :func:`output_transaction` the flushed file is renamed when the transaction ends.

    Args:
        path: the destination; its folder must exist.
        mode: permission bits of the finished file.

    Yields:
        The temporary path to write to.

    Raises:
        OutputError: the file could not be written whole, or the transaction already has it.
    """
    path = Path(path)
    transaction = _CURRENT.get()
    if transaction is not None:
        transaction.claim(path)
    try:
        fd, name = mkstemp(prefix=f".{path.name}.", suffix=f".tmp{path.suffix}", dir=path.parent)
    except OSError as exc:
        raise output_error(path, exc) from exc
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        _flush(tmp, path, mode)
        if transaction is None:
            os.replace(tmp, path)
            _sync_folder(path.parent)
        else:
            transaction.add(path, tmp)
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
