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

Every archive is checked against the registry's sha256 before it is unpacked; an archive that
fails the check is deleted. Unpacking refuses members outside the data set's folder and uses
:mod:`tarfile`'s ``data`` filter (no absolute paths, links out of the tree or device files), into
a temporary folder renamed into place, so a half-unpacked data set is never visible.
"""

from __future__ import annotations

import hashlib
import http.client
import json
import logging
import os
import shutil
import tarfile
import tempfile
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    TimeRemainingColumn,
    TransferSpeedColumn,
)

import emotive
from emotive.data.registry import DatasetInfo, get_dataset
from emotive.errors import ChecksumError, DataError
from emotive.io.atomic import atomic_output

log = logging.getLogger(__name__)

#: File written into an unpacked data set once it is complete.
MARKER = ".emotive-dataset.json"
_CHUNK = 1 << 20
_TIMEOUT_S = 60.0


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
    cache; later calls return the cached folder at once.

    Args:
        name: registry name, e.g. ``"bandai-namco-1"``.

    Raises:
        DataError: the data set is neither cached nor in a shared data folder; the message says
            to run ``emotive data fetch NAME``.
        ChecksumError: the shared archive is corrupt.
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
    log.info("unpacking %s from %s", info.name, shared)
    verify_archive(info, shared, remove=False)
    return extract_archive(info, shared)


def sha256_file(path: Path) -> str:
    """Hex sha256 of a file."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(_CHUNK):
            digest.update(block)
    return digest.hexdigest()


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
    """
    info = get_dataset(name)
    actual = sha256_file(path)
    if actual != info.sha256:
        if remove:
            Path(path).unlink(missing_ok=True)
        removed = "; the corrupt copy was removed" if remove else ""
        raise ChecksumError(
            f"archive {source or path} has sha256 {actual} but {info.name} needs {info.sha256}: "
            f"the file is corrupt or not {info.archive}{removed}; fetch it again with "
            f"`emotive data fetch {info.name} --source PATH_OR_URL`"
        )


def extract_archive(name: str | DatasetInfo, archive: Path) -> Path:
    """Unpack a checked archive into the cache and return the data set folder.

    Members must lie inside the data set's folder; :mod:`tarfile`'s ``data`` filter rejects
    absolute paths, ``..`` and links that leave the tree. The archive is unpacked into a
    temporary folder that is renamed into place when complete.

    Raises:
        DataError: the archive is not a readable tar file or holds unsafe members.
    """
    info = get_dataset(name)
    root = emotive_home() / "datasets"
    root.mkdir(parents=True, exist_ok=True)
    target = root / info.folder
    tmp = Path(tempfile.mkdtemp(prefix=f".{info.folder}.", dir=root))
    try:
        with tarfile.open(archive, "r:*") as tar:
            members = tar.getmembers()
            outside = [
                m.name for m in members
                if m.name.rstrip("/") != info.folder and not m.name.startswith(info.folder + "/")
            ]
            if outside:
                raise DataError(
                    f"archive {archive} holds {outside[0]!r}, outside {info.folder}/: it is not "
                    f"the {info.name} archive; fetch it again"
                )
            tar.extractall(tmp, members=members, filter="data")
        unpacked = tmp / info.folder
        if not (unpacked / "data").is_dir():
            raise DataError(f"archive {archive} has no {info.folder}/data folder; fetch it again")
        (unpacked / MARKER).write_text(
            json.dumps({"name": info.name, "archive": info.archive, "sha256": info.sha256})
        )
        if target.exists():
            shutil.rmtree(target)
        try:
            os.replace(unpacked, target)
        except OSError:
            # Another process unpacked the same archive at the same moment: keep its copy.
            if not is_cached(info):
                raise
    except (tarfile.TarError, EOFError, OSError) as exc:
        raise DataError(f"cannot unpack {archive} ({exc}); fetch the archive again") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return target


def _is_url(source: str) -> bool:
    return source.startswith(("http://", "https://"))


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
        DataError: the source does not exist, the download fails or is interrupted (run again
            to resume), or no source is known.
        ChecksumError: the copy is corrupt; it is removed.
    """
    info = get_dataset(name)
    dest = archive_cache_path(info)
    dest.parent.mkdir(parents=True, exist_ok=True)
    if source is None:
        shared = find_shared_archive(info)
        base = os.environ.get("EMOTIVE_DATA_URL")
        if shared is not None:
            source = shared
        elif base:
            source = f"{base.rstrip('/')}/{info.archive}"
        else:
            raise DataError(
                f"no source for {info.name}: the upstream repository {info.upstream} does not "
                f"host {info.archive}; pass --source with a URL, the archive file or the folder "
                f"holding it, or set EMOTIVE_DATA (a folder of archives) or EMOTIVE_DATA_URL"
            )
    text = str(source)
    if _is_url(text):
        download(text, dest, progress=progress)
        verify_archive(info, dest, source=text)
        return dest
    path = Path(text).expanduser()
    if path.is_dir():
        path = path / info.archive
    if not path.is_file():
        raise DataError(f"{path} does not exist: pass the {info.archive} file or its folder")
    with atomic_output(dest) as tmp:
        shutil.copyfile(path, tmp)
        verify_archive(info, tmp, source=str(path))
    return dest


