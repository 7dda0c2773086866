"""The input contract every motion reader keeps: which files it opens and what it accepts.

BVH (:mod:`emotive.io.bvh`), glTF/GLB (:mod:`emotive.io.gltf_read`) and FBX
(:mod:`emotive.io.fbx`, converted by Blender to a GLB that the glTF reader reads) share these
limits, so a clip is refused or read alike whatever its format. A reader:

- opens only regular files (:func:`open_regular`): never a pipe, socket, device, folder or a
  file under :data:`SYSTEM_FOLDERS`, each opened without blocking (``O_NONBLOCK``) and checked
  with ``fstat`` on the open file, at most :data:`MAX_FILE_BYTES` long, read at most as long as
  it was when opened;
- follows a reference a file makes to another file (a glTF buffer's ``uri``) only inside the
  folder of the file, after percent-decoding and resolving symbolic links
  (:func:`resolve_reference`); URLs are never fetched, and ``data:`` URIs are decoded within
  the budget of the document holding them (:func:`decode_data_uri`);
- checks every count and size against these limits before it makes an array: at most
  :data:`MAX_JOINTS` joints, :data:`MAX_FRAMES` frames and :data:`MAX_VALUES` values
  (:func:`size_problem`), :data:`MAX_NODES` nodes nested at most :data:`MAX_DEPTH` deep, of
  which at most :data:`MAX_MOVING_NODES` move;
- accepts only finite numbers, lengths within :data:`MAX_LENGTH_M` metres
  (:func:`length_problem`) and frame rates within :data:`MIN_FPS`-:data:`MAX_FPS`
  (:func:`fps_problem`).

Each function reports a problem as one line that names the value and the fix: the ``*_problem``
functions return it (``None`` when all is well), the others raise the exception ``fail`` makes
of it, so each reader raises its own typed error (:class:`~emotive.errors.BVHError`,
:class:`~emotive.errors.MotionFileError`) naming the file and the element. ``docs/limits.md``
and ``docs/rigs.md`` state every limit and why.
"""

from __future__ import annotations

import base64
import binascii
import os
import re
import stat
from collections.abc import Callable
from urllib.parse import unquote

import numpy as np

#: Largest file read (1 GiB), of any format: a BVH file at :data:`MAX_VALUES` written with 9
#: significant digits takes 230-330 MB, a GLB holding as many float32 values 80 MB.
MAX_FILE_BYTES = 1 << 30
#: Largest JSON text of a glTF document (128 MiB): its base64 data URIs included, so a
#: ``.gltf`` holding :data:`MAX_VALUES` float32 values (107 MB of base64) is read.
MAX_JSON_BYTES = 128 << 20
#: Most JSON values in one glTF document (counted from its ``{``, ``[`` and ``,`` before it is
#: parsed): parsed values take up to 64 bytes each, so the parsed document stays under 300 MB.
MAX_JSON_ITEMS = 1 << 22
#: Most nodes in one glTF document, and most entries of each of its other arrays (accessors,
#: buffer views, animation channels...): characters with props and a scene around them have
#: a few thousand.
MAX_NODES = 65_536
#: Most joints in one skeleton, and most end sites; full-body rigs with fingers and a face
#: have a few hundred.
MAX_JOINTS = 1024
#: Deepest node nesting (root depth 1): a joint chain as deep as :data:`MAX_JOINTS` under as
#: many scene, armature and helper nodes again. Node trees are walked without recursion.
MAX_DEPTH = 2 * MAX_JOINTS
#: Most nodes whose transforms change during a clip and place its joints (the joints and the
#: animated helper nodes above them): a clip's transforms are composed for each of them on
#: every frame.
MAX_MOVING_NODES = 2 * MAX_JOINTS
#: Longest joint (node) name, in characters: rig names run to a few dozen.
MAX_NAME_CHARS = 256
#: Most frames in one clip: over 9 hours at 30 fps, over 16 minutes at 1,000 fps.
MAX_FRAMES = 1_000_000
#: Most values in one clip, checked before any array is made: a BVH file's frames x channels,
#: a glTF file's resampled frames x 6 per joint and the animation values it holds. An hour of
#: a 60-joint rig (183 channels) at 30 fps. Reading a BVH file at this limit peaks at about
#: 540 MB above the interpreter; 59 million values took over 2 GB and ended in a
#: ``MemoryError`` under a 3 GB address-space limit.
MAX_VALUES = 20_000_000
#: Lowest and highest frame rate, frames per second.
MIN_FPS = 1.0
MAX_FPS = 1000.0
#: Largest absolute offset or position coordinate, in metres after unit conversion: a
#: capture volume or game level spans at most a few hundred metres, and float32 (the GPU's
#: type) still resolves 0.1 mm at 1 km.
MAX_LENGTH_M = 1000.0
#: Most characters of a file's own text (a value, a URI) quoted in a message.
QUOTE_CHARS = 80
#: Folders of the kernel's pseudo files: their files look regular but are not data.
SYSTEM_FOLDERS = ("/proc", "/sys", "/dev")
#: Longest reference (URI) followed, in characters: the longest path Linux opens.
MAX_URI_CHARS = 4096

