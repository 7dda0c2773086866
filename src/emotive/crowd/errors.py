"""Typed errors of crowds: a scene that cannot be run as written."""

from __future__ import annotations

from emotive.errors import EmotiveError


class SceneError(EmotiveError):
    """A scene file or value that is not valid; the message names the key or group and the fix.

    Args:
        where: the part of the scene at fault (``scene.toml: group 'east' spawn``).
        problem: what is wrong and how to fix it, in one line.
    """

    def __init__(self, where: str, problem: str) -> None:
        self.where = where
        self.problem = problem
        super().__init__(f"{where}: {problem}")


class CrowdError(EmotiveError):
    """A crowd request that cannot be applied (an unknown agent, a missing extra)."""
