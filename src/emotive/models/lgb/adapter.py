"""The end-effector Local Grid Bootstrap behind the model contract (:mod:`emotive.models.api`).

Registered as ``lgb`` (:mod:`emotive.models.registry`), a generator doing what
``emotive resample`` does: the clips of the data set are read (:func:`emotive.data.load_clips`),
an :class:`~emotive.models.lgb.resampler.EmotionResampler` is fitted on those of the requested
emotion (once per emotion and generator, then kept), resamples the requested number of frames
and rebuilds them by inverse kinematics; the result is resampled to ``fps`` when one is given.

The model has no weights (it is fitted from the data each time it is loaded) and makes one
emotional state at a time: a request must be one label, constant over time (blends and
schedules raise :class:`~emotive.errors.EmotionError`); it follows no path and takes no primer.

Options: ``workers`` (IK worker processes; the result does not depend on it), ``dataset`` (the
data set resampled) and ``fps`` (output frame rate, default the data's).

Legend: ``T`` frames, ``C`` labels.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from emotive.core.ops import resample
from emotive.data import clips as clip_data
from emotive.data.emotion import ALL_LABELS
from emotive.errors import EmotionError
from emotive.models.api import Capabilities, Generated, GenerationRequest, check_request
from emotive.models.lgb.bootstrap import LGBError
from emotive.models.lgb.resampler import EmotionResampler

if TYPE_CHECKING:
    from emotive.models.lgb.resampler import EmotionResampler

#: Longest motion one request makes, seconds (a day).
MAX_SECONDS = 86400.0
#: Output frame rates accepted by ``fps``.
FPS_RANGE = (1.0, 240.0)
#: The data set read by default.
DATASET = "bandai-namco-1"
#: What the resampler can honour: one constant label, no path, no primer.
CAPABILITIES = Capabilities(paths=False, blends=False, schedules=False, valence_arousal=False,
                            primer=False, max_seconds=MAX_SECONDS)


def idle_cores(most: int = 2) -> int:
    """Cores free for IK workers: the machine's cores less its 1-minute load, from 1 to ``most``.

    On a busy machine a second worker only competes with the first.
    """
    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:  # not available on every platform
        load = 0.0
    return max(1, min(most, cores - math.floor(load)))


def check_fps(fps: float | None) -> None:
    """Check that ``fps`` is ``None`` or within :data:`FPS_RANGE`.

    Raise :class:`~emotive.models.lgb.bootstrap.LGBError` unless ``fps`` is ``None`` or a
    rate within :data:`FPS_RANGE`.
    """
    if fps is not None and not (isinstance(fps, int | float) and math.isfinite(fps)
                                and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        raise LGBError(f"fps {fps!r}: give a frame rate from {FPS_RANGE[0]:g} to "
                       f"{FPS_RANGE[1]:g}, e.g. 30, or leave it out for the data's rate")


@dataclass
class LGBGenerator:
    """The Local Grid Bootstrap as a :class:`~emotive.models.api.Generator`.

    Attributes:
        name: its name in reports.
        dataset: the data set whose clips are resampled.
        workers: IK worker processes, or ``None`` for the idle cores (at most 2).
        fps: output frame rate, or ``None`` for the data's.
    """

    name: str = "lgb"
    dataset: str = DATASET
    workers: int | None = None
    fps: float | None = None
    capabilities: Capabilities = CAPABILITIES
    _fitted: dict[str, EmotionResampler] = field(default_factory=dict, repr=False)

    @property
    def labels(self) -> tuple[str, ...]:
        """Every style label of the data (:data:`emotive.data.emotion.ALL_LABELS`)."""
        return ALL_LABELS

    def label_of(self, request: GenerationRequest) -> str:
        """The one label a request asks for.

        Raises:
            EmotionError: a blend, a schedule changing over time, or a label outside
                :attr:`labels`.
        """
        schedule = request.schedule
        check_request(request, self.name, self.capabilities)
        label = schedule.labels[int(np.argmax(schedule.weights[0]))]
        if label not in self.labels:
            raise EmotionError(f"request {request.name!r} to {self.name}: no clips of "
                               f"{label!r}; use one of {', '.join(self.labels)}")
        return label

    def resampler(self, label: str) -> EmotionResampler:
        """The resampler of ``label``, fitted on first use (reads the data set)."""
        if label not in self._fitted:
            clips = clip_data.load_clips(self.dataset)  # module attribute: tests patch it
            self._fitted[label] = EmotionResampler.fit(clips, label, source=self.dataset)
        return self._fitted[label]

    def generate(self, request: GenerationRequest, progress: bool = False) -> Generated:
        """The motion for one request (see :meth:`emotive.models.api.Generator.generate`).

        Returns:
            The motion on the data's rig at :attr:`fps` (or the data's rate) and its
            ``(T, C)`` one-hot emotion over the request's labels; the summary tells the IK
            residuals and the not-a-replay check.

        Raises:
            EmotionError: not one constant label (see :meth:`label_of`).
            RequestError: a path, a primer, or more than :data:`MAX_SECONDS`.
            LGBError: a bad ``fps``; DataError: the data set is missing.
        """
        check_fps(self.fps)
        label = self.label_of(request)
        model = self.resampler(label)
        frames = max(1, round(request.seconds * model.fps))
        workers = self.workers or idle_cores()
        if progress:
            columns = (TextColumn("{task.description}"), BarColumn(),
                       TextColumn("{task.completed}/{task.total} frames"), TimeElapsedColumn())
            with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
                task = bar.add_task(f"rebuilding {label} by IK ({workers} workers)",
                                    total=frames)
                result = model.generate(frames, request.seed,
                                        lambda done, _: bar.update(task, completed=done),
                                        workers=workers)
        else:
            result = model.generate(frames, request.seed, workers=workers)
        motion = result.motion
        if self.fps is not None and abs(self.fps - motion.fps) > 1e-9:
            motion = resample(motion, self.fps)
        motion = motion.replace(metadata={**motion.metadata, "name": request.name})
        emotion = np.zeros((motion.num_frames, len(request.schedule.labels)))
        emotion[:, request.schedule.labels.index(label)] = 1.0
        summary = (f"{label}, seed {request.seed}: {motion.num_frames} frames "
                   f"({motion.duration:.1f} s) resampled and rebuilt")
        if result.novelty is not None:
            summary += (f"; closest to a captured 1-s window {1000 * result.novelty.closest:.1f}"
                        " mm")
        return Generated(motion, emotion, request.schedule.labels, None, summary)


def load_generator(name: str = "lgb", weights: str | Path | None = None,
                   workers: int | None = None, dataset: str | None = None,
                   fps: float | None = None) -> LGBGenerator:
    """Registry loader: the resampler (nothing is read until the first request).

    Raises:
        LGBError: a bad ``fps`` or ``workers``.
    """
    check_fps(fps)
    if workers is not None and (isinstance(workers, bool) or int(workers) != workers
                                or workers < 1):
        raise LGBError(f"workers {workers!r}: give a whole number >= 1, or leave it out")
    return LGBGenerator(name, dataset or DATASET, None if workers is None else int(workers),
                        None if fps is None else float(fps))