#: What makes the exception a reader raises from a problem's text.
Fail = Callable[[str], Exception]

_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.\-]*:")
_DRIVE = re.compile(r"[A-Za-z]:[\\/]")


def quote(text: str) -> str:
    """``text`` in quotes, cut to :data:`QUOTE_CHARS` characters and its length when longer.

    Args:
        text: text of the file that a message shows.

    Returns:
        ``'text'``, or ``'first characters...' (5,000 characters)``.
    """
    if len(text) <= QUOTE_CHARS:
        return f"'{text}'"
    return f"'{text[:QUOTE_CHARS - 3]}...' ({len(text):,} characters)"


def size_problem(frames: int, width: int, n_joints: int) -> str | None:
    """What is too large about a clip's declared size, or ``None``.

    Args:
        frames: frames of the clip.
        width: values per frame (channels).
        n_joints: joints in the skeleton.

    Returns:
        A message naming the count and the limit, or ``None``.
    """
    if n_joints > MAX_JOINTS:
        return f"{n_joints} joints: at most {MAX_JOINTS} are read; split or simplify the rig"
    if frames > MAX_FRAMES:
        return f"{frames:,} frames: at most {MAX_FRAMES:,} frames are read; split the clip"
    if frames * width > MAX_VALUES:
        return (
            f"{frames:,} frames x {width} channels = {frames * width:,} values: at most "
            f"{MAX_VALUES:,} are read; split the clip"
        )
    return None


def length_problem(values_m: np.ndarray, what: str) -> str | None:
    """What is out of range in lengths already converted to metres, or ``None``.

    Args:
        values_m: any-shaped lengths in metres.
        what: what they are, for the message (``"joint offsets"``).

    Returns:
        A message naming the largest value (or the first that is not finite) and the limit,
        or ``None``.
    """
    if values_m.size == 0:
        return None
    if not np.all(np.isfinite(values_m)):
        return f"{what} are not all finite numbers (NaN or infinite); the file is corrupt"
    biggest = float(np.abs(values_m).max())
    if biggest <= MAX_LENGTH_M:
        return None
    return (
        f"{what} reach {biggest:.3g} m: at most {MAX_LENGTH_M:g} m is plausible; check the "
        "numbers or pass the file's unit (unit='mm', 'cm', 'm' or 'in')"
    )


def fps_problem(fps: float) -> str | None:
    """What is wrong with a frame rate, or ``None`` when it is within the limits.

    Args:
        fps: frames per second.

    Returns:
        A message naming the rate and the allowed range, or ``None``.
    """
    if np.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS:
        return None
    return (f"a frame rate of {fps:g} frames per second: {MIN_FPS:g}-{MAX_FPS:g} are read; "
            "pass a rate in that range")


