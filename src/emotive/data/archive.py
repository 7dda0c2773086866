"""Unpacking a data set archive safely, and turning file-system failures into typed errors.

The data sets hold only folders and regular files, so :func:`check_members` refuses every other
kind of member (symbolic and hard links, devices, FIFOs) and every name that is absolute, holds
``..`` or lies outside the data set's folder, all before anything is written. :func:`unpack`
then writes the members itself, never following a link, instead of trusting
:meth:`tarfile.TarFile.extractall` (whose ``data`` filter lets a chain of links inside the tree
write outside it on Pythons without the 2025 :mod:`tarfile` fixes). It hashes every file's
bytes as it writes them, for the data set's manifest (:mod:`emotive.data.manifest`).
:func:`scan` reads an archive once from start to end, with the same checks, to hash every file
and write only some (a repair), decompressing the archive a single time; it checks each member
as it meets it, so what it writes stays in a temporary folder until the whole archive passed.
"""

from __future__ import annotations

import errno
import gzip
import hashlib
import lzma
import os
import shutil
import tarfile
import zlib
from collections.abc import Container
from pathlib import Path
from typing import BinaryIO

from emotive.errors import DataError

#: The most bytes the members of one archive may declare in all (the real data sets unpack to
#: well under 1 GiB); a larger archive is refused before anything is written.
MAX_UNPACKED_BYTES = 16 << 30
#: Errors of a damaged compressed stream (``gzip.BadGzipFile`` is an ``OSError``).
CORRUPT_STREAM_ERRORS = (tarfile.TarError, EOFError, zlib.error, lzma.LZMAError, gzip.BadGzipFile)
_CHUNK = 1 << 20
_KINDS = {
    tarfile.SYMTYPE: "a symbolic link", tarfile.LNKTYPE: "a hard link",
    tarfile.CHRTYPE: "a character device", tarfile.BLKTYPE: "a block device",
    tarfile.FIFOTYPE: "a FIFO",
}
_NO_SPACE = (errno.ENOSPC, errno.EDQUOT)
#: Errors of a folder that may not be written.
READ_ONLY_ERRNOS = (errno.EROFS, errno.EACCES, errno.EPERM)


def disk_error(exc: OSError, folder: Path, doing: str) -> DataError:
    """The typed error for a file-system failure while writing into ``folder``.

    Args:
        exc: the failure.
        folder: the cache folder being written.
        doing: what was being done, e.g. ``"unpacking bandai-namco-1"``.

    Returns:
        A :class:`DataError` that names the folder and the fix: free space, a writable
        ``EMOTIVE_HOME``, or (otherwise) running again.
    """
    reason = exc.strerror or str(exc)
    if exc.errno in _NO_SPACE:
        return DataError(
            f"no space left on the disk holding {folder} while {doing} ({reason}); free some "
            f"space, or set EMOTIVE_HOME to a folder on a larger disk, and run the command again"
        )
    if isinstance(exc, PermissionError) or exc.errno in READ_ONLY_ERRNOS:
        return DataError(
            f"cannot write to {folder} while {doing} ({reason}): the cache is read-only; set "
            f"EMOTIVE_HOME to a writable folder, or make {folder} writable"
        )
    return DataError(f"cannot write to {folder} while {doing} ({exc}); run the command again")


def _member_problem(member: tarfile.TarInfo, folder: str) -> str | None:
    """Why ``member`` may not be unpacked into ``folder``, or ``None`` when it may."""
    if not (member.isreg() or member.isdir()):
        kind = _KINDS.get(member.type, f"a member of tar type {member.type!r}")
        return f"is {kind}; the data sets hold only folders and regular files"
    parts = member.name.rstrip("/").split("/")
    if member.name.startswith("/") or any(p in ("", ".", "..") for p in parts):
        return "is an absolute path or holds '.', '..' or an empty part"
    if parts[0] != folder:
        return f"lies outside {folder}/"
    return None


def check_members(members: list[tarfile.TarInfo], folder: str, archive: str, fix: str) -> None:
    """Refuse an archive with any member :func:`unpack` must not write.

    Args:
        members: every member of the archive.
        folder: the one top-level folder every member must lie in.
        archive: the archive, named in the error.
        fix: what the user should do, appended to the error.

    Raises:
        DataError: a member is a link, device or FIFO, has an unsafe name or lies outside
            ``folder``, or the members declare more than :data:`MAX_UNPACKED_BYTES`; the
            message names the first such member.
    """
    for member in members:
        problem = _member_problem(member, folder)
        if problem is not None:
            raise DataError(f"archive {archive} member {member.name!r} {problem}; {fix}")
    total = sum(m.size for m in members if m.isreg())
    if total > MAX_UNPACKED_BYTES:
        raise DataError(
            f"archive {archive} would unpack to {total} bytes, over the limit of "
            f"{MAX_UNPACKED_BYTES}; {fix}"
        )


