"""Finding, fetching, verifying and unpacking the data sets.

Where data comes from, in order:

1. the user's cache ``$EMOTIVE_HOME`` (default ``~/.cache/emotive``): unpacked data sets live in
   ``datasets/<folder>``, fetched archives in ``archives/`` and preprocessed arrays in
   ``preprocessed/``;
2. a folder of archives shared on this machine, used without a fetch: ``$EMOTIVE_DATA``, then
   ``../shared/data`` seen from the current directory, then ``../shared/data`` seen from the
   repository root of an editable install;
3. ``emotive data fetch NAME [--source PATH_OR_URL]``: a copy from a local file or folder, or a
   resumable HTTP(S) download (``$EMOTIVE_DATA_URL`` is a base URL holding the archives).

Every archive is opened once, checked against the registry's sha256 through that open file and
unpacked from the same file, so the bytes unpacked are the bytes checked; a fetched archive that
fails the check is deleted. Unpacking writes only folders and regular files inside the data
set's folder (see :mod:`emotive.data.archive`) into a temporary folder that is renamed into
place, so a half-unpacked data set is never visible.

Any number of processes may share one cache: unpacking and fetching hold a lock beside their
target (:mod:`emotive.data.lock`), a process that finds the data set complete once it holds the
lock uses that copy, and a finished copy is never replaced except by ``fetch --force``. A full
disk, a read-only cache or an oversized download is a :class:`~emotive.errors.DataError` that
leaves no partial folder or temporary file behind.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import emotive
from emotive.data.archive import CORRUPT_STREAM_ERRORS, check_members, disk_error, unpack
from emotive.data.download import MAX_DOWNLOAD_BYTES, download
from emotive.data.lock import file_lock
from emotive.data.registry import DatasetInfo, get_dataset
from emotive.errors import ChecksumError, DataError

log = logging.getLogger(__name__)

#: File written into an unpacked data set once it is complete.
MARKER = ".emotive-dataset.json"
_CHUNK = 1 << 20

__all__ = [
    "MARKER", "DatasetState", "archive_cache_path", "cache_dir", "dataset_dir", "dataset_state",
    "download", "emotive_home", "extract_archive", "fetch", "fetch_archive",
    "find_shared_archive", "is_cached", "sha256_file", "shared_data_dirs", "verify_archive",
]


def emotive_home() -> Path:
    """The cache root: ``$EMOTIVE_HOME`` or ``~/.cache/emotive``."""
    return Path(os.environ.get("EMOTIVE_HOME") or "~/.cache/emotive").expanduser()


def _repo_root() -> Path | None:
    """The source checkout holding this package, for editable installs (else ``None``)."""
    root = Path(emotive.__file__).resolve().parents[2]
    return root if (root / "pyproject.toml").is_file() else None


def shared_data_dirs() -> list[Path]:
    """Existing folders that may hold the archives, in the order they are searched."""
    candidates: list[Path] = []
    if os.environ.get("EMOTIVE_DATA"):
        candidates.append(Path(os.environ["EMOTIVE_DATA"]).expanduser())
    candidates.append(Path.cwd() / ".." / "shared" / "data")
    root = _repo_root()
    if root is not None:
        candidates.append(root / ".." / "shared" / "data")
    found: list[Path] = []
    for path in candidates:
        path = path.resolve()
        if path.is_dir() and path not in found:
            found.append(path)
    return found


def find_shared_archive(name: str | DatasetInfo) -> Path | None:
    """The first shared archive of a data set (see :func:`shared_data_dirs`), or ``None``."""
    info = get_dataset(name)
    for folder in shared_data_dirs():
        if (folder / info.archive).is_file():
            return folder / info.archive
    return None


def cache_dir(name: str | DatasetInfo) -> Path:
    """Where the data set is (or would be) unpacked: ``$EMOTIVE_HOME/datasets/<folder>``."""
    return emotive_home() / "datasets" / get_dataset(name).folder


def archive_cache_path(name: str | DatasetInfo) -> Path:
    """Where a fetched archive is kept: ``$EMOTIVE_HOME/archives/<archive>``."""
    return emotive_home() / "archives" / get_dataset(name).archive


def is_cached(name: str | DatasetInfo) -> bool:
    """Whether the data set is completely unpacked in the cache from the registry's archive."""
    info = get_dataset(name)
    marker = cache_dir(info) / MARKER
    try:
        return json.loads(marker.read_text()).get("sha256") == info.sha256
    except (OSError, ValueError):
        return False


