"""The recipe of a synthetic data set, and which walk each sample index is.

The main paper's augmented data set (Bhattacharya et al. 2020, section 5.2, "Synthesized
Emotive Gaits") is gaits on ``P`` trajectories not in the data with ``E`` emotions not in the
data on each (``P x E`` walks), plus transitions between ``K`` pairs of those emotions on each
trajectory, the pairs drawn from the ``E`` without replacement (``P x K`` more). The paper's
numbers are ``P = 20``, ``E = 100``, ``K = 50``: 2,000 + 1,000 = 3,000 walks (the paper's text
says 5,000 in all; its recipe gives 3,000).

A :class:`Recipe` holds every choice that changes the data set; :meth:`Recipe.to_dict` (with
the ranges the trajectories and emotions are drawn from, the model's weights and the rig) is
what a folder is made with, and :meth:`Recipe.recipe_id` names it.

Sample layout. Sample ``i`` of ``N = P E + P K``:

* ``i < P E``: a walk of constant emotion, trajectory ``i // E``, emotion ``i % E``;
* ``i >= P E``: with ``j = i - P E``, a transition on trajectory ``j // K``, pair ``j % K``.

Shards are the fixed index ranges ``[s S, (s + 1) S)`` of :attr:`Recipe.shard_size` ``S``:
independent of how many workers or nodes make them, so that the batch every walk is stepped
in, and so every byte of the data set, depends on the recipe alone.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from emotive.errors import EmotiveError

#: Version of the folder layout and of the sample layout above.
LAYOUT_VERSION = 1
#: Extra per-walk files ``--formats`` can ask for beside the shards (``npz``: shards only).
FORMATS = ("npz", "bvh", "glb")
#: Bounds of a recipe's numbers: ``(low, high)``, inclusive.
PATHS_RANGE = (1, 100_000)
EMOTIONS_RANGE = (1, 100_000)
SECONDS_RANGE = (1.0, 600.0)
SHARD_SIZE_RANGE = (1, 2_000)
SEED_MAX = 2**32 - 1
#: The paper's recipe (section 5.2).
PAPER_PATHS, PAPER_EMOTIONS, PAPER_TRANSITIONS, PAPER_SECONDS = 20, 100, 50, 10.0
#: Walks stepped in one batch by one task.
DEFAULT_SHARD_SIZE = 100
#: Recipes chosen by name (``emotive synth --recipe NAME``), their counts and walk length:
#: the paper's 3,000 walks, and 8 short ones to try the command (2 x 3 + 2 x 1, 4 s each).
RECIPES: dict[str, dict[str, Any]] = {
    "paper": {"paths": PAPER_PATHS, "emotions": PAPER_EMOTIONS,
              "transitions": PAPER_TRANSITIONS, "seconds": PAPER_SECONDS},
    "small": {"paths": 2, "emotions": 3, "transitions": 1, "seconds": 4.0},
}


class SynthError(EmotiveError):
    """A synthetic data set that cannot be made as asked: a bad recipe, folder or cluster."""


@dataclass(frozen=True)
class Recipe:
    """Everything that decides the walks of a synthetic data set (section 5.2).

    Attributes:
        paths: trajectories ``P``.
        emotions: emotions ``E`` walked on every trajectory.
        transitions: pairs ``K`` of those emotions walked as a transition on every trajectory
            (disjoint pairs, so ``2 K <= E``).
        seconds: length of every walk, seconds.
        seed: the seed every random choice is drawn from, with the sample index.
        model: generator of :mod:`emotive.models.registry` (``gait``, ``fcrbm``, ``lgb``, ...).
        shard_size: walks per shard (and per batched generator call).
        formats: files written: ``npz`` (the shards, always), ``bvh`` and ``glb`` (one file per
            walk beside them).
        rig: identity of the ``--rig`` file (``{"name", "sha256"}``), or ``None`` for the
            model's own rig.
        rig_roles: role map of the rig (see :func:`emotive.core.roles.resolve_roles`).
    """

    paths: int = PAPER_PATHS
    emotions: int = PAPER_EMOTIONS
    transitions: int = PAPER_TRANSITIONS
    seconds: float = PAPER_SECONDS
    seed: int = 0
    model: str = "gait"
    shard_size: int = DEFAULT_SHARD_SIZE
    formats: tuple[str, ...] = ("npz",)
    rig: dict[str, str] | None = None
    rig_roles: str | None = None

    def __post_init__(self) -> None:
        _whole(self.paths, "--paths", PATHS_RANGE, "the number of trajectories")
        _whole(self.emotions, "--emotions", EMOTIONS_RANGE, "the number of emotions")
        _whole(self.transitions, "--transitions", (0, EMOTIONS_RANGE[1]),
               "the number of transition pairs per trajectory")
        _whole(self.shard_size, "--shard-size", SHARD_SIZE_RANGE, "walks per shard")
        _whole(self.seed, "--seed", (0, SEED_MAX), "the seed")
        if 2 * self.transitions > self.emotions:
            raise SynthError(
                f"--transitions {self.transitions}: {self.emotions} emotions make at most "
                f"{self.emotions // 2} disjoint pairs (drawn without replacement); give "
                f"--transitions {self.emotions // 2} or fewer, or more --emotions")
        s = self.seconds
        if isinstance(s, bool) or not isinstance(s, int | float) or not (
                math.isfinite(s) and SECONDS_RANGE[0] <= s <= SECONDS_RANGE[1]):
            raise SynthError(f"--seconds {s!r}: give a walk length from {SECONDS_RANGE[0]:g} to "
                             f"{SECONDS_RANGE[1]:g} seconds (the classifier needs a stride)")
        object.__setattr__(self, "seconds", float(s))
        object.__setattr__(self, "formats", check_formats(self.formats))

    @property
    def constant_walks(self) -> int:
        """Walks of one emotion: ``P E``."""
        return self.paths * self.emotions

    @property
    def transition_walks(self) -> int:
        """Transition walks: ``P K``."""
        return self.paths * self.transitions

    @property
    def total(self) -> int:
        """All walks, ``N``."""
        return self.constant_walks + self.transition_walks

    @property
    def shards(self) -> int:
        """Number of shards."""
        return -(-self.total // self.shard_size)

    def shard_range(self, shard: int) -> range:
        """The sample indices of ``shard``.

        Raises:
            IndexError: no such shard.
        """
        if not 0 <= shard < self.shards:
            raise IndexError(f"shard {shard} of {self.shards}")
        return range(shard * self.shard_size, min((shard + 1) * self.shard_size, self.total))

    def sample(self, index: int) -> SampleSpec:
        """Which walk sample ``index`` is (the layout of the module docstring).

        Raises:
            IndexError: ``index`` outside ``[0, N)``.
        """
        if not 0 <= index < self.total:
            raise IndexError(f"sample {index} of {self.total}")
        if index < self.constant_walks:
            return SampleSpec(index, index // self.emotions, index % self.emotions, None)
        j = index - self.constant_walks
        return SampleSpec(index, j // self.transitions, None, j % self.transitions)

    def to_dict(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """The recipe as JSON-able values, with ``extra`` entries (ranges, weights) merged in."""
        out = {
            "layout": LAYOUT_VERSION, "paths": self.paths, "emotions": self.emotions,
            "transitions": self.transitions, "seconds": self.seconds, "seed": self.seed,
            "model": self.model, "shard_size": self.shard_size, "formats": list(self.formats),
            "rig": self.rig, "rig_roles": self.rig_roles,
        }
        return {**out, **(extra or {})}

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Recipe:
        """The recipe of :meth:`to_dict`'s output (extra entries are ignored)."""
        return cls(
            paths=values["paths"], emotions=values["emotions"],
            transitions=values["transitions"], seconds=values["seconds"], seed=values["seed"],
            model=values["model"], shard_size=values["shard_size"],
            formats=tuple(values["formats"]), rig=values.get("rig"),
            rig_roles=values.get("rig_roles"),
        )