def _open(url: str, offset: int) -> tuple[http.client.HTTPResponse, int]:
    """Open ``url`` asking for bytes from ``offset``; return the response and its start byte."""
    headers = {"User-Agent": f"emotive/{emotive.__version__}"}
    if offset:
        headers["Range"] = f"bytes={offset}-"
    try:
        resp = urllib.request.urlopen(
            urllib.request.Request(url, headers=headers), timeout=_TIMEOUT_S
        )
    except urllib.error.HTTPError as exc:
        if exc.code == 416 and offset:
            # The partial file is already complete (or longer than the file): start over.
            return _open(url, 0)
        raise DataError(f"download of {url} failed: HTTP {exc.code} {exc.reason}") from None
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", exc)
        raise DataError(f"cannot reach {url} ({reason}): check the URL and the network") from None
    if resp.status == 206:
        content_range = resp.headers.get("Content-Range", "")
        start = content_range.removeprefix("bytes ").split("-")[0]
        if start.isdigit() and int(start) == offset:
            return resp, offset
        resp.close()
        if offset:
            return _open(url, 0)
        raise DataError(
            f"download of {url} failed: the server sent part of the file unasked; try another URL"
        )
    return resp, 0


def download(url: str, dest: Path, *, progress: bool = False) -> Path:
    """Download ``url`` to ``dest`` through ``dest.part``, resuming a partial ``.part``.

    A server that honours HTTP ``Range`` continues where the last attempt stopped; one that does
    not sends the whole file again. ``dest`` appears only when the download is complete.

    Raises:
        DataError: the server answers with an error, or the transfer breaks off (the ``.part``
            file is kept so the next call resumes).
    """
    dest = Path(dest)
    part = dest.with_name(dest.name + ".part")
    offset = part.stat().st_size if part.exists() else 0
    resp, start = _open(url, offset)
    length = resp.headers.get("Content-Length")
    total = start + int(length) if length and length.isdigit() else None
    done = start
    bar = None
    if progress:
        bar = Progress(
            "[progress.description]{task.description}", BarColumn(), DownloadColumn(),
            TransferSpeedColumn(), TimeRemainingColumn(),
        )
        task = bar.add_task(dest.name, total=total, completed=done)
        bar.start()
    try:
        with resp, open(part, "ab" if start else "wb") as fh:
            while block := resp.read(_CHUNK):
                fh.write(block)
                done += len(block)
                if bar is not None:
                    bar.update(task, completed=done)
    except (OSError, http.client.HTTPException) as exc:
        raise DataError(
            f"download of {url} broke off after {done} bytes ({exc}); run the same command "
            f"again to resume from {part}"
        ) from None
    finally:
        if bar is not None:
            bar.stop()
    if total is not None and done != total:
        raise DataError(
            f"download of {url} stopped at {done} of {total} bytes; run the same command again "
            f"to resume from {part}"
        )
    os.replace(part, dest)
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
    else:
        try:
            verify_archive(info, archive)
        except ChecksumError:
            log.warning("removed corrupt %s; fetching it again", archive)
            archive = fetch_archive(info, None, progress=progress)
    return extract_archive(info, archive)
