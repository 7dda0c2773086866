"""Resumable HTTP(S) download of an archive, with a size limit.

A download goes to ``<dest>.part`` and is renamed to ``dest`` when complete. A server that
honours HTTP ``Range`` continues where the last attempt stopped; one that does not sends the
whole file again. A transfer that breaks off keeps the ``.part`` file for the next attempt; one
that grows past the size limit, or that the local disk cannot hold, removes it.
"""

from __future__ import annotations

import http.client
import os
import urllib.error
import urllib.request
from pathlib import Path

from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    TimeRemainingColumn,
    TransferSpeedColumn,
)

import emotive
from emotive.data.archive import disk_error
from emotive.errors import DataError

#: The largest archive a download may bring (the real archives are under 100 MB).
MAX_DOWNLOAD_BYTES = 4 << 30
_CHUNK = 1 << 20
_TIMEOUT_S = 60.0


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


def _too_large(url: str, size: int, limit: int, part: Path) -> DataError:
    part.unlink(missing_ok=True)
    return DataError(
        f"download of {url} is {size} bytes or more, over the limit of {limit} bytes for a data "
        f"set archive; the partial file was removed; check that the URL names the archive"
    )


def _read(resp: http.client.HTTPResponse, url: str, done: int, part: Path) -> bytes:
    """The next block of the response; a broken transfer is a :class:`DataError`."""
    try:
        return resp.read(_CHUNK)
    except (OSError, http.client.HTTPException) as exc:
        raise DataError(
            f"download of {url} broke off after {done} bytes ({exc}); run the same command "
            f"again to resume from {part}"
        ) from None


def _progress_bar(name: str, total: int | None, done: int) -> tuple[Progress, object]:
    bar = Progress(
        "[progress.description]{task.description}", BarColumn(), DownloadColumn(),
        TransferSpeedColumn(), TimeRemainingColumn(),
    )
    task = bar.add_task(name, total=total, completed=done)
    bar.start()
    return bar, task


def download(
    url: str, dest: Path, *, progress: bool = False, max_bytes: int | None = None
) -> Path:
    """Download ``url`` to ``dest`` through ``dest.part``, resuming a partial ``.part``.

    Args:
        url: ``http(s)://`` address of the file.
        dest: where the complete file goes; its folder must exist.
        progress: show a progress bar.
        max_bytes: refuse a file larger than this; default :data:`MAX_DOWNLOAD_BYTES`.

    Returns:
        ``dest``, which appears only when the download is complete.

    Raises:
        DataError: the server answers with an error; the transfer breaks off (the ``.part``
            file is kept so the next call resumes); the file is larger than ``max_bytes`` or the
            disk cannot hold it (the ``.part`` file is removed).
    """
    dest = Path(dest)
    limit = MAX_DOWNLOAD_BYTES if max_bytes is None else max_bytes
    part = dest.with_name(dest.name + ".part")
    offset = part.stat().st_size if part.exists() else 0
    resp, start = _open(url, offset)
    length = resp.headers.get("Content-Length")
    total = start + int(length) if length and length.isdigit() else None
    if total is not None and total > limit:
        resp.close()
        raise _too_large(url, total, limit, part)
    done = start
    try:
        fh = open(part, "ab" if start else "wb")
    except OSError as exc:
        resp.close()
        raise disk_error(exc, part.parent, f"downloading {url}") from None
    bar, task = _progress_bar(dest.name, total, done) if progress else (None, None)
    try:
        with resp, fh:
            while block := _read(resp, url, done, part):
                if done + len(block) > limit:
                    raise _too_large(url, done + len(block), limit, part)
                fh.write(block)
                done += len(block)
                if bar is not None:
                    bar.update(task, completed=done)
    except OSError as exc:
        part.unlink(missing_ok=True)
        raise disk_error(exc, part.parent, f"downloading {url} (partial file removed)") from None
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
