"""Saving model configs in checkpoints: a frozen dataclass to and from a JSON-safe dict."""

from __future__ import annotations

import json
from dataclasses import asdict, fields
from typing import Any, Self


class DictConfig:
    """Mixin of a frozen dataclass config: :meth:`to_dict`/:meth:`from_dict` (tuples stored as
    lists) and their JSON texts; a checkpoint holds ``config.to_dict()``."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe dict of every field (tuples as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        """The config saved by :meth:`to_dict`.

        Raises:
            ValueError: a key that is not a field (a checkpoint of another model or version).
        """
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ValueError(f"unknown {cls.__name__} fields {unknown}; known: {sorted(known)}")
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})

    def to_json(self) -> str:
        """The config as a JSON text."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> Self:
        """The config from :meth:`to_json` text."""
        return cls.from_dict(json.loads(text))