@dataclass(frozen=True)
class DatasetState:
    """Where a data set can be read from.

    Attributes:
        name: registry name.
        state: ``"cached"`` (unpacked in the cache), ``"shared"`` (an archive in a shared data
            folder, unpacked on first use) or ``"missing"``.
        location: the unpacked folder, the shared archive, or ``None``.
    """

    name: str
    state: str
    location: Path | None


def dataset_state(name: str | DatasetInfo) -> DatasetState:
    """Whether a data set is cached, available in shared data, or missing."""
    info = get_dataset(name)
    if is_cached(info):
        return DatasetState(info.name, "cached", cache_dir(info))
    shared = find_shared_archive(info)
    if shared is not None:
        return DatasetState(info.name, "shared", shared)
    return DatasetState(info.name, "missing", None)


def dataset_dir(name: str | DatasetInfo) -> Path:
    """The unpacked data set folder (holding ``cfg/`` and ``data/*.bvh``).

    On first use the archive is taken from a shared data folder, checked and unpacked into the
    cache; later calls return the cached folder at once. Processes that ask at the same moment
    wait for the first one's copy instead of unpacking their own.

    Args:
        name: registry name, e.g. ``"bandai-namco-1"``.

    Raises:
        DataError: the data set is neither cached nor in a shared data folder; the message says
            to run ``emotive data fetch NAME``; or the cache cannot be written (full disk,
            read-only ``EMOTIVE_HOME``).
        ChecksumError: the shared archive is corrupt (it is left in place).
    """
    info = get_dataset(name)
    if is_cached(info):
        return cache_dir(info)
    shared = find_shared_archive(info)
    if shared is None:
        searched = ", ".join(str(p) for p in shared_data_dirs()) or "none found"
        raise DataError(
            f"data set {info.name!r} is not in the cache ({cache_dir(info)}) and no shared "
            f"folder holds {info.archive} (searched: {searched}); run `emotive data fetch "
            f"{info.name}`, or set EMOTIVE_DATA to a folder holding {info.archive}"
        )
    return extract_archive(info, shared)


