"""The manifest of an unpacked data set: each file's size and sha256, taken from its archive.

A manifest is made while the archive is unpacked, from the bytes written (which are the bytes
of the archive whose sha256 the registry holds), and written atomically beside the data set
folder as ``<folder>.manifest.json``, outside the folder it describes. :func:`check_folder`
compares a folder with its manifest and names every file that is damaged (another size or
sha256, or no longer a regular file), missing, or extra (not in the archive).

Sizes are compared before any hashing, so a truncated file costs nothing to find; hashing the
rest reads every byte once (about 240 MB for both Bandai Namco sets, under a second or two on
one core when the files are in the page cache).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import tarfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

from emotive.io.atomic import atomic_output

#: Suffix of the manifest file beside a data set folder.
SUFFIX = ".manifest.json"
#: Format version written into every manifest; another version is read as no manifest.
VERSION = 1
_CHUNK = 1 << 20


@dataclass(frozen=True)
class FileRecord:
    """One file of an archive.

    Attributes:
        size: length in bytes.
        sha256: hex sha256 of its bytes.
    """

    size: int
    sha256: str


@dataclass(frozen=True)
class Manifest:
    """Every file a data set folder must hold, as its archive holds it.

    Attributes:
        name: registry name of the data set.
        archive: file name of the archive the files come from.
        archive_sha256: hex sha256 of that archive (the registry's at unpack time).
        files: each file by its path relative to the data set folder (``/``-separated).
        folders: every folder inside the data set folder, by the same kind of path.
    """

    name: str
    archive: str
    archive_sha256: str
    files: dict[str, FileRecord]
    folders: frozenset[str]

    @classmethod
    def from_members(
        cls, name: str, archive: str, archive_sha256: str, folder: str,
        members: list[tarfile.TarInfo], hashes: dict[str, str],
    ) -> Manifest:
        """The manifest of an archive's checked members (see :mod:`emotive.data.archive`).

        Args:
            name: registry name.
            archive: archive file name.
            archive_sha256: the archive's hex sha256.
            folder: the archive's single top-level folder, stripped from every member name.
            members: the archive's members (folders and regular files).
            hashes: each regular member's hex sha256, by member name.
        """
        prefix = f"{folder}/"
        files = {}
        folders = set()
        for member in members:
            rel = member.name.rstrip("/").removeprefix(prefix)
            if member.isreg():
                files[rel] = FileRecord(member.size, hashes[member.name])
            elif rel != folder:
                folders.add(rel)
            parts = rel.split("/")
            folders.update("/".join(parts[:i]) for i in range(1, len(parts)))
        return cls(name, archive, archive_sha256, dict(sorted(files.items())),
                   frozenset(folders))

    def to_json(self) -> str:
        """The manifest as JSON text (files sorted by path)."""
        return json.dumps({
            "version": VERSION, "name": self.name, "archive": self.archive,
            "archive_sha256": self.archive_sha256,
            "folders": sorted(self.folders),
            "files": {p: [r.size, r.sha256] for p, r in sorted(self.files.items())},
        }, indent=0)

    @classmethod
    def from_json(cls, text: str) -> Manifest | None:
        """Parse :meth:`to_json`'s text.

        Returns:
            The manifest; ``None`` when the text is no manifest of this version or names a
            path outside the data set folder (an edited file is made again from the archive).
        """
        try:
            data = json.loads(text)
            if data.get("version") != VERSION:
                return None
            files = {
                str(p): FileRecord(int(size), str(digest))
                for p, (size, digest) in data["files"].items()
            }
            folders = frozenset(str(p) for p in data["folders"])
            if not all(map(_is_inside, [*files, *folders])):
                return None
            return cls(str(data["name"]), str(data["archive"]), str(data["archive_sha256"]),
                       files, folders)
        except (ValueError, TypeError, KeyError, AttributeError):
            return None


def _is_inside(path: str) -> bool:
    """Whether a manifest path names something inside the data set folder (no ``..``)."""
    return not path.startswith("/") and all(p not in ("", ".", "..") for p in path.split("/"))


@dataclass(frozen=True)
class Problem:
    """One way a data set folder differs from its manifest.

    Attributes:
        path: the file or folder, relative to the data set folder (``.`` for the folder).
        kind: ``"damaged"``, ``"missing"`` or ``"extra"``.
        detail: what differs, e.g. ``"1203 bytes, the archive's has 4096"``.
    """

    path: str
    kind: str
    detail: str


def manifest_path(folder: Path) -> Path:
    """Where the manifest of the data set folder ``folder`` lives: beside it."""
    return folder.with_name(folder.name + SUFFIX)


def read_manifest(path: Path) -> Manifest | None:
    """The manifest at ``path``; ``None`` when it is absent, unreadable or not a manifest."""
    try:
        return Manifest.from_json(path.read_text())
    except (OSError, UnicodeDecodeError):
        return None


def write_manifest(manifest: Manifest, path: Path) -> None:
    """Write ``manifest`` to ``path`` atomically (a reader sees the old file or the new one).

    Raises:
        OutputError: the file cannot be written (full disk, read-only folder).
    """
    with atomic_output(path) as tmp:
        tmp.write_text(manifest.to_json())


def _walk(folder: Path, rel: str = "") -> dict[str, os.stat_result]:
    """Every entry under ``folder`` (links not followed) with its ``lstat``, by relative path.

    A folder's contents are listed under it; a link to a folder is one entry, not descended.
    """
    entries = {}
    with os.scandir(folder) as it:
        for entry in it:
            path = f"{rel}{entry.name}"
            entries[path] = entry.stat(follow_symlinks=False)
            if entry.is_dir(follow_symlinks=False):
                entries.update(_walk(Path(entry.path), f"{path}/"))
    return entries


def _sha256(path: Path, advance: Callable[[int], None]) -> str:
    """Hex sha256 of the file at ``path``, calling ``advance(n)`` after every ``n`` bytes."""
    digest = hashlib.sha256()
    with open(path, "rb", buffering=0) as fh:
        while block := fh.read(_CHUNK):
            digest.update(block)
            advance(len(block))
    return digest.hexdigest()


def check_folder(
    manifest: Manifest, folder: Path, *, ignore: tuple[str, ...] = (), progress: bool = False
) -> tuple[list[Problem], int]:
    """Compare a data set folder with its manifest.

    Args:
        manifest: what the folder must hold.
        folder: the unpacked data set folder.
        ignore: paths (relative to ``folder``) that belong there but not to the archive.
        progress: show a progress bar of the bytes hashed on stderr.

    Returns:
        The problems sorted by path (empty when the folder is intact), and the bytes hashed.
        A folder that is not there at all is one ``missing`` problem with path ``.``.

    Raises:
        OSError: a file cannot be read (the caller names the folder).
    """
    if not folder.is_dir():
        return [Problem(".", "missing", f"the data set folder {folder} is not there")], 0
    on_disk = _walk(folder)
    expected_dirs = manifest.folders
    problems: list[Problem] = []
    to_hash: list[tuple[str, FileRecord]] = []
    for path, record in manifest.files.items():
        found = on_disk.get(path)
        if found is None:
            problems.append(Problem(path, "missing", "file not there"))
        elif not stat.S_ISREG(found.st_mode):
            kind = "a folder" if stat.S_ISDIR(found.st_mode) else "a link or special file"
            problems.append(Problem(path, "damaged", f"is {kind}, not the archive's file"))
        elif found.st_size != record.size:
            problems.append(Problem(
                path, "damaged", f"{found.st_size} bytes, the archive's has {record.size}"
            ))
        else:
            to_hash.append((path, record))
    replaced = {p.path for p in problems if p.kind == "damaged"}
    for path in sorted(expected_dirs - on_disk.keys()):
        problems.append(Problem(path, "missing", "folder not there"))
    for path, found in on_disk.items():
        parent = path.rsplit("/", 1)[0] if "/" in path else None
        inside_reported = any(path.startswith(f"{r}/") for r in replaced)
        if path in manifest.files or path in ignore or inside_reported:
            continue
        if parent is not None and parent not in expected_dirs:
            continue  # inside an extra folder, which is reported once
        if path in expected_dirs:
            if not stat.S_ISDIR(found.st_mode):
                problems.append(Problem(path, "damaged", "is a file or link, the archive's is "
                                                         "a folder"))
            continue
        problems.append(Problem(path, "extra", "not in the archive"))
    total = sum(record.size for _, record in to_hash)
    with _bar(f"verifying {manifest.name}", total, progress) as advance:
        for path, record in to_hash:
            if _sha256(folder / path, advance) != record.sha256:
                problems.append(Problem(path, "damaged", "sha256 differs from the archive's"))
    return sorted(problems, key=lambda p: (p.path, p.kind)), total


@contextmanager
def _bar(description: str, total: int, show: bool) -> Iterator[Callable[[int], None]]:
    """A transient progress bar of ``total`` bytes on stderr (hidden unless ``show``).

    It shows only on a terminal: a log of stderr gets no bar and no blank line.

    Yields:
        ``advance(n)``, to call after every ``n`` bytes.
    """
    console = Console(stderr=True)
    progress = Progress(
        "[progress.description]{task.description}", BarColumn(), DownloadColumn(),
        TimeRemainingColumn(), console=console, transient=True,
        disable=not (show and console.is_terminal),
    )
    task = progress.add_task(description, total=total)
    with progress:
        yield lambda n: progress.advance(task, n)