class InputFile:
    """A regular file opened for reading, within its size budget (see :func:`open_regular`).

    Args:
        fd: the open file descriptor (owned and closed by this object).
        path: the file's real path.
        size: its size in bytes when it was opened.
        fail: makes the exception a problem raises.
    """

    def __init__(self, fd: int, path: str, size: int, fail: Fail) -> None:
        self.fd = fd
        self.path = path
        self.size = size
        self._fail = fail

    def read_at(self, offset: int, length: int) -> bytes:
        """``length`` bytes from ``offset``, within the size the file had when opened.

        Raises:
            The exception of ``fail``: the range is beyond that size, or the file shrank.
        """
        if offset < 0 or length < 0 or offset + length > self.size:
            raise self._fail(f"holds {self.size:,} bytes, too few for the {length:,} bytes at "
                             f"offset {offset:,} it is read for; the file is truncated")
        chunks, done = [], 0
        while done < length:
            try:
                chunk = os.pread(self.fd, min(length - done, 1 << 26), offset + done)
            except OSError as exc:
                raise self._fail(f"cannot be read ({exc.strerror or exc})") from None
            if not chunk:
                raise self._fail("became shorter while it was read; read it again once it is "
                                 "written whole")
            chunks.append(chunk)
            done += len(chunk)
        return b"".join(chunks)

    def read_all(self) -> bytes:
        """The whole file, as long as it was when opened."""
        return self.read_at(0, self.size)

    def close(self) -> None:
        """Close the file (again: nothing)."""
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    def __enter__(self) -> InputFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _system_file(real: str) -> bool:
    return any(real == top or real.startswith(top + os.sep) for top in SYSTEM_FOLDERS)


def _opened_path(fd: int) -> str | None:
    """The path the kernel gives an open file (Linux's ``/proc/self/fd``), else ``None``."""
    try:
        return os.readlink(f"/proc/self/fd/{fd}")
    except OSError:
        return None


def open_regular(path: str | os.PathLike, fail: Fail, max_bytes: int | None = None,
                 inside: str | None = None) -> InputFile:
    """Open a regular file for reading without ever blocking, within a size budget.

    A pipe, socket, device or folder is refused, as is a file under :data:`SYSTEM_FOLDERS`
    (``/proc``'s files say they are regular and empty) and one bigger than ``max_bytes``:
    checked with ``os.stat`` before the file is opened, so such a file is never opened, and
    again with ``fstat`` on the descriptor opened with ``O_NONBLOCK`` (a pipe swapped in
    between does not wait for a writer).

    Args:
        path: the file.
        fail: makes the exception a problem raises (the problem names no file: ``fail``
            adds it).
        max_bytes: largest size read; ``None`` for :data:`MAX_FILE_BYTES`.
        inside: a real folder path the opened file must lie in (a reference the caller
            resolved with :func:`resolve_reference`); its last component is then not
            followed if it became a symbolic link since, and the path the kernel reports
            for the open file is checked again.

    Returns:
        The open file; close it (it is a context manager).

    Raises:
        The exception of ``fail``.
    """
    limit = MAX_FILE_BYTES if max_bytes is None else max_bytes
    # Checked before opening too, so a device, pipe or kernel file is never opened at all;
    # the checks on the open descriptor below catch one swapped in since.
    try:
        before = os.stat(path, follow_symlinks=inside is None)
    except FileNotFoundError:
        raise fail("no such file; check the path") from None
    except OSError as exc:
        raise fail(f"cannot be opened ({exc.strerror or exc}); pass a regular file") from None
    _check_kind(before, os.path.realpath(path), limit, inside, fail)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(
        os, "O_BINARY", 0)
    if inside is not None:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise fail("no such file; check the path") from None
    except OSError as exc:
        raise fail(f"cannot be opened ({exc.strerror or exc}); pass a regular file") from None
    try:
        info = os.fstat(fd)
        real = _opened_path(fd) or os.path.realpath(path)
        _check_kind(info, real, limit, inside, fail)
    except BaseException:
        os.close(fd)
        raise
    return InputFile(fd, real, info.st_size, fail)


