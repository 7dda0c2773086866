"""The valence/arousal FCRBM behind the model contract (:mod:`emotive.models.api`).

Registered as ``fcrbm`` (:mod:`emotive.models.registry`), a generator doing what
``emotive fcrbm generate`` does: the request's emotion becomes a per-frame valence/arousal track
on the toolkit's -1..1 scale, shifted by +2 to the paper's 1..3 scale of the model
(:mod:`emotive.models.fcrbm.generate`), and :func:`~emotive.models.fcrbm.generate.generate_motion`
walks it. Blends and schedules of labels are accepted through their valence/arousal; the model
follows no path. Requests are bounded at an hour (:data:`MAX_SECONDS`): generation is one frame
after another, about 3 ms a frame, so an hour takes minutes.

Options: ``gibbs`` (Gibbs iterations per frame, default the model's) and ``root`` (``"feet"``:
the root rebuilt from the stance foot, the default; ``"model"``: the model's own root).

Legend: ``T`` frames, ``C`` labels.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console

from emotive.data.emotion import ALL_LABELS
from emotive.models.api import Capabilities, Generated, GenerationRequest, check_request
from emotive.models.fcrbm.generate import (
    FCRBMInputError,
    check_root,
    generate_motion,
    load_fcrbm_model,
)

if TYPE_CHECKING:
    from emotive.data.emotion import EmotionSchedule
    from emotive.models.fcrbm.generate import FCRBMModel

#: Longest request, seconds.
MAX_SECONDS = 3600.0
#: Offset from the toolkit's valence/arousal scale (-1..1) to the model's (1..3).
SCALE_OFFSET = 2.0
#: What the FCRBM can honour.
CAPABILITIES = Capabilities(paths=False, blends=True, schedules=True, valence_arousal=True,
                            primer=True, max_seconds=MAX_SECONDS)


def valence_arousal_track(schedule: EmotionSchedule, frames: int, fps: float) -> np.ndarray:
    """``(T, 2)`` valence/arousal of ``schedule`` at frames ``i / fps``.

    Toolkit scale -1..1 (valence/arousal keyframes exactly, label keyframes as the weighted mean of
    their label points: :meth:`~emotive.data.emotion.EmotionSchedule.sample_valence_arousal`).
    """
    return np.asarray(schedule.sample_valence_arousal(frames, fps), dtype=np.float64)


@dataclass
class FCRBMGenerator:
    """A trained FCRBM as a :class:`~emotive.models.api.Generator`.

    Attributes:
        model: the loaded model.
        name: its name in reports.
        gibbs: Gibbs iterations per frame, or ``None`` for the model's.
        root: ``"feet"`` or ``"model"`` (see the module docstring).
    """

    model: FCRBMModel
    name: str = "fcrbm"
    gibbs: int | None = None
    root: str = "feet"
    capabilities: Capabilities = CAPABILITIES

    @property
    def labels(self) -> tuple[str, ...]:
        """Every label with a valence/arousal point (:data:`emotive.data.emotion.ALL_LABELS`)."""
        return ALL_LABELS

    def context(self, request: GenerationRequest) -> np.ndarray:
        """``(T, 2)`` context of a request on the model's 1..3 scale."""
        frames = max(1, round(request.seconds * self.model.fps))
        return SCALE_OFFSET + valence_arousal_track(request.schedule, frames, self.model.fps)

    def generate(self, request: GenerationRequest, progress: bool = False) -> Generated:
        """The motion for one request (see :meth:`emotive.models.api.Generator.generate`).

        Returns:
            The motion at the model's frame rate and the ``(T, C)`` label weights of the
            schedule at its frames, over the schedule's labels.

        Raises:
            RequestError: a path, or a request longer than :data:`MAX_SECONDS`.
            FCRBMInputError: a valence/arousal outside the model's range, a bad primer.
            FCRBMDivergedError: the model diverged for this context.
        """
        check_request(request, self.name, self.capabilities)
        context = self.context(request)
        status = (Console(stderr=True).status(f"generating {len(context)} frames ...")
                  if progress else nullcontext())
        with status:
            motion, _ = generate_motion(self.model, context, seed=request.seed,
                                        primer=request.primer, gibbs=self.gibbs,
                                        name=request.name, root=self.root)
        emotion = request.schedule.sample(motion.fps, num_frames=motion.num_frames)
        first, last = (np.round(context[k] - SCALE_OFFSET, 2).tolist() for k in (0, -1))
        span = f"{first}" if first == last else f"{first} to {last}"
        return Generated(motion, emotion, request.schedule.labels, None,
                         f"{motion.num_frames} frames ({motion.duration:.1f} s), "
                         f"valence/arousal {span}")


def load_generator(name: str = "fcrbm", weights: str | Path | None = None,
                   gibbs: int | None = None, root: str | None = None) -> FCRBMGenerator:
    """Registry loader: the FCRBM of ``weights`` (default: the committed checkpoint).

    Raises:
        FCRBMInputError: ``gibbs < 1`` or an unknown ``root``.
        ConfigError: a missing or corrupt checkpoint.
    """
    root = root or "feet"
    check_root(root)
    if gibbs is not None and (isinstance(gibbs, bool) or int(gibbs) != gibbs or gibbs < 1):
        raise FCRBMInputError(f"gibbs must be a whole number >= 1, got {gibbs!r}")
    label = name if weights is None else Path(weights).stem
    return FCRBMGenerator(load_fcrbm_model(weights), label, None if gibbs is None
                          else int(gibbs), root)
