"""The gait network behind the model contract (:mod:`emotive.models.api`).

Registered as ``gait`` (the pretrained checkpoint) and as its two ablations
``gait-no-affective`` and ``gait-no-root-loss`` (:mod:`emotive.models.registry`), each both a
generator and a Table 1 predictor:

* :class:`GaitWalkGenerator` is what ``emotive generate`` does: the walks of
  :func:`~emotive.models.gait.walks.generate_walks` with the foot-contact cleanup, at
  :data:`OUTPUT_FPS` (the data's rate; a checkpoint of another rate is resampled), along the
  request's path (by default a figure-8 of radius 2 m, the command's default), their feet
  kept above the floor (:func:`emotive.ik.floor.keep_above_floor`: no heel or toe lower than
  in the checkpoint's standing pose, which stands on the floor, by more than
  :data:`~emotive.ik.floor.FLOOR_ALLOWANCE`; the stream's network sinks into it by up to 3 cm,
  a sad walk for much of its stance);
* the predictor is :class:`~emotive.models.gait.predict.GaitPredictor`.

Legend: ``T`` frames, ``C`` labels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.ops import resample
from emotive.core.roles import resolve_roles
from emotive.ik.floor import keep_above_floor, standing_floor
from emotive.models.api import Capabilities, Generated, GenerationRequest, check_request
from emotive.models.gait.model import default_checkpoint_path, load_gait_model
from emotive.models.gait.predict import GaitPredictor
from emotive.models.gait.walks import generate_walks
from emotive.paths import load_path

if TYPE_CHECKING:
    from emotive.models.gait.model import GaitModel

#: What the gait network can honour: paths, blends, schedules and primers, up to an hour
#: (the ``emotive generate --seconds`` bound).
CAPABILITIES = Capabilities(paths=True, blends=True, schedules=True, valence_arousal=False,
                            primer=True, max_seconds=3600.0)
#: Frame rate of every walk returned, frames per second (the data's).
OUTPUT_FPS = 30.0
#: The path walked when a request gives none (``emotive generate --path`` default).
DEFAULT_PATH = "figure8"


def checkpoint_for(name: str, weights: str | Path | None) -> Path | None:
    """The checkpoint of registry entry ``name``.

    ``weights`` if given, else ``None`` for the pretrained ``gait`` or the committed ablation
    ``emotive/assets/gait/<name>.pt``.
    """
    if weights is not None:
        return Path(weights)
    if name == "gait":
        return None

    return default_checkpoint_path().with_name(f"{name}.pt")


@dataclass
class GaitWalkGenerator:
    """A gait model as a :class:`~emotive.models.api.Generator`.

    Attributes:
        model: the loaded model.
        name: its name in reports.
        foot_lock: hold planted feet in the stream and keep them above the floor
            (``emotive generate`` does; ``--raw`` not).
    """

    model: GaitModel
    name: str = "gait"
    foot_lock: bool = True
    capabilities: Capabilities = CAPABILITIES

    @property
    def labels(self) -> tuple[str, ...]:
        """The ``C`` labels of the model's emotion vector."""
        return self.model.labels

    def generate(self, request: GenerationRequest, progress: bool = False) -> Generated:
        """The walk for one request (see :meth:`emotive.models.api.Generator.generate`).

        Returns:
            The motion at the model's frame rate, its ``(T, C)`` per-frame emotion over the
            model's labels (the schedule at the frames), and the path followed.

        Raises:
            RequestError: a request longer than an hour.
            EmotionError, PathError, RigError: as
                :func:`~emotive.models.gait.walks.generate_walks`.
        """
        check_request(request, self.name, self.capabilities)
        path = request.path if request.path is not None else load_path(DEFAULT_PATH)
        walk = generate_walks(self.model, [path], [request.schedule], request.seconds,
                              seed=request.seed, primer=request.primer, progress=progress,
                              foot_lock=self.foot_lock)[0]
        motion, emotion = at_output_rate(walk.motion, walk.emotion)
        if self.foot_lock:
            motion = keep_above_floor(motion, model_floor(self.model))
        motion = motion.replace(metadata={**motion.metadata, "name": request.name})
        return Generated(motion, emotion, walk.labels, walk.path,
                         f"{request.name}: {motion.num_frames} frames ({motion.duration:.1f} s)"
                         f" along {path.name}")


def at_output_rate(motion: Motion, emotion: np.ndarray) -> tuple[Motion, np.ndarray]:
    """A walk and its ``(T, C)`` emotion at :data:`OUTPUT_FPS`.

    The motion is resampled by :func:`emotive.core.ops.resample`, the emotion interpolated
    linearly and renormalized; a walk already at that rate is returned as it is.
    """
    if abs(motion.fps - OUTPUT_FPS) < 1e-9:
        return motion, emotion
    out = resample(motion, OUTPUT_FPS)
    src = np.arange(motion.num_frames) / motion.fps
    dst = np.arange(out.num_frames) / OUTPUT_FPS
    moved = np.stack([np.interp(dst, src, emotion[:, c]) for c in range(emotion.shape[1])], 1)
    return out, moved / moved.sum(1, keepdims=True)


def model_floor(model: GaitModel) -> np.ndarray:
    """``(2, 2)`` floor heights of the model's rig: its standing pose's heels and toes.

    The standing pose (:class:`~emotive.models.gait.controls.GaitControls`, a statistic of
    the training data) stands on the floor; the stream's foot lock takes the same heights as
    its ground.
    """
    c = model.controls
    standing = Motion(c.skeleton, c.standing_rotations[None], c.standing_positions[None],
                      c.fps).positions_with_end_sites()[0]
    return standing_floor(standing, resolve_roles(c.skeleton))


def load_model(name: str = "gait", weights: str | Path | None = None) -> GaitModel:
    """The gait model of registry entry ``name`` or of the checkpoint ``weights``."""
    return load_gait_model(checkpoint_for(name, weights))


def load_generator(name: str = "gait", weights: str | Path | None = None,
                   raw: bool | None = None) -> GaitWalkGenerator:
    """Registry loader: the gait network as a generator.

    Args:
        name: the registry entry.
        weights: a checkpoint instead of the entry's.
        raw: stream the network's poses without the causal foot lock.
    """
    return GaitWalkGenerator(load_model(name, weights), name=_report_name(name, weights),
                             foot_lock=not raw)


def load_predictor(name: str = "gait", weights: str | Path | None = None) -> Any:
    """Registry loader: the gait network as a Table 1 predictor.

    Registry loader: the gait network as a Table 1 predictor
    (:class:`~emotive.models.gait.predict.GaitPredictor`, named "Ours" for the pretrained
    model as in the paper's table).
    """
    label = "Ours" if name == "gait" and weights is None else _report_name(name, weights)
    return GaitPredictor(load_model(name, weights), name=label)


def _report_name(name: str, weights: str | Path | None) -> str:
    return name if weights is None else Path(weights).stem