def _check_kind(info: os.stat_result, real: str, limit: int, inside: str | None,
                fail: Fail) -> None:
    """Refuse what :func:`open_regular` does not read, from the file's status."""
    if stat.S_ISDIR(info.st_mode):
        raise fail("is a folder, not a file; pass the path of a file")
    if not stat.S_ISREG(info.st_mode):
        raise fail("is not a regular file (a pipe, socket or device); save the data to a "
                   "file first")
    if _system_file(real):
        raise fail(f"is a system file ({real}), not a motion file; pass a file of yours")
    if inside is not None and not _within(real, inside):
        raise fail(f"leads outside the folder {inside}; keep the files it needs in its own "
                   "folder")
    if info.st_size > limit:
        raise fail(f"is {info.st_size:,} bytes: at most {limit:,} are read; split the clip or "
                   "export less")


def _within(real: str, folder: str) -> bool:
    try:
        return os.path.commonpath([real, folder]) == folder
    except ValueError:  # one absolute and one relative path, or different drives
        return False


def resolve_reference(folder: str, uri: str, fail: Fail) -> str:
    """The real path of a file a document refers to, which must lie inside ``folder``.

    The reference is percent-decoded (``%2E%2E`` is ``..``) and joined to the folder; the
    result, with every symbolic link resolved, must lie in the folder or below it. URLs
    (``http:``, ``file:``...), absolute paths, NUL bytes and references longer than
    :data:`MAX_URI_CHARS` are refused; nothing is opened here.

    Args:
        folder: the real path of the folder of the referring file.
        uri: the reference as the document writes it (not a ``data:`` URI).
        fail: makes the exception a problem raises.

    Returns:
        The real path, to open with :func:`open_regular` (``inside=folder``).

    Raises:
        The exception of ``fail``.
    """
    keep = "keep the file it names in the same folder (or one below it), or export a .glb"
    if len(uri) > MAX_URI_CHARS:
        raise fail(f"is {len(uri):,} characters long: at most {MAX_URI_CHARS:,} are read; {keep}")
    if _SCHEME.match(uri) and not _DRIVE.match(uri):
        raise fail(f"{quote(uri)} is a URL: only files beside the document and data: URIs are "
                   f"read, nothing is fetched; {keep}")
    try:
        name = unquote(uri, errors="strict")
    except UnicodeDecodeError:
        raise fail(f"{quote(uri)} does not decode to a UTF-8 file name; {keep}") from None
    if not name or "\0" in name:
        raise fail(f"{quote(uri)} names no file (empty, or holds a NUL byte); {keep}")
    if os.path.isabs(name) or name.startswith(("/", "\\")) or _DRIVE.match(name):
        raise fail(f"{quote(uri)} is an absolute path: references are read only relative to "
                   f"the document's folder; {keep}")
    real = os.path.realpath(os.path.join(folder, name))
    if not _within(real, folder):
        raise fail(f"{quote(uri)} leads outside the document's folder (to {quote(real)}); "
                   f"{keep}")
    return real


def decode_data_uri(uri: str, fail: Fail) -> bytes:
    """The bytes of a base64 ``data:`` URI (``data:[type];base64,...``).

    Its size is bounded by the document holding it (:data:`MAX_JSON_BYTES`).

    Raises:
        The exception of ``fail``: the URI is not base64, or not valid base64.
    """
    head, _, data = uri.partition(",")
    if not head.endswith(";base64"):
        raise fail(f"is a data URI that is not base64 ({quote(head)}); re-export the file as "
                   ".glb")
    try:
        return base64.b64decode(data, validate=True)
    except (binascii.Error, ValueError):
        raise fail("holds invalid base64; the file is corrupt, export it again") from None

