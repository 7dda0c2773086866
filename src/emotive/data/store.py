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
place, so a half-unpacked data set is never visible. Beside the folder goes its manifest, each
file's size and sha256 as the archive holds it (:mod:`emotive.data.manifest`): :func:`verify`
compares the folder with it, and :func:`repair` (what :func:`fetch` does to a cached data set)
unpacks again only the damaged and missing files and removes the extra ones.

Any number of processes may share one cache: unpacking and fetching hold a lock beside their
target (:mod:`emotive.data.lock`), a process that finds the data set complete once it holds the
lock uses that copy, and a finished copy is never replaced except by ``fetch --force``. A full
disk, a read-only cache or an oversized download is a :class:`~emotive.errors.DataError` that
leaves no partial folder or temporary file behind. A process killed outright (``kill -9``, a
power cut) cannot clean up: the temporary folders and files it leaves, which only a holder of
the lock writes, are removed by the next process that holds the lock (:func:`leftovers`).
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import re
import shutil
import stat
import tarfile
import tempfile
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import emotive
from emotive.data.archive import (
    CORRUPT_STREAM_ERRORS,
    READ_ONLY_ERRNOS,
    HashingReader,
    check_members,
    disk_error,
    scan,
    unpack,
)
from emotive.data.download import MAX_DOWNLOAD_BYTES, download
from emotive.data.lock import file_lock, try_file_lock
from emotive.data.manifest import (
    SUFFIX,
    Manifest,
    Problem,
    check_folder,
    manifest_path,
    read_manifest,
    write_manifest,
)
from emotive.data.registry import DatasetInfo, get_dataset
from emotive.errors import ChecksumError, DataError

log = logging.getLogger(__name__)

#: File written into an unpacked data set once it is complete.
MARKER = ".emotive-dataset.json"
_CHUNK = 1 << 20

_RANDOM = "[a-z0-9_]{8}"  # the random part of a tempfile.mkdtemp / mkstemp name

