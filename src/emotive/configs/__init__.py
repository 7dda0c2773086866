"""The shipped training recipes: one TOML file per trained model, installed with the package.

``emotive train gait`` without ``--config`` trains from ``gait.toml`` here; ``--config
gait-finetune`` names another shipped recipe; any other value is a path to the user's own
TOML file. A recipe's relative paths (``init_from``) are read from the recipe's own folder,
so the shipped fine-tuning recipe finds the shipped first stage from any working folder.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from emotive.errors import ConfigError


def recipe_names() -> list[str]:
    """Names of the shipped recipes (``gait``, ``gait-finetune``, ``classifier``, ...), sorted."""
    return sorted(Path(entry.name).stem for entry in resources.files(__name__).iterdir()
                  if entry.name.endswith(".toml"))


def recipe_path(name: str) -> Path:
    """The installed file of the shipped recipe ``name`` (without ``.toml``).

    Raises:
        ConfigError: no shipped recipe has that name; the message lists them.
    """
    if name not in recipe_names():
        raise ConfigError(f"no shipped recipe named {name!r}: use one of "
                          f"{', '.join(recipe_names())}, or give a path to a TOML file")
    return Path(str(resources.files(__name__) / f"{name}.toml"))


def resolve_config(value: str | Path) -> Path:
    """A ``--config`` value as a file: an existing path as given, else a shipped recipe's name.

    Args:
        value: a path to a TOML file, or the name of a shipped recipe (see
            :func:`recipe_names`).

    Raises:
        ConfigError: ``value`` is neither an existing file nor a recipe name; the message
            names both ways.
    """
    path = Path(value)
    if path.exists() or path.suffix == ".toml" or len(path.parts) > 1:
        return path
    if str(value) in recipe_names():
        return recipe_path(str(value))
    raise ConfigError(f"--config {value}: no such file and no shipped recipe of that name: "
                      f"give a TOML file or one of {', '.join(recipe_names())}")