def _hash_open(fh: BinaryIO) -> str:
    """Hex sha256 of an open binary file from its start; leaves it at its start again."""
    digest = hashlib.sha256()
    fh.seek(0)
    while block := fh.read(_CHUNK):
        digest.update(block)
    fh.seek(0)
    return digest.hexdigest()


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file."""
    with open(path, "rb") as fh:
        return _hash_open(fh)


def _checksum_error(info: DatasetInfo, actual: str, source: str, removed: bool) -> ChecksumError:
    note = "; the corrupt copy was removed" if removed else ""
    return ChecksumError(
        f"archive {source} has sha256 {actual} but {info.name} needs {info.sha256}: the file "
        f"is corrupt or not {info.archive}{note}; fetch it again with "
        f"`emotive data fetch {info.name} --source PATH_OR_URL`"
    )


def _open_archive(path: Path) -> BinaryIO:
    """Open an archive for reading; a missing or unreadable file is a :class:`DataError`."""
    try:
        return open(path, "rb")
    except OSError as exc:
        raise DataError(
            f"cannot read archive {path} ({exc.strerror or exc}); fetch it again"
        ) from None


def _check_open(
    info: DatasetInfo, fh: BinaryIO, path: Path, *, remove: bool, source: str | None
) -> None:
    """Check the sha256 of an open archive; see :func:`verify_archive`."""
    try:
        actual = _hash_open(fh)
    except OSError as exc:
        raise DataError(f"cannot read archive {path} ({exc}); fetch it again") from None
    if actual != info.sha256:
        if remove:
            Path(path).unlink(missing_ok=True)
        raise _checksum_error(info, actual, source or str(path), remove)


def verify_archive(
    name: str | DatasetInfo, path: Path, *, remove: bool = True, source: str | None = None
) -> None:
    """Check an archive's sha256 against the registry.

    Args:
        name: registry name or entry.
        path: the archive.
        remove: delete the file when it fails the check (never do this to a user's own file).
        source: where the file came from, named in the error.

    Raises:
        ChecksumError: the sha256 differs.
        DataError: the file cannot be read.
    """
    info = get_dataset(name)
    with _open_archive(path) as fh:
        _check_open(info, fh, path, remove=remove, source=source)


def extract_archive(
    name: str | DatasetInfo,
    archive: Path,
    *,
    remove: bool = False,
    source: str | None = None,
    force: bool = False,
) -> Path:
    """Check and unpack an archive into the cache and return the data set folder.

    The archive is opened once: its sha256 is computed from the open file and the same file is
    unpacked, so a file swapped on disk in between cannot slip through. Only folders and regular
    files inside the data set's folder are written (see :func:`emotive.data.archive.unpack`),
    into a temporary folder renamed into place when complete. The whole step holds the data
    set's lock; a process that finds the data set complete once it holds the lock returns it.

    Args:
        name: registry name or entry.
        archive: the archive file.
        remove: delete the archive when it fails the check (only for the cache's own copy).
        source: where the archive came from, named in errors.
        force: unpack again even when the data set is complete in the cache.

    Returns:
        ``$EMOTIVE_HOME/datasets/<folder>``.

    Raises:
        ChecksumError: the archive's sha256 differs from the registry's.
        DataError: the archive cannot be read, is not a tar file or holds links, devices or
            members outside the data set's folder; or the cache cannot be written (full disk,
            read-only). Nothing is left behind.
    """
    info = get_dataset(name)
    root = emotive_home() / "datasets"
    target = root / info.folder
    doing = f"unpacking {info.name}"
    try:
        root.mkdir(parents=True, exist_ok=True)
        with file_lock(root / f".{info.folder}.lock", what=doing):
            if is_cached(info) and not force:
                return target
            with _open_archive(archive) as fh:
                _check_open(info, fh, archive, remove=remove, source=source)
                log.info("unpacking %s from %s", info.name, source or archive)
                _unpack_into(info, fh, source or str(archive), root)
    except OSError as exc:
        raise disk_error(exc, root, doing) from None
    return target


def _unpack_into(info: DatasetInfo, fh: BinaryIO, label: str, root: Path) -> None:
    """Unpack the checked open archive ``fh`` to ``root/<folder>``; the caller holds the lock."""
    target = root / info.folder
    tmp = Path(tempfile.mkdtemp(prefix=f".{info.folder}.", dir=root))
    try:
        try:
            with tarfile.open(fileobj=fh, mode="r:*") as tar:
                members = tar.getmembers()
                fix = f"it is not the {info.name} archive; fetch it again"
                check_members(members, info.folder, label, fix)
                unpack(tar, members, tmp)
        except CORRUPT_STREAM_ERRORS as exc:
            raise DataError(f"cannot unpack {label} ({exc}); fetch the archive again") from None
        unpacked = tmp / info.folder
        if not (unpacked / "data").is_dir():
            raise DataError(f"archive {label} has no {info.folder}/data folder; fetch it again")
        (unpacked / MARKER).write_text(
            json.dumps({"name": info.name, "archive": info.archive, "sha256": info.sha256})
        )
        if os.path.lexists(target):
            # Under the lock, an existing folder is no complete copy of this archive (or the
            # user asked for --force): nobody else is using it as one.
            os.rename(target, tmp / ".replaced")
        os.rename(unpacked, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _is_url(source: str) -> bool:
    return source.startswith(("http://", "https://"))


def _default_source(info: DatasetInfo) -> str | Path:
    """A shared data folder's archive, else ``$EMOTIVE_DATA_URL/<archive>``."""
    shared = find_shared_archive(info)
    base = os.environ.get("EMOTIVE_DATA_URL")
    if shared is not None:
        return shared
    if base:
        return f"{base.rstrip('/')}/{info.archive}"
    raise DataError(
        f"no source for {info.name}: the upstream repository {info.upstream} does not host "
        f"{info.archive}; pass --source with a URL, the archive file or the folder holding it, "
        f"or set EMOTIVE_DATA (a folder of archives) or EMOTIVE_DATA_URL"
    )


def _local_source(info: DatasetInfo, text: str) -> Path:
    """The archive file named by a local ``--source`` (the file or its folder)."""
    path = Path(text).expanduser()
    if path.is_dir():
        path = path / info.archive
    if not path.is_file():
        raise DataError(f"{path} does not exist: pass the {info.archive} file or its folder")
    return path


class _HashingReader:
    """A binary file whose reads also update a sha256."""

    def __init__(self, fh: BinaryIO) -> None:
        self.fh = fh
        self.digest = hashlib.sha256()

    def read(self, size: int = -1) -> bytes:
        block = self.fh.read(size)
        self.digest.update(block)
        return block


def _copy_checked(info: DatasetInfo, path: Path, dest: Path) -> None:
    """Copy a local archive to ``dest``, hashing the bytes as they are written.

    The copy goes to a temporary file beside ``dest``, renamed into place once its sha256 is
    right and deleted on any failure; an :class:`OSError` propagates for the caller to name the
    cache folder.
    """
    with _open_archive(path) as src:
        size = os.fstat(src.fileno()).st_size
        if size > MAX_DOWNLOAD_BYTES:
            raise DataError(
                f"{path} is {size} bytes, over the limit of {MAX_DOWNLOAD_BYTES} bytes for a "
                f"data set archive: it is not {info.archive}; pass the right file"
            )
        reader = _HashingReader(src)
        fd, name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent)
        try:
            with open(fd, "wb") as out:
                shutil.copyfileobj(reader, out, _CHUNK)
            actual = reader.digest.hexdigest()
            if actual != info.sha256:
                raise _checksum_error(info, actual, str(path), removed=True)
            os.replace(name, dest)
        except BaseException:
            Path(name).unlink(missing_ok=True)
            raise