__all__ = [
    "MARKER", "DatasetState", "Verification", "archive_cache_path", "cache_dir", "dataset_dir",
    "dataset_state", "download", "emotive_home", "extract_archive", "fetch", "fetch_archive",
    "find_shared_archive", "is_cached", "leftovers", "repair", "sha256_file",
    "shared_data_dirs", "verify", "verify_archive",
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
        _remove_leftovers_if_free(info)
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
        with file_lock(_lock_path(info), what=doing):
            _remove_leftovers(info)
            if is_cached(info) and not force:
                return target
            with _open_archive(archive) as fh:
                _check_open(info, fh, archive, remove=remove, source=source)
                log.info("unpacking %s from %s", info.name, source or archive)
                _unpack_into(info, fh, source or str(archive), root)
    except OSError as exc:
        raise disk_error(exc, root, doing) from None
    return target


def _lock_path(info: DatasetInfo) -> Path:
    """The lock guarding a data set's folder, its manifest and their temporary files."""
    return emotive_home() / "datasets" / f".{info.folder}.lock"


def leftovers(name: str | DatasetInfo) -> list[Path]:
    """What a killed process left of its work on a data set in the cache.

    These are the temporary folders of an unpack or a repair (``.<folder>.XXXXXXXX``, each up
    to the size of the data set) and the temporary files of a manifest
    (``.<folder>.manifest.json.XXXXXXXX.tmp.json``) and of an archive copy
    (``archives/.<archive>.XXXXXXXX.tmp``). Only a holder of the data set's (or the archive's)
    lock writes them, so while this process holds that lock every one of them is a leftover.
    A download's ``<archive>.part`` is no leftover: the next fetch resumes from it.

    Args:
        name: registry name or entry.

    Returns:
        The leftover paths, sorted (none when the cache folders do not exist).
    """
    info = get_dataset(name)
    folder, archive = re.escape(info.folder), re.escape(info.archive)
    patterns = (
        (emotive_home() / "datasets",
         re.compile(rf"\.{folder}\.{_RANDOM}|\.{folder}{re.escape(SUFFIX)}\.{_RANDOM}\.tmp\.json")),
        (emotive_home() / "archives", re.compile(rf"\.{archive}\.{_RANDOM}\.tmp")),
    )
    found = []
    for root, pattern in patterns:
        try:
            names = os.listdir(root)
        except OSError:
            continue
        found += [root / n for n in names if pattern.fullmatch(n)]
    return sorted(found)


def _remove(path: Path) -> None:
    """Delete a file, link or folder tree (a link is removed, never followed)."""
    if stat.S_ISDIR(os.lstat(path).st_mode):
        shutil.rmtree(path)
    else:
        path.unlink()


def _remove_leftovers(info: DatasetInfo) -> None:
    """Delete :func:`leftovers`; the caller holds the data set's lock.

    The archive's temporary copies are deleted only when the archive's lock is free at once
    (a copy in progress holds it); the next run gets them otherwise.
    """
    found = leftovers(info)
    archives = [p for p in found if p.parent.name == "archives"]
    for path in (p for p in found if p not in archives):
        log.info("removing %s, left by a process that was stopped", path)
        _remove(path)
    if archives:
        with try_file_lock(_archive_lock_path(info)) as held:
            for path in archives if held else ():
                log.info("removing %s, left by a process that was stopped", path)
                path.unlink(missing_ok=True)


def _remove_leftovers_if_free(info: DatasetInfo) -> None:
    """Delete :func:`leftovers` when there are any and nobody holds the data set's lock now.

    A cache that cannot be written (read-only) is used as it is: reading must not fail for it.
    """
    if not leftovers(info):
        return
    try:
        with try_file_lock(_lock_path(info)) as held:
            if held:
                _remove_leftovers(info)
    except OSError as exc:
        log.warning("cannot remove what a stopped process left in %s (%s)", emotive_home(), exc)


def _unpack_into(info: DatasetInfo, fh: BinaryIO, label: str, root: Path) -> None:
    """Unpack the checked open archive ``fh`` to ``root/<folder>``; the caller holds the lock."""
    target = root / info.folder
    tmp = Path(tempfile.mkdtemp(prefix=f".{info.folder}.", dir=root))
    try:
        try:
            with tarfile.open(fileobj=fh, mode="r:*") as tar:
                members = _checked_members(info, tar, label)
                hashes = unpack(tar, members, tmp)
        except CORRUPT_STREAM_ERRORS as exc:
            raise DataError(f"cannot unpack {label} ({exc}); fetch the archive again") from None
        unpacked = tmp / info.folder
        if not (unpacked / "data").is_dir():
            raise DataError(f"archive {label} has no {info.folder}/data folder; fetch it again")
        _write_marker(info, unpacked)
        # The manifest depends on the checked archive alone, so it may go first: it is right
        # for the folder renamed below, and for a complete copy already in place.
        write_manifest(_manifest_of(info, members, hashes), manifest_path(target))
        if os.path.lexists(target):
            # Under the lock, an existing folder is no complete copy of this archive (or the
            # user asked for --force): nobody else is using it as one.
            os.rename(target, tmp / ".replaced")
        os.rename(unpacked, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _not_the_archive(info: DatasetInfo) -> str:
    """The fix named when an archive holds what the data set's archive never does."""
    return f"it is not the {info.name} archive; fetch it again"


def _checked_members(info: DatasetInfo, tar: tarfile.TarFile, label: str) -> list:
    """The members of an open archive, refused unless safe to unpack (see ``check_members``)."""
    members = tar.getmembers()
    check_members(members, info.folder, label, _not_the_archive(info))
    return members


def _write_marker(info: DatasetInfo, folder: Path) -> None:
    """Mark ``folder`` as a complete copy of the registry's archive (see :func:`is_cached`)."""
    (folder / MARKER).write_text(
        json.dumps({"name": info.name, "archive": info.archive, "sha256": info.sha256})
    )


def _manifest_of(
    info: DatasetInfo, members: list[tarfile.TarInfo], hashes: dict[str, str]
) -> Manifest:
    return Manifest.from_members(
        info.name, info.archive, info.sha256, info.folder, members, hashes
    )


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
        reader = HashingReader(src)
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


def _archive_lock_path(info: DatasetInfo) -> Path:
    """The lock guarding a data set's archive in the cache and its temporary copies."""
    return archive_cache_path(info).with_name(f".{info.archive}.lock")


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
        with file_lock(_archive_lock_path(info), what=doing):
            for leftover in leftovers(info):
                if leftover.parent == dest.parent:
                    log.info("removing %s, left by a process that was stopped", leftover)
                    leftover.unlink(missing_ok=True)
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

    A data set already in the cache is verified against its manifest, and what is damaged,
    missing or extra is repaired (see :func:`repair`).

    Args:
        name: registry name.
        source: URL, archive file or folder (see :func:`fetch_archive`); ``None`` for the
            default sources.
        force: fetch and unpack again even when the data set is cached.
        progress: show a progress bar while downloading or verifying.

    Raises:
        DataError: see :func:`fetch_archive` and :func:`extract_archive`.
        ChecksumError: the archive is corrupt; it is removed.
    """
    info = get_dataset(name)
    if is_cached(info) and not force:
        repair(info, source, progress=progress)
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


@dataclass(frozen=True)
class Verification:
    """An unpacked data set compared with its manifest (see :func:`verify`).

    Attributes:
        name: registry name.
        folder: the unpacked data set folder.
        files: number of files the manifest lists.
        hashed_bytes: bytes read and hashed (files whose size was already wrong are not read).
        problems: every damaged, missing or extra file or folder, sorted by path.
    """

    name: str
    folder: Path
    files: int
    hashed_bytes: int
    problems: tuple[Problem, ...]

    @property
    def clean(self) -> bool:
        """Whether the folder holds exactly the archive's files, intact."""
        return not self.problems

    def count(self, kind: str) -> int:
        """Number of problems of one kind (``"damaged"``, ``"missing"`` or ``"extra"``)."""
        return sum(p.kind == kind for p in self.problems)


def _lock_unless_read_only(stack: ExitStack, info: DatasetInfo, doing: str) -> bool:
    """Take the data set's lock in ``stack``; return whether the cache can be written.

    A cache this process may not write to cannot hold its lock file: it is read without the
    lock (on a read-only file system nobody can change it meanwhile).
    """
    try:
        stack.enter_context(file_lock(_lock_path(info), what=doing))
    except OSError as exc:
        if isinstance(exc, PermissionError) or exc.errno in READ_ONLY_ERRNOS:
            return False
        raise
    return True


@contextmanager
def _local_archive(info: DatasetInfo) -> Iterator[tuple[BinaryIO, str] | None]:
    """The data set's archive on this machine, opened and checked against the registry.

    The cache's copy is taken first, else a shared one (see :func:`find_shared_archive`).

    Yields:
        The open file at its start and its path for messages, or ``None``.

    Raises:
        ChecksumError: the archive is corrupt (the cache's own copy is removed).
    """
    cached = archive_cache_path(info)
    path = cached if cached.is_file() else find_shared_archive(info)
    if path is None:
        yield None
        return
    with _open_archive(path) as fh:
        _check_open(info, fh, path, remove=path == cached, source=None)
        yield fh, str(path)


@contextmanager
def _archive_for_repair(
    info: DatasetInfo, source: str | os.PathLike | None, progress: bool
) -> Iterator[tuple[BinaryIO, str]]:
    """A checked, open archive to repair from, and its path for messages.

    ``source`` when given (fetched into the cache), else one on this machine, else a fetch from
    the default sources (see :func:`fetch_archive`).
    """
    if source is None:
        with ExitStack() as stack:
            try:
                found = stack.enter_context(_local_archive(info))
            except ChecksumError:
                log.warning("removed a corrupt archive of %s; fetching it again", info.name)
                found = None
            if found is not None:
                yield found
                return
    path = fetch_archive(info, source, progress=progress)
    with _open_archive(path) as fh:
        _check_open(info, fh, path, remove=True, source=None)
        yield fh, str(path)


def _manifest_from_archive(info: DatasetInfo, fh: BinaryIO, label: str) -> Manifest:
    """The manifest of a checked, open archive, read without unpacking it."""
    fh.seek(0)
    try:
        members, hashes = scan(fh, info.folder, label, _not_the_archive(info))
    except CORRUPT_STREAM_ERRORS as exc:
        raise DataError(f"cannot read {label} ({exc}); fetch the archive again") from None
    return _manifest_of(info, members, hashes)


def _current_manifest(info: DatasetInfo) -> Manifest | None:
    """The manifest beside the data set folder, if it is one of the registry's archive."""
    manifest = read_manifest(manifest_path(cache_dir(info)))
    if manifest is None or (manifest.name, manifest.archive_sha256) != (info.name, info.sha256):
        return None
    return manifest


def _compare(info: DatasetInfo, manifest: Manifest, progress: bool) -> Verification:
    """Compare the data set folder with ``manifest``, the completion marker included."""
    folder = cache_dir(info)
    try:
        problems, hashed = check_folder(manifest, folder, ignore=(MARKER,), progress=progress)
    except OSError as exc:
        raise DataError(
            f"cannot read {folder} while verifying {info.name} ({exc}); make it readable, or "
            f"unpack it again with `emotive data fetch {info.name} --force`"
        ) from None
    if folder.is_dir() and not is_cached(info):
        there = os.path.lexists(folder / MARKER)
        problems.append(Problem(
            MARKER, "damaged" if there else "missing",
            "the mark of a complete unpack " + ("names another archive" if there else "is gone"),
        ))
        problems.sort(key=lambda p: (p.path, p.kind))
    return Verification(info.name, folder, len(manifest.files), hashed, tuple(problems))


def verify(name: str | DatasetInfo, *, progress: bool = False) -> Verification:
    """Compare an unpacked data set, file by file, with the manifest of its archive.

    Every file is checked for its size and sha256 against the manifest made when the archive
    was unpacked (see :mod:`emotive.data.manifest`). A cache unpacked before manifests existed
    gets one made from the archive, when the archive is on this machine. Leftovers of a killed
    unpack are removed first. Nothing in the data set folder is changed: :func:`repair` does.

    Args:
        name: registry name, e.g. ``"bandai-namco-1"``.
        progress: show a progress bar of the bytes hashed on stderr.

    Returns:
        What was found; :attr:`Verification.clean` when nothing differs.

    Raises:
        DataError: the data set was never unpacked in the cache (the message says to fetch it),
            it has no manifest and no archive is at hand to make one, or a file cannot be read.
        ChecksumError: the archive needed for a missing manifest is corrupt.
    """
    info = get_dataset(name)
    _require_unpacked(info, "verify")
    doing = f"verifying {info.name}"
    root = cache_dir(info).parent
    try:
        with ExitStack() as stack:
            writable = _lock_unless_read_only(stack, info, doing)
            if writable:
                _remove_leftovers(info)
            manifest = _current_manifest(info)
            if manifest is None:
                manifest = _make_manifest(info, writable)
            return _compare(info, manifest, progress)
    except OSError as exc:
        raise disk_error(exc, root, doing) from None


def _require_unpacked(info: DatasetInfo, verb: str) -> None:
    """Refuse a data set that was never unpacked in the cache (no folder, no manifest)."""
    folder = cache_dir(info)
    if not os.path.lexists(folder) and not manifest_path(folder).exists():
        raise DataError(
            f"data set {info.name!r} is not unpacked in the cache ({folder}): there is nothing "
            f"to {verb}; run `emotive data fetch {info.name}` first"
        )


def _make_manifest(info: DatasetInfo, writable: bool) -> Manifest:
    """Make the missing manifest from the archive on this machine (and save it if writable)."""
    path = manifest_path(cache_dir(info))
    with _local_archive(info) as found:
        if found is None:
            raise DataError(
                f"{path} is missing or out of date and no archive of {info.name} is on this "
                f"machine to make it again; run `emotive data fetch {info.name} --force` to "
                f"unpack the data set again with its manifest"
            )
        manifest = _manifest_from_archive(info, *found)
    if writable:
        write_manifest(manifest, path)
    return manifest


def repair(
    name: str | DatasetInfo, source: str | os.PathLike | None = None, *, progress: bool = False
) -> Verification:
    """Verify an unpacked data set and repair what differs from its archive.

    Damaged and missing files are unpacked again from the archive (checked against the
    registry first) into a temporary folder and renamed into place one by one, so a reader sees
    each file either as it was or whole; extra files and folders are removed. Nothing is
    written when the data set is intact, so an intact read-only cache passes. The whole step
    holds the data set's lock.

    Args:
        name: registry name.
        source: where to fetch the archive from if it is needed (see :func:`fetch_archive`);
            ``None`` uses the cache's archive, a shared one, or the default sources.
        progress: show progress bars while verifying and downloading.

    Returns:
        The verification before the repair: its problems are what was repaired.

    Raises:
        DataError: see :func:`verify` and :func:`fetch_archive`; the data set needs a repair
            but the cache is read-only; or the archive disagrees with the manifest (the message
            says to unpack again with ``--force``).
        ChecksumError: the archive is corrupt; a fetched copy is removed.
    """
    info = get_dataset(name)
    _require_unpacked(info, "repair")
    root = emotive_home() / "datasets"
    doing = f"repairing {info.name}"
    try:
        with ExitStack() as stack:
            writable = _lock_unless_read_only(stack, info, doing)
            if writable:
                _remove_leftovers(info)
            manifest = _current_manifest(info)
            if manifest is None and not writable:
                manifest = _make_manifest(info, writable=False)
            if manifest is not None:
                found = _compare(info, manifest, progress)
                if found.clean:
                    return found
                if not writable:
                    raise DataError(
                        f"{info.name} in {found.folder} has {len(found.problems)} damaged, "
                        f"missing or extra files (see `emotive data verify {info.name}`) but "
                        f"the cache is read-only; make {root} writable, or set EMOTIVE_HOME "
                        f"to a writable folder and fetch the data set again"
                    )
            with _archive_for_repair(info, source, progress) as (fh, label):
                if manifest is None:
                    manifest = _manifest_from_archive(info, fh, label)
                    write_manifest(manifest, manifest_path(cache_dir(info)))
                    found = _compare(info, manifest, progress)
                    if found.clean:
                        return found
                log.info("repairing %d files of %s from %s", len(found.problems), info.name,
                         label)
                _restore(info, fh, label, manifest, found)
    except OSError as exc:
        raise disk_error(exc, root, doing) from None
    return found


def _restore(
    info: DatasetInfo, fh: BinaryIO, label: str, manifest: Manifest, found: Verification
) -> None:
    """Make the data set folder match ``manifest`` again; the caller holds the lock."""
    target = found.folder
    whole = any(p.path == "." for p in found.problems)
    wanted = set(manifest.files) if whole else {
        p.path for p in found.problems if p.path in manifest.files
    }
    if whole and os.path.lexists(target) and not target.is_dir():
        _remove(target)
    for problem in found.problems:
        path = target / problem.path
        if problem.kind == "missing" or problem.path in (".", MARKER):
            continue
        if problem.kind == "extra" or not stat.S_ISREG(os.lstat(path).st_mode):
            _remove(path)  # extra, or a folder or link in the way of the archive's file
    target.mkdir(parents=True, exist_ok=True)
    for folder in sorted(manifest.folders):
        (target / folder).mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{info.folder}.", dir=target.parent))
    try:
        fh.seek(0)
        prefix = f"{info.folder}/"
        try:
            members, hashes = scan(fh, info.folder, label, _not_the_archive(info), dest=tmp,
                                   wanted={prefix + rel for rel in wanted})
        except CORRUPT_STREAM_ERRORS as exc:
            raise DataError(f"cannot unpack {label} ({exc}); fetch the archive again") from None
        for member in members:
            rel = member.name.removeprefix(prefix)
            if rel not in wanted or not member.isreg():
                continue
            if hashes[member.name] != manifest.files[rel].sha256:
                raise DataError(
                    f"{manifest_path(target)} disagrees with archive {label} on {rel}; unpack "
                    f"the data set again with `emotive data fetch {info.name} --force`"
                )
            os.replace(tmp.joinpath(*member.name.split("/")), target / rel)
        if not is_cached(info):
            _write_marker(info, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