class HashingReader:
    """A binary file whose reads also update a sha256 (:attr:`digest`).

    Args:
        fh: the file to read.
    """

    def __init__(self, fh: BinaryIO) -> None:
        self.fh = fh
        self.digest = hashlib.sha256()

    def read(self, size: int = -1) -> bytes:
        """Read up to ``size`` bytes (all when negative) and hash them."""
        block = self.fh.read(size)
        self.digest.update(block)
        return block


def unpack(
    tar: tarfile.TarFile, members: list[tarfile.TarInfo], dest: Path
) -> dict[str, str]:
    """Write checked members (see :func:`check_members`) into the empty folder ``dest``.

    Folders get mode ``0o755`` and files ``0o644`` whatever the archive says; a file is opened
    with ``O_NOFOLLOW`` and every parent folder is checked to resolve inside ``dest``.

    Args:
        tar: the open archive.
        members: its checked members.
        dest: an empty folder owned by this process.

    Returns:
        The hex sha256 of the bytes written for each regular member, by member name.

    Raises:
        DataError: a member would land outside ``dest`` (cannot happen after the check).
        OSError: a write fails (full disk, read-only folder): the caller reports it.
    """
    root = os.path.realpath(dest)
    hashes = {}
    for member in members:
        try:
            digest = _unpack_one(tar, member, dest, root)
        except (FileExistsError, NotADirectoryError, IsADirectoryError):
            raise DataError(
                f"archive member {member.name!r} clashes with another member of the same path: "
                f"it is not a data set archive; fetch it again"
            ) from None
        if digest is not None:
            hashes[member.name] = digest
    return hashes


def scan(
    fh: BinaryIO, folder: str, archive: str, fix: str, *,
    dest: Path | None = None, wanted: Container[str] = (),
) -> tuple[list[tarfile.TarInfo], dict[str, str]]:
    """Read an archive once, start to end: check, hash and (some) write every member.

    Every member is checked as :func:`check_members` does, every regular member hashed, and
    the regular members named in ``wanted`` written below ``dest`` as :func:`unpack` writes
    them. A member refused after others were written leaves those in ``dest``, which the
    caller then discards.

    Args:
        fh: the open archive at its start (any compression :mod:`tarfile` reads).
        folder: the one top-level folder every member must lie in.
        archive: the archive, named in errors.
        fix: what the user should do, appended to errors.
        dest: an empty folder owned by this process; ``None`` writes nothing.
        wanted: member names of the files to write.

    Returns:
        Every member, and the hex sha256 of each regular member's bytes by member name.

    Raises:
        DataError: as :func:`check_members`.
        tarfile.TarError, EOFError, zlib.error, ...: the stream is damaged
            (:data:`CORRUPT_STREAM_ERRORS`).
        OSError: a write fails.
    """
    members, hashes = [], {}
    root = os.path.realpath(dest) if dest is not None else ""
    with tarfile.open(fileobj=fh, mode="r|*") as tar:
        for member in tar:
            problem = _member_problem(member, folder)
            if problem is not None:
                raise DataError(f"archive {archive} member {member.name!r} {problem}; {fix}")
            members.append(member)
            if not member.isreg():
                continue
            if dest is not None and member.name in wanted:
                hashes[member.name] = _unpack_one(tar, member, dest, root)
            else:
                reader = HashingReader(_member_data(tar, member))
                with reader.fh:
                    while reader.read(_CHUNK):
                        pass
                hashes[member.name] = reader.digest.hexdigest()
    check_members(members, folder, archive, fix)
    return members, hashes


def _member_data(tar: tarfile.TarFile, member: tarfile.TarInfo) -> BinaryIO:
    source = tar.extractfile(member)
    if source is None:
        raise DataError(f"archive member {member.name!r} has no data")
    return source


def _unpack_one(
    tar: tarfile.TarFile, member: tarfile.TarInfo, dest: Path, root: str
) -> str | None:
    """Write one checked member into ``dest`` (whose real path is ``root``).

    Returns:
        The hex sha256 of a file's bytes, ``None`` for a folder.
    """
    path = dest.joinpath(*member.name.rstrip("/").split("/"))
    folder = path if member.isdir() else path.parent
    folder.mkdir(mode=0o755, parents=True, exist_ok=True)
    if os.path.commonpath([root, os.path.realpath(folder)]) != root:
        raise DataError(f"archive member {member.name!r} would be written outside {dest}")
    if member.isdir():
        return None
    reader = HashingReader(_member_data(tar, member))
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | os.O_CLOEXEC
    with reader.fh, open(os.open(path, flags, 0o644), "wb") as out:
        shutil.copyfileobj(reader, out, _CHUNK)
    return reader.digest.hexdigest()
