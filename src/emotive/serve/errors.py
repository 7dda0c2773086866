"""Typed errors of the live server: start-up errors and bad control messages."""

from __future__ import annotations

from typing import Any

from emotive.errors import EmotiveError

#: A message's ``ref`` when it had none (or it could not be read).
NO_REF: Any = type("NoRef", (), {"__repr__": lambda self: "NO_REF"})()


class ServeError(EmotiveError):
    """A server that cannot start as asked: a bad bind address, port, limit or option."""


class MessageError(EmotiveError):
    """A control message that cannot be applied; its text is the ``error`` reply's message.

    Args:
        message: what is wrong and how to fix it.
        ref: the message's ``ref`` when it could be read despite the problem (e.g. a message
            holding ``NaN``), else :data:`NO_REF`.
    """

    def __init__(self, message: str, ref: Any = NO_REF) -> None:
        super().__init__(message)
        self.ref = ref
