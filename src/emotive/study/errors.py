"""Typed errors of the perceptual-study kit; each message names the input and the fix."""

from __future__ import annotations

from emotive.errors import ConfigError, EmotiveError


class StudyError(EmotiveError):
    """A study folder, database or server setting that cannot be used as given."""


class StudyConfigError(StudyError, ConfigError):
    """A ``study.toml`` with a missing or bad key or value."""


class ServerUnavailable(StudyError):
    """The study server did not answer, or could not store, within the simulation's deadline."""
