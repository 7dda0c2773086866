"""Every model of the toolkit by name: what it is, what it ships with, and how to load it.

Each :class:`ModelEntry` names its kinds (:data:`KINDS`) and, per kind, a loader given as a
``"module:function"`` string that is imported only when the model is loaded, so reading the
registry (``emotive models``, ``emotive evaluate --help``) imports no model package and no
torch. A loader is called as ``loader(name=entry.name, weights=weights, **options)`` and returns
an object satisfying the protocol of its kind (:mod:`emotive.models.api`):

* ``generator``: :class:`~emotive.models.api.Generator`;
* ``predictor``: :class:`~emotive.models.api.Predictor`;
* ``transfer``: :class:`~emotive.models.api.TransferModel`;
* ``classifier``: :class:`emotive.eval.classifier.EmotionClassifier` (the perceived-emotion
  judge of the evaluation suites).

Example::

    from emotive.models.registry import get_model

    fcrbm = get_model("fcrbm").load("generator", gibbs=20)
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from emotive.errors import EmotiveError

__all__ = [
    "KINDS",
    "REGISTRY",
    "ModelEntry",
    "ModelError",
    "ModelOption",
    "get_model",
    "model_names",
]

#: What a model can be loaded as.
KINDS: tuple[str, ...] = ("generator", "predictor", "transfer", "classifier")


class ModelError(EmotiveError):
    """An unknown model, kind or option, or weights given to a model that has none."""


@dataclass(frozen=True)
class ModelOption:
    """A model-specific option that the CLI passes through to the loader.

    Attributes:
        name: the Python keyword, e.g. ``"gibbs"`` (command-line flag ``--gibbs``).
        help: one line for ``--help`` and ``emotive models``.
    """

    name: str
    help: str


@dataclass(frozen=True)
class ModelEntry:
    """One registered model.

    Attributes:
        name: registry name, e.g. ``"gait"``.
        kinds: what it can be loaded as, a subset of :data:`KINDS`.
        summary: one line.
        paper: short citation.
        weights: what ships by default (asset path, ``"built on first use ..."`` or
            ``"none: ..."`` for a model without weights).
        loaders: kind -> ``"module:function"``.
        options: model-specific options its loaders take.
        card: package-relative path of its model card, or ``None``.
    """

    name: str
    kinds: tuple[str, ...]
    summary: str
    paper: str
    weights: str
    loaders: dict[str, str]
    options: tuple[ModelOption, ...] = ()
    card: str | None = None
    #: Whether a weights file can be given (``False`` for models without weights).
    takes_weights: bool = field(default=True)

    def __post_init__(self) -> None:
        unknown = [k for k in self.kinds if k not in KINDS]
        if unknown or set(self.kinds) != set(self.loaders):
            raise ValueError(f"model {self.name!r}: kinds {self.kinds} must be among {KINDS} "
                             f"and match the loaders {sorted(self.loaders)}")

    @property
    def option_names(self) -> tuple[str, ...]:
        """Names of :attr:`options`."""
        return tuple(o.name for o in self.options)

    def loader(self, kind: str) -> Callable[..., Any]:
        """The loader function of ``kind``, imported now (the model is not built).

        Raises:
            ModelError: a kind this model lacks, or a loader that cannot be imported.
        """
        if kind not in self.loaders:
            raise ModelError(f"model {self.name!r} is no {kind}: it can be loaded as "
                             f"{', '.join(self.kinds)}")
        module_name, _, function = self.loaders[kind].partition(":")
        try:
            module = importlib.import_module(module_name)
            return getattr(module, function)
        except (ImportError, AttributeError) as exc:
            raise ModelError(f"model {self.name!r}: its {kind} loader {self.loaders[kind]!r} "
                             f"cannot be imported ({exc}); reinstall emotive") from None

    def load(self, kind: str, weights: str | Path | None = None, **options: Any) -> Any:
        """The model as ``kind``.

        Args:
            kind: one of :attr:`kinds`.
            weights: a checkpoint file (gait, quaternet, fcrbm, classifier) or an index file
                (mar) instead of the default; ``None`` for the default.
            **options: model-specific options (:attr:`options`); those given as ``None`` are
                ignored, so a caller may pass every option it knows.

        Returns:
            An object satisfying the protocol of ``kind`` (see the module docstring).

        Raises:
            ModelError: an option (not ``None``) this model does not take, weights for a
                model without weights, or a kind this model lacks.
        """
        given = {k: v for k, v in options.items() if v is not None}
        unknown = sorted(set(given) - set(self.option_names))
        if unknown:
            takes = (f"it takes {', '.join(self.option_names)}" if self.options
                     else "it takes no options")
            raise ModelError(f"model {self.name!r} has no option {', '.join(unknown)}: {takes}")
        if weights is not None and not self.takes_weights:
            raise ModelError(f"model {self.name!r} has no weights to replace ({self.weights}): "
                             f"leave out the weights {str(weights)!r}")
        return self.loader(kind)(name=self.name, weights=weights, **given)


_GAIT_PAPER = ("Bhattacharya et al. 2020, Generating Emotive Gaits for Virtual Agents Using "
               "Affect-Based Autoregression (ISMAR)")
_GAIT_LOADERS = {"generator": "emotive.models.gait.adapter:load_generator",
                 "predictor": "emotive.models.gait.adapter:load_predictor"}
_GAIT_CARD = "assets/gait/MODEL_CARD.md"
_GAIT_OPTIONS = (
    ModelOption("raw", "Stream the network's poses without the causal foot lock (planted "
                "feet held by two-bone IK in every step)."),
)

_ENTRIES = (
    ModelEntry(
        "gait", ("generator", "predictor"),
        "Emotive gaits along a ground path by affect-based autoregression (blends, schedules).",
        _GAIT_PAPER, "assets/gait/emotive-gait.pt", _GAIT_LOADERS, _GAIT_OPTIONS,
        card=_GAIT_CARD,
    ),
    ModelEntry(
        "gait-no-affective", ("generator", "predictor"),
        "Ablation of the gait network trained without the affective-feature loss.",
        _GAIT_PAPER, "assets/gait/gait-no-affective.pt", _GAIT_LOADERS, _GAIT_OPTIONS,
        card=_GAIT_CARD,
    ),
    ModelEntry(
        "gait-no-root-loss", ("generator", "predictor"),
        "Ablation of the gait network trained without the root-trajectory loss.",
        _GAIT_PAPER, "assets/gait/gait-no-root-loss.pt", _GAIT_LOADERS, _GAIT_OPTIONS,
        card=_GAIT_CARD,
    ),
    ModelEntry(
        "quaternet", ("predictor",),
        "The QuaterNet baseline of Table 1: quaternion RNN predicting the next poses.",
        "Pavllo et al. 2018, QuaterNet: A Quaternion-based Recurrent Model for Human Motion "
        "(BMVC)",
        "assets/gait/quaternet.pt",
        {"predictor": "emotive.models.gait.quaternet.adapter:load_predictor"}, card=_GAIT_CARD,
    ),
    ModelEntry(
        "fcrbm", ("generator",),
        "Movement for a valence/arousal point or schedule from a factored conditional RBM.",
        "Alemi et al. 2015, Affect-expressive movement generation with factored conditional "
        "Restricted Boltzmann Machines (ACII)",
        "assets/fcrbm/fcrbm.pt",
        {"generator": "emotive.models.fcrbm.adapter:load_generator"},
        options=(
            ModelOption("gibbs", "Gibbs iterations per frame (default: the model's)."),
            ModelOption("root", "Root path: 'feet' rebuilds it from the stance foot (default), "
                                "'model' keeps the model's own root velocity."),
        ),
        card="assets/fcrbm/MODEL_CARD.md",
    ),
    ModelEntry(
        "lgb", ("generator",),
        "New whole-body motion of one emotion by Local Grid Bootstrap of end-effector "
        "trajectories, rebuilt by inverse kinematics.",
        "Carreno-Medrano et al. 2019, Perceptual validation for the generation of expressive "
        "movements from end-effector trajectories (ACM TiiS)",
        "none: fitted on each use from the data set's clips of the emotion",
        {"generator": "emotive.models.lgb.adapter:load_generator"},
        options=(
            ModelOption("workers", "Worker processes for the inverse kinematics (default: the "
                                   "idle cores, at most 2); the result does not depend on it."),
            ModelOption("dataset", "Data set whose clips are resampled (default "
                                   "bandai-namco-1)."),
            ModelOption("fps", "Frame rate of the output (default: the data's, 30)."),
        ),
        takes_weights=False,
    ),
    ModelEntry(
        "mar", ("transfer",),
        "Realtime style transfer of any clip by online local mixtures of autoregressive "
        "models.",
        "Xia et al. 2015, Realtime style transfer for unlabeled heterogeneous human motion "
        "(SIGGRAPH)",
        "built on first use from the Bandai Namco data into $EMOTIVE_HOME/mar/",
        {"transfer": "emotive.models.mar.adapter:load_transfer"},
        options=(
            ModelOption("index", "Index file (default: in $EMOTIVE_HOME/mar, built on first "
                                 "use)."),
            ModelOption("rho", "Content kept for inputs unlike the data: 0 (pure style) to 1; "
                               "default 0.7."),
            ModelOption("input_style", "The input's style if known (neutral, ...)."),
            ModelOption("action", "The input's action if known (walk, run, ...)."),
            ModelOption("roles", "Role map of the input rig: a family name (bandai, cmu, mixamo, "
                        "unreal, unity, vrm, smpl, smplx) or a JSON file; default: detected."),
        ),
    ),
    ModelEntry(
        "zero-velocity", ("predictor",),
        "Baseline predictor that holds the last observed frame (the lower bar of Table 1).",
        "standard motion-prediction baseline (Martinez et al. 2017)",
        "none: it has no parameters",
        {"predictor": "emotive.eval.evaluate:load_zero_velocity"},
        takes_weights=False,
    ),
    ModelEntry(
        "classifier", ("classifier",),
        "Perceived-emotion classifier of windows of motion: the judge of the evaluation "
        "suites.",
        "this toolkit (see its model card)",
        "assets/classifier/emotion-classifier.pt",
        {"classifier": "emotive.eval.evaluate:load_classifier"},
        card="assets/classifier/MODEL_CARD.md",
    ),
)

#: Every registered model by name.
REGISTRY: dict[str, ModelEntry] = {entry.name: entry for entry in _ENTRIES}


def get_model(name: str) -> ModelEntry:
    """The registry entry of ``name``.

    Raises:
        ModelError: an unknown name, with the closest name and the list of models.
    """
    if name in REGISTRY:
        return REGISTRY[name]
    close = difflib.get_close_matches(name, list(REGISTRY), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise ModelError(f"unknown model {name!r}{hint}: use one of {', '.join(REGISTRY)} "
                     "(see `emotive models`)")


def model_names(kind: str | None = None) -> list[str]:
    """Registered model names, in registry order, of one kind or of all.

    Raises:
        ModelError: an unknown kind.
    """
    if kind is None:
        return list(REGISTRY)
    if kind not in KINDS:
        raise ModelError(f"unknown model kind {kind!r}: use one of {', '.join(KINDS)}")
    return [name for name, entry in REGISTRY.items() if kind in entry.kinds]