def named_recipe(name: str, **changes: Any) -> Recipe:
    """The recipe ``name`` of :data:`RECIPES` with ``changes`` (those not ``None``) applied.

    Raises:
        SynthError: no recipe has that name, or a change is out of range.
    """
    if name not in RECIPES:
        raise SynthError(f"--recipe {name}: no such recipe; give one of {', '.join(RECIPES)}")
    given = {key: value for key, value in changes.items() if value is not None}
    return Recipe(**{**RECIPES[name], **given})


@dataclass(frozen=True)
class SampleSpec:
    """One sample of the layout.

    Attributes:
        index: the sample index.
        path: trajectory index.
        emotion: emotion index of a constant walk, ``None`` for a transition.
        pair: pair index of a transition, ``None`` for a constant walk.
    """

    index: int
    path: int
    emotion: int | None
    pair: int | None

    @property
    def is_transition(self) -> bool:
        """Whether the walk changes emotion."""
        return self.pair is not None


def recipe_id(values: dict[str, Any]) -> str:
    """16 hex digits naming a recipe dictionary (sha256 of its canonical JSON)."""
    text = json.dumps(values, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def check_formats(formats: str | Sequence[str]) -> tuple[str, ...]:
    """``formats`` (``"npz,bvh"`` or a sequence) checked, in :data:`FORMATS` order, ``npz`` first.

    Raises:
        SynthError: an unknown format.
    """
    items = formats.split(",") if isinstance(formats, str) else list(formats)
    names = {str(f).strip().lower().lstrip(".") for f in items if str(f).strip()}
    unknown = sorted(names - set(FORMATS))
    if unknown:
        raise SynthError(f"--formats {','.join(map(str, items))}: unknown {', '.join(unknown)}; "
                         f"give a comma-separated list of {', '.join(FORMATS)}")
    return tuple(f for f in FORMATS if f in names | {"npz"})


def _whole(value: Any, flag: str, bounds: tuple[int, int], what: str) -> None:
    """Raise :class:`SynthError` unless ``value`` is a whole number within ``bounds``."""
    if isinstance(value, bool) or not isinstance(value, int) or not (
            bounds[0] <= value <= bounds[1]):
        raise SynthError(f"{flag} {value!r}: {what} must be a whole number from {bounds[0]} "
                         f"to {bounds[1]:,}")
