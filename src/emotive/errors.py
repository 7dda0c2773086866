"""Typed errors a user can hit. Each message names the input and how to fix it."""

from __future__ import annotations

from pathlib import Path


class EmotiveError(Exception):
    """Base class of every error the toolkit raises on bad user input."""


class BVHError(EmotiveError):
    """A BVH file that cannot be read.

    Args:
        path: the file.
        line: 1-based line number of the problem, or ``None`` when it concerns the whole file.
        problem: what is wrong, phrased so the user can fix it.
    """

    def __init__(self, path: str | Path, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


class RigError(EmotiveError):
    """A skeleton that lacks joints or roles a feature or model needs."""


class DataError(EmotiveError):
    """A data set that is missing, corrupt or cannot be fetched."""


class ChecksumError(DataError):
    """An archive whose sha256 differs from the registry's."""


class EmotionError(EmotiveError):
    """An emotion name, weight vector or schedule that is not valid."""


class PathError(EmotiveError):
    """A path that cannot be followed: too few or repeated points, zero length, bad file."""


class OutputError(EmotiveError):
    """An output file that cannot be written: unknown suffix or missing folder."""


class ConfigError(EmotiveError):
    """A config file or checkpoint that is missing or holds a bad key or value."""


class MotionFileError(EmotiveError):
    """A glTF or FBX motion file that cannot be read (BVH files raise :class:`BVHError`).

    Args:
        path: the file.
        problem: what is wrong, phrased so the user can fix it.
    """

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")
