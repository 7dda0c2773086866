"""Streaming RGB frames into an MP4 or GIF file through ffmpeg, with every failure reported.

The ffmpeg binary is the one the ``imageio-ffmpeg`` wheel ships. Unlike
``imageio_ffmpeg.write_frames``, :class:`VideoEncoder` waits for ffmpeg to finish however long
the GIF palette takes, checks its exit status, and checks that the file it wrote is whole (a GIF
ends with its trailer byte), so a full disk or a killed encoder is an
:class:`~emotive.errors.OutputError` and never a truncated video reported as written. An
encoder stopped by a signal is named by it, in words (:func:`killed_by`): the file-size limit
(``SIGXFSZ``), or a kill.
"""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path
from types import TracebackType

from emotive.errors import OutputError
from emotive.io.atomic import output_error

#: ffmpeg's words for a system error -> its errno, to phrase the message as for Python writes.
_FFMPEG_ERRNO = {
    "No space left on device": errno.ENOSPC,
    "Disk quota exceeded": errno.EDQUOT,
    "File too large": errno.EFBIG,
    "Read-only file system": errno.EROFS,
    "Permission denied": errno.EACCES,
    "Operation not permitted": errno.EPERM,
    "Is a directory": errno.EISDIR,
    "Input/output error": errno.EIO,
}
#: Signal name -> what to do when it stopped ffmpeg (:func:`killed_by`).
_SIGNAL_HINTS = {
    "SIGXFSZ": "the video grew beyond the largest file this process may write (ulimit -f); "
               "raise the limit (ulimit -f unlimited) or ask for a shorter or smaller video",
    "SIGKILL": "something killed it, often the system running out of memory; free memory or "
               "ask for a smaller video",
    "SIGTERM": "it was asked to stop; run the command again",
    "SIGINT": "it was interrupted; run the command again",
}
#: MP4 frames are padded to a multiple of this many pixels (what most players expect).
MP4_BLOCK = 16
#: The last byte of every complete GIF file.
GIF_TRAILER = b"\x3b"


def _command(path: Path, size: tuple[int, int], fps: float, gif: bool) -> list[str]:
    """The ffmpeg command line reading raw ``rgb24`` frames on stdin and writing ``path``."""
    import imageio_ffmpeg  # noqa: PLC0415 (heavy: imageio_ffmpeg)

    width, height = size
    rate = str(Fraction(fps).limit_denominator())
    cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-nostdin", "-v", "error", "-f", "rawvideo",
           "-vcodec", "rawvideo", "-s", f"{width}x{height}", "-pix_fmt", "rgb24", "-r", rate,
           "-i", "-", "-an"]
    if gif:
        palette = "split[a][b];[a]palettegen=max_colors=64:stats_mode=full[p];[b][p]paletteuse"
        cmd += ["-vcodec", "gif", "-pix_fmt", "pal8", "-filter_complex", palette]
    else:
        cmd += ["-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", "15"]
        padded = [-(-n // MP4_BLOCK) * MP4_BLOCK for n in size]
        if padded != [width, height]:
            cmd += ["-vf", f"scale={padded[0]}:{padded[1]}"]
    return [*cmd, "-f", "gif" if gif else "mp4", str(path)]


class VideoEncoder:
    """A context manager that encodes the frames sent to it into ``path``.

    Use as ``with VideoEncoder(tmp, (w, h), fps, gif=True, name=out) as video: video.send(rgb)``;
    leaving the block without an exception finishes the file and checks it.

    Args:
        path: the file ffmpeg writes (a temporary name of :func:`~emotive.io.atomic.atomic_output`).
        size: ``(width, height)`` in pixels of every frame.
        fps: frames per second.
        gif: GIF (else MP4).
        name: the file to name in messages (the destination), default ``path``.

    Raises:
        OutputError: ffmpeg cannot write the file (full disk, no permission), stopped early, or
            left an incomplete file.
    """

    def __init__(self, path: Path, size: tuple[int, int], fps: float, *, gif: bool,
                 name: Path | None = None) -> None:
        self.path = Path(path)
        self.name = Path(name) if name is not None else self.path
        self.gif = gif
        self._frame_bytes = size[0] * size[1] * 3
        self._log = tempfile.TemporaryFile()
        self._process = subprocess.Popen(_command(self.path, size, fps, gif),
                                         stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                         stderr=self._log)
        self._frames = 0

    def __enter__(self) -> VideoEncoder:
        return self

    def send(self, rgb: bytes) -> None:
        """Encode one frame of ``height * width * 3`` bytes (rows top to bottom, RGB)."""
        if len(rgb) != self._frame_bytes:
            raise ValueError(f"a frame holds {len(rgb)} bytes, expected {self._frame_bytes}")
        try:
            self._process.stdin.write(rgb)
        except (BrokenPipeError, OSError):
            # ffmpeg stopped (its own error is in the log): report that instead.
            self._process.wait()
            raise self._failure() from None
        self._frames += 1

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if kind is not None:
                self._process.kill()
                self._process.wait()
                return
            try:
                self._process.stdin.close()
            except OSError:
                pass
            if self._process.wait() != 0:
                raise self._failure()
            self._check_file()
        finally:
            if self._process.stdin and not self._process.stdin.closed:
                self._process.stdin.close()
            self._log.close()

    def _check_file(self) -> None:
        """Raise unless ffmpeg left a plausible, complete file."""
        if self._frames == 0:
            raise OutputError(f"cannot write {self.name}: no frames were drawn")
        try:
            with open(self.path, "rb") as fh:
                fh.seek(0, os.SEEK_END)
                size = fh.tell()
                if size:
                    fh.seek(-1, os.SEEK_END)
                last = fh.read(1)
        except OSError as exc:
            raise output_error(self.name, exc) from exc
        if size == 0 or (self.gif and last != GIF_TRAILER):
            raise OutputError(f"cannot write {self.name}: the video encoder left an incomplete "
                              "file (a full disk?); free space or choose another folder")

    def _failure(self) -> OutputError:
        """The error of a failed ffmpeg, from the last line it logged."""
        self._log.seek(0)
        lines = [line.strip() for line in
                 self._log.read().decode("utf-8", "replace").splitlines() if line.strip()]
        for words, code in _FFMPEG_ERRNO.items():
            if any(words in line for line in lines):
                return output_error(self.name, OSError(code, words))
        status = self._process.returncode
        if status is not None and status < 0:
            return OutputError(f"cannot write {self.name}: the video encoder (ffmpeg) "
                               f"{killed_by(-status)}")
        why = lines[-1] if lines else f"exit status {status}"
        return OutputError(f"cannot write {self.name}: the video encoder (ffmpeg) failed: {why}; "
                           "check the folder and the free space, or choose another folder")


def killed_by(number: int) -> str:
    """Why a process ended by signal ``number``, and the fix, in words.

    E.g. ``"was stopped by the file-size limit (SIGXFSZ): ..."`` for 25 on Linux, the signal a
    process gets when it writes past ``ulimit -f`` (its exit status reads ``-25``).

    Args:
        number: the signal (minus a negative :attr:`subprocess.Popen.returncode`).
    """
    try:
        name = signal.Signals(number).name
    except ValueError:
        return (f"was stopped by signal {number}; run the command again, or check the ffmpeg "
                "of imageio-ffmpeg")
    hint = _SIGNAL_HINTS.get(name, "run the command again, or check the ffmpeg of "
                             "imageio-ffmpeg")
    if name == "SIGXFSZ":
        return f"was stopped by the file-size limit ({name}): {hint}"
    return f"was stopped by signal {name} ({signal.strsignal(number)}); {hint}"
