"""Simulated output faults for the tests: a full disk and a folder that refuses new files.

Both work through :func:`emotive.io.atomic.mkstemp`, which makes every temporary output file
(and the up-front writability probe of :func:`emotive.io.outputs.check_output`).

* :func:`fill_disk`: each temporary file is a symbolic link to ``/dev/full``, so every write to
  it, from Python or from a subprocess such as ffmpeg, fails in the kernel with ``ENOSPC``, as on
  a full disk (where creating an empty file still works). Reliable as ``root`` too, unlike a
  ``chmod``.
* :func:`refuse_files`: creating a file fails with the given errno (``EROFS``, ``EACCES``,
  ``EPERM``), as in a read-only, forbidden or immutable folder; ``root`` ignores a ``chmod``,
  so this is simulated.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import emotive.io.atomic as atomic

FULL = Path("/dev/full")


def fill_disk(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make every output written through :mod:`emotive.io.atomic` meet a full disk."""
    if not FULL.exists():
        pytest.skip("needs /dev/full (Linux)")

    def mkstemp(suffix: str = "", prefix: str = "tmp", dir: str | os.PathLike = ".") -> tuple:
        for n in range(1000):
            name = os.path.join(dir, f"{prefix}full{n}{suffix}")
            if not os.path.lexists(name):
                os.symlink(FULL, name)
                return os.open(name, os.O_WRONLY), name
        raise FileExistsError(name)

    monkeypatch.setattr(atomic, "mkstemp", mkstemp)


def refuse_files(monkeypatch: pytest.MonkeyPatch, code: int) -> None:
    """Make creating any output file fail with ``OSError(code)``."""

    def mkstemp(suffix: str = "", prefix: str = "tmp", dir: str | os.PathLike = ".") -> tuple:
        raise OSError(code, os.strerror(code), os.path.join(dir, f"{prefix}{suffix}"))

    monkeypatch.setattr(atomic, "mkstemp", mkstemp)
