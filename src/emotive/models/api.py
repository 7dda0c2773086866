"""One contract for every model: what a generator, a predictor and a style-transfer model offer.

Every model of the toolkit is reached through :mod:`emotive.models.registry`, which hands out
objects satisfying these protocols, so the CLI (``emotive generate``, ``emotive evaluate``) and
the evaluation suites (:mod:`emotive.eval`) have no per-model code:

* :class:`Generator`: new motion for a :class:`GenerationRequest` (an emotion schedule, a
  length, optionally a ground path, a seed and a primer), returned as :class:`Generated`;
  what a generator can honour is stated by its :class:`Capabilities`.
* :class:`Predictor`: the continuation of an observed motion under a desired emotion (the
  motion-prediction protocol of :mod:`emotive.eval.table1`).
* :class:`TransferModel`: an existing motion rendered in another style (emotion schedule).

This module refers only to :mod:`emotive.core`, :mod:`emotive.data` and :mod:`emotive.paths`,
and only for type hints: importing it loads neither NumPy nor torch. :func:`check_request`
checks a request against a generator's :class:`Capabilities` (adapters call it first).

Legend: ``T`` frames, ``C`` emotion labels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from emotive.errors import EmotionError, EmotiveError

if TYPE_CHECKING:
    import numpy as np

    from emotive.core.motion import Motion
    from emotive.data.emotion import EmotionSchedule
    from emotive.paths import GroundPath

__all__ = [
    "Capabilities",
    "Generated",
    "GenerationRequest",
    "Generator",
    "Predictor",
    "RequestError",
    "TransferModel",
    "check_request",
]


@dataclass(frozen=True)
class GenerationRequest:
    """One request to a generator.

    Attributes:
        name: a label for reports and output captions.
        schedule: the intended emotion over time.
        seconds: length of the motion, seconds.
        path: the ground path to follow, or ``None`` for the model's own default (or no path
            at all for a model that walks freely).
        seed: random seed; the same request and seed give the same motion.
        primer: a motion to start from (on the model's rig), or ``None`` for the model's own
            start.
    """

    name: str
    schedule: EmotionSchedule
    seconds: float
    path: GroundPath | None = None
    seed: int = 0
    primer: Motion | None = None


@dataclass(frozen=True, eq=False)
class Generated:
    """What a generator or transfer model returns.

    Attributes:
        motion: the motion, metres, Y up, at the model's output frame rate.
        emotion: ``(T, C)`` intended emotion weights per frame of ``motion``, rows summing
            to one.
        labels: the ``C`` labels of ``emotion``.
        path: the ground path it followed, or ``None``.
        summary: one line for the CLI (may be empty).
    """

    motion: Motion
    emotion: np.ndarray
    labels: tuple[str, ...]
    path: GroundPath | None = None
    summary: str = ""


@dataclass(frozen=True)
class Capabilities:
    """What a generator can honour in a :class:`GenerationRequest`.

    Attributes:
        paths: follows a ground path (:attr:`GenerationRequest.path`).
        blends: accepts blends of several labels (``happy=0.7,neutral=0.3``).
        schedules: accepts an emotion that changes over time.
        valence_arousal: driven natively by valence and arousal (blends go through them).
        primer: accepts a primer motion.
        max_seconds: longest request accepted, seconds.
    """

    paths: bool
    blends: bool
    schedules: bool
    valence_arousal: bool
    primer: bool
    max_seconds: float


@runtime_checkable
class Generator(Protocol):
    """A model that makes new motion from an emotion request.

    Attributes:
        name: the model's name in reports.
        labels: the emotion labels it understands (a request's schedule is over these).
        capabilities: what it can honour.
    """

    name: str
    labels: tuple[str, ...]
    capabilities: Capabilities

    def generate(self, request: GenerationRequest, progress: bool = False) -> Generated:
        """The motion for one request.

        Args:
            request: what to make.
            progress: show a progress bar on stderr.

        Returns:
            The motion at the model's output frame rate with its per-frame intended emotion.

        Raises:
            EmotiveError: a request beyond :attr:`capabilities` (naming the input and what the
                model accepts instead).
        """
        ...


@runtime_checkable
class Predictor(Protocol):
    """A motion-prediction model as :func:`emotive.eval.table1.table1` evaluates it.

    Attributes:
        name: the model's name in the table; unique among the predictors of one run.
    """

    name: str

    def predict(
        self, primer: Motion, frames: int, emotion: np.ndarray, labels: tuple[str, ...]
    ) -> Motion:
        """The ``frames`` frames that follow ``primer``.

        Args:
            primer: the observed motion, ``T`` frames at the evaluation rate (a copy: the
                predictor may keep or change it).
            frames: number of frames to predict, ``T'``.
            emotion: ``(C,)`` desired emotion, non-negative weights summing to one.
            labels: the ``C`` labels of ``emotion``.

        Returns:
            The continuation alone: rotations ``(T', J, 4)``, positions ``(T', J, 3)``, on the
            primer's skeleton (same joints) at the primer's ``fps``.
        """
        ...


@runtime_checkable
class TransferModel(Protocol):
    """A model that renders an existing motion in another style.

    Attributes:
        name: the model's name in reports.
        labels: the styles it can produce.
    """

    name: str
    labels: tuple[str, ...]

    def transfer(self, motion: Motion, style: EmotionSchedule, progress: bool = False
                 ) -> Generated:
        """``motion`` in ``style``.

        Args:
            motion: the input motion, any rig the model supports.
            style: the output style over time (seconds of the input).
            progress: show progress on stderr.

        Returns:
            The motion on the input's rig with the per-frame style weights as its emotion.
        """
        ...


class RequestError(EmotiveError):
    """A request a generator cannot honour: too long, a path or a primer it cannot use."""


def check_request(request: GenerationRequest, name: str, capabilities: Capabilities) -> None:
    """Raise unless ``request`` is within ``capabilities`` of the generator ``name``.

    Raises:
        RequestError: ``seconds`` not a finite number in ``(0, max_seconds]``, a path for a
            generator without paths, or a primer for one without primers.
        EmotionError: a blend for a generator of single labels, or an emotion changing over
            time for a generator of constant emotions.
    """
    # Deferred: importing the model contract loads no numpy (tests/models/test_api.py).
    import numpy as np  # noqa: PLC0415

    where = f"request {request.name!r} to {name}"
    seconds = request.seconds
    if isinstance(seconds, bool) or not isinstance(seconds, int | float) or not (
            math.isfinite(seconds) and 0 < seconds <= capabilities.max_seconds):
        raise RequestError(f"{where}: seconds {seconds!r} must be a number above 0 and at most "
                           f"{capabilities.max_seconds:g}; ask for a shorter motion")
    if request.path is not None and not capabilities.paths:
        raise RequestError(f"{where}: {name} walks freely and follows no path; leave the path "
                           "out (or use a model with paths, e.g. gait)")
    if request.primer is not None and not capabilities.primer:
        raise RequestError(f"{where}: {name} takes no primer motion; leave the primer out")
    weights = np.asarray(request.schedule.weights)
    if not capabilities.schedules and len(weights) > 1 and not np.allclose(weights, weights[0]):
        raise EmotionError(f"{where}: {name} makes one constant emotion, and the schedule "
                           f"changes over time; give one emotion (e.g. 'happy') and generate "
                           "each part separately")
    if not capabilities.blends and not np.allclose(weights.max(-1), 1.0):
        raise EmotionError(f"{where}: {name} makes one emotion at a time, and the request "
                           f"blends {request.schedule.to_keyframes()[0]['emotion']}; give a "
                           "single label such as 'happy'")
