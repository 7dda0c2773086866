"""Core types: :class:`Skeleton` and :class:`Motion`, joint roles and motion operations."""

from emotive.core.motion import Motion
from emotive.core.skeleton import Skeleton

__all__ = ["Motion", "Skeleton"]
