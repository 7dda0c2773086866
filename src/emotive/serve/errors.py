"""Typed errors of the live server: start-up errors and bad control messages."""

from __future__ import annotations

from emotive.errors import EmotiveError


class ServeError(EmotiveError):
    """A server that cannot start as asked: a bad bind address, port, limit or option."""


class MessageError(EmotiveError):
    """A control message that cannot be applied; its text is the ``error`` reply's message."""