def fetch_archive(
    name: str | DatasetInfo, source: str | os.PathLike | None = None, *, progress: bool = False
) -> Path:
    """Put a checked copy of a data set's archive into ``$EMOTIVE_HOME/archives``.

    Args:
        name: registry name.
        source: an ``http(s)://`` URL of the archive, a local archive file, or a folder holding
            it. ``None`` takes a shared data folder, else ``$EMOTIVE_DATA_URL/<archive>``.
        progress: show a progress bar while downloading.

    Returns:
        The archive in the cache.

    Raises:
        DataError: the source does not exist or is too large, the download fails or is
            interrupted (run again to resume), no source is known, or the cache cannot be
            written (full disk, read-only; no partial file is left).
        ChecksumError: the copy is corrupt; it is removed.
    """
    info = get_dataset(name)
    dest = archive_cache_path(info)
    text = str(_default_source(info) if source is None else source)
    local = None if _is_url(text) else _local_source(info, text)
    doing = f"fetching {info.name}"
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        with file_lock(dest.parent / f".{info.archive}.lock", what=doing):
            if local is not None:
                _copy_checked(info, local, dest)
            else:
                download(text, dest, progress=progress)
                verify_archive(info, dest, source=text)
    except OSError as exc:
        raise disk_error(exc, dest.parent, doing) from None
    return dest


def fetch(
    name: str | DatasetInfo,
    source: str | os.PathLike | None = None,
    *,
    force: bool = False,
    progress: bool = False,
) -> Path:
    """Fetch, check and unpack a data set into the cache; return its folder.

    Args:
        name: registry name.
        source: URL, archive file or folder (see :func:`fetch_archive`); ``None`` for the
            default sources.
        force: fetch and unpack again even when the data set is cached.
        progress: show a progress bar while downloading.

    Raises:
        DataError: see :func:`fetch_archive` and :func:`extract_archive`.
        ChecksumError: the archive is corrupt; it is removed.
    """
    info = get_dataset(name)
    if is_cached(info) and not force:
        return cache_dir(info)
    archive = archive_cache_path(info)
    if force or source is not None or not archive.is_file():
        archive = fetch_archive(info, source, progress=progress)
        return extract_archive(info, archive, remove=True, force=force)
    try:
        return extract_archive(info, archive, remove=True)
    except ChecksumError:
        log.warning("removed corrupt %s; fetching it again", archive)
    archive = fetch_archive(info, None, progress=progress)
    return extract_archive(info, archive, remove=True)
