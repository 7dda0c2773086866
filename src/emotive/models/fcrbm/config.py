"""Sizes and training settings of the FCRBM (:mod:`emotive.models.fcrbm.model`).

Legend: ``D`` visible units, ``C`` context size, ``N`` order (past frames), ``H`` hidden units.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

from emotive.models.checkpoint_checks import SEED_RANGE, WIDTH_RANGE, Range, check_fields

__all__ = ["CONTEXT_FEATURES", "RANGES", "FCRBMConfig"]

#: Gating features of the context (:attr:`FCRBMConfig.context_features`).
CONTEXT_FEATURES = ("linear", "rbf")
#: Plausible values of the numeric fields, checked with their types by
#: :func:`~emotive.models.checkpoint_checks.check_fields` (a TOML file's or a checkpoint's).
RANGES: dict[str, Range] = {
    **dict.fromkeys(("visible", "hidden", "factors", "factors_past_visible",
                     "factors_past_hidden"), WIDTH_RANGE),
    "context": Range(1, 64), "order": Range(1, 1000), "cd_steps": Range(1, 1000),
    "gibbs": Range(1, 10000), "learning_rate": Range(0, 10, above=True),
    "weight_decay": Range(0, 10), "init_std": Range(0, 10, above=True),
    "rbf_width": Range(0, 10, above=True), "seed": SEED_RANGE,
}


@dataclass(frozen=True)
class FCRBMConfig:
    """Sizes and training settings of an :class:`~emotive.models.fcrbm.model.FCRBM`.

    The defaults are the paper's model.

    Attributes:
        visible: ``D``, values per frame (paper 52).
        context: ``C``, context size (2: valence and arousal).
        order: ``N``, past frames the model is conditioned on (paper 6).
        hidden: ``H``, binary hidden units (paper 400).
        factors: factors of the visible-hidden-context interaction (paper 300).
        factors_past_visible: factors of the past-to-visible interaction (paper 300).
        factors_past_hidden: factors of the past-to-hidden interaction (paper 300).
        learning_rate: step size of the CD updates.
        momentum: momentum of the CD updates.
        weight_decay: L2 penalty on the weights (biases are not decayed).
        cd_steps: ``k`` of CD-k.
        gibbs: alternating Gibbs iterations per generated frame.
        init_std: standard deviation of the initial weights.
        seed: seed of the initial weights and of the default sampling generator.
        visible_autoregression: keep the past-to-visible interaction (the paper's model);
            ``False`` leaves it out (see :mod:`emotive.models.fcrbm.model`).
        context_features: what gates the factors: ``"linear"``, the context itself (the
            paper's model), or ``"rbf"`` (valence/arousal only, ``C = 2``), the context
            followed by :data:`~emotive.models.fcrbm.model.RBF_CENTRES` Gaussian bumps (see
            :meth:`~emotive.models.fcrbm.model.FCRBM.features`).
        rbf_width: standard deviation of those bumps, in valence/arousal units.
    """

    visible: int
    context: int = 2
    order: int = 6
    hidden: int = 400
    factors: int = 300
    factors_past_visible: int = 300
    factors_past_hidden: int = 300
    learning_rate: float = 1e-3
    momentum: float = 0.9
    weight_decay: float = 2e-4
    cd_steps: int = 1
    gibbs: int = 30
    init_std: float = 0.01
    seed: int = 0
    visible_autoregression: bool = True
    context_features: str = "linear"
    rbf_width: float = 0.5

    def __post_init__(self) -> None:
        check_fields(self)
        sizes = (
            "visible", "context", "order", "hidden", "factors",
            "factors_past_visible", "factors_past_hidden", "cd_steps", "gibbs",
        )  # fmt: skip
        for name in sizes:
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"FCRBMConfig.{name} must be a positive integer, got {value!r}")
        for name in ("learning_rate", "init_std", "rbf_width"):
            if not getattr(self, name) > 0:
                raise ValueError(f"FCRBMConfig.{name} must be > 0, got {getattr(self, name)!r}")
        if not 0 <= self.momentum < 1:
            raise ValueError(f"FCRBMConfig.momentum must be in [0, 1), got {self.momentum!r}")
        if not isinstance(self.visible_autoregression, bool):
            raise ValueError(f"FCRBMConfig.visible_autoregression must be true or false, got "
                             f"{self.visible_autoregression!r}")
        if self.context_features not in CONTEXT_FEATURES:
            raise ValueError(f"FCRBMConfig.context_features must be one of {CONTEXT_FEATURES}, "
                             f"got {self.context_features!r}")
        if self.context_features == "rbf" and self.context != 2:
            raise ValueError("FCRBMConfig.context_features 'rbf' needs context = 2 (valence, "
                             f"arousal), got {self.context}")
        if not self.weight_decay >= 0:
            raise ValueError(f"FCRBMConfig.weight_decay must be >= 0, got {self.weight_decay!r}")
        check_fields(self, RANGES)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready dictionary of every field."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FCRBMConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise ``ValueError`` (typos fail loudly)."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ValueError(f"unknown FCRBMConfig keys: {unknown}")
        return cls(**data)
