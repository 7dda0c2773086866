"""What the evaluation suite evaluates: motions with their intended emotion (and path).

Every generator of the project, and any folder of BVH files, becomes a list of
:class:`EvaluatedMotion` here, so the suites have no special cases:

* a folder of motion files, BVH, glTF or FBX (:func:`read_folder`): the intended emotion of
  each file comes from a ``labels.json`` in the folder, else from a Bandai Namco style file
  name (``dataset-N_{content}_{style}_{take}.bvh``);
* a generator (:class:`~emotive.models.api.Generator`), asked for the standard requests of
  :func:`standard_requests` (each emotion alone, and emotion transitions, along a figure-8)
  that its capabilities allow (:func:`requests_for`);
* a style-transfer model (:class:`~emotive.models.api.TransferModel`), given clips to render
  in each emotion (:func:`from_transfer`).

``labels.json`` maps file names to what was intended::

    {
      "walk_happy.bvh": {"emotion": "happy=0.7,neutral=0.3", "path": "figure8"},
      "angry_to_happy.bvh": {"schedule": [{"t": 0, "emotion": "angry"},
                                           {"t": 10, "emotion": "happy"}],
                             "path": [[0, 0], [2, 3], [4, 0]]}
    }

``emotion`` is any text form of :meth:`emotive.data.emotion.Emotion.parse`; ``schedule`` any
keyframe list of :class:`~emotive.data.emotion.EmotionSchedule`; ``path`` a built-in shape name
or ``[[x, z], ...]`` waypoints in metres (see :mod:`emotive.paths`).

Legend: ``T`` frames, ``C`` labels, ``P`` path samples.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.data.clips import parse_clip_name
from emotive.data.emotion import DEFAULT_LABELS, Emotion, EmotionSchedule, canonical_label
from emotive.errors import EmotionError, EmotiveError, PathError
from emotive.io.motion_files import READ_SUFFIXES, read_motion
from emotive.models.api import (
    Capabilities,
    GenerationRequest,
    Generator,
    TransferModel,
)
from emotive.paths import GroundPath, figure8, load_path, waypoints

#: Name of the intended-emotion file of a folder.
LABELS_FILE = "labels.json"


class SourceError(EmotiveError):
    """A folder or generator output that cannot be evaluated (no labels, bad labels.json)."""


@dataclass(frozen=True, eq=False)
class EvaluatedMotion:
    """One motion to evaluate.

    Attributes:
        name: a label for reports (file name or request name).
        motion: the motion, metres, Y up.
        intended: ``(T, C)`` intended emotion weights per frame, rows summing to one.
        labels: the ``C`` labels of ``intended``.
        path: ``(P, 2)`` ``(x, z)`` path it was asked to follow, or ``None``.
    """

    name: str
    motion: Motion
    intended: np.ndarray
    labels: tuple[str, ...]
    path: np.ndarray | None = None

    @property
    def changes(self) -> np.ndarray:
        """Frames where the dominant intended label changes: ``(K,)``."""
        dominant = self.intended.argmax(-1)
        return np.flatnonzero(np.diff(dominant) != 0) + 1


def standard_requests(labels: Sequence[str] = DEFAULT_LABELS, seconds: float = 10.0,
                      path: GroundPath | None = None) -> list[GenerationRequest]:
    """Each label alone, then transitions between labels, along ``path``.

    Each label alone, then transitions angry -> happy and sad -> happy, along ``path``
    (default: a figure-8 of radius 2 m), ``seconds`` long each.

    The transitions switch linearly over the middle second.
    """
    path = path or figure8(2.0)
    requests = [
        GenerationRequest(label, EmotionSchedule.constant(Emotion.one_hot(label, labels)),
                          seconds, path)
        for label in labels
    ]
    half = 0.5 * seconds
    for start, end in (("angry", "happy"), ("sad", "happy")):
        if start in labels and end in labels:
            schedule = EmotionSchedule.from_keyframes(
                [{"t": 0.0, "emotion": start}, {"t": half - 0.5, "emotion": start},
                 {"t": half + 0.5, "emotion": end}], labels,
            )
            requests.append(GenerationRequest(f"{start}-to-{end}", schedule, seconds, path))
    return requests


def requests_for(capabilities: Capabilities, requests: Sequence[GenerationRequest]
                 ) -> list[GenerationRequest]:
    """The requests a generator of ``capabilities`` can honour.

    Without their path when it follows none, without those whose emotion changes (or blends) when it
    cannot, at most ``max_seconds`` long.
    """
    out = []
    for request in requests:
        weights = np.asarray(request.schedule.weights)
        changes = len(weights) > 1 and not np.allclose(weights, weights[0])
        blended = not np.all(np.isclose(weights.max(-1), 1.0))
        if (changes and not capabilities.schedules) or (blended and not capabilities.blends):
            continue
        out.append(replace(request, path=request.path if capabilities.paths else None,
                           primer=request.primer if capabilities.primer else None,
                           seconds=min(request.seconds, capabilities.max_seconds)))
    return out


def from_generator(generator: Generator, requests: Sequence[GenerationRequest]
                   ) -> list[EvaluatedMotion]:
    """Run the requests through a generator.

    Run the requests through a generator (:class:`~emotive.models.api.Generator`): each
    motion with the per-frame emotion the generator reports and the path it followed.
    """
    out = []
    for request in requests:
        made = generator.generate(request)
        out.append(EvaluatedMotion(request.name, made.motion, made.emotion, made.labels,
                                   made.path.points if made.path is not None else None))
    return out


def from_transfer(model: TransferModel, clips: Sequence[EvaluatedMotion],
                  labels: Sequence[str]) -> list[EvaluatedMotion]:
    """Each clip transferred into each of ``labels`` by a style-transfer model.

    Each clip transferred into each of ``labels`` by a style-transfer model
    (:class:`~emotive.models.api.TransferModel`), named ``"<clip> -> <label>"``.
    """
    out = []
    for clip in clips:
        for label in labels:
            style = EmotionSchedule.constant(Emotion.one_hot(label, labels))
            made = model.transfer(clip.motion, style)
            out.append(EvaluatedMotion(f"{clip.name} -> {label}", made.motion, made.emotion,
                                       made.labels))
    return out


def _intent(entry: Any, where: str, labels: Sequence[str]) -> tuple[EmotionSchedule,
                                                                   np.ndarray | None]:
    if not isinstance(entry, dict) or not ({"emotion", "schedule"} & set(entry)):
        raise SourceError(f'{where}: give "emotion" or "schedule" for each file')
    try:
        if "schedule" in entry:
            schedule = EmotionSchedule.from_keyframes(entry["schedule"], labels)
        else:
            spec = entry["emotion"]
            emotion = (Emotion.from_dict(spec, labels) if isinstance(spec, dict)
                       else Emotion.parse(str(spec), labels))
            schedule = EmotionSchedule.constant(emotion)
        path = None
        if "path" in entry:
            spec = entry["path"]
            path = (load_path(spec) if isinstance(spec, str)
                    else waypoints(np.asarray(spec, dtype=np.float64), name=where)).points
    except (EmotionError, PathError, TypeError, ValueError) as exc:
        raise SourceError(f"{where}: {exc}") from None
    return schedule, path


def read_folder(folder: str | Path, labels: Sequence[str] = DEFAULT_LABELS
                ) -> list[EvaluatedMotion]:
    """The motion files of a folder (BVH, glTF, FBX) with their intended emotion.

    See the module docstring.

    Files named after a Bandai Namco style outside ``labels`` are left out (a report names
    them); files with no intended emotion at all are an error.

    Raises:
        SourceError: not a folder, no motion files, a bad ``labels.json``, or unlabelled files.
        BVHError: a BVH file that cannot be read.
        MotionFileError: a glTF or FBX file that cannot be read.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SourceError(f"{folder} is not a folder of motion files")
    files = sorted(f for f in folder.iterdir()
                   if f.suffix.lower() in READ_SUFFIXES and f.is_file())
    if not files:
        raise SourceError(f"{folder} holds no .bvh files (nor {', '.join(READ_SUFFIXES[1:])})")
    table: dict[str, Any] = {}
    if (folder / LABELS_FILE).is_file():
        try:
            table = json.loads((folder / LABELS_FILE).read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise SourceError(f"{folder / LABELS_FILE} is not valid JSON ({exc})") from None
        if not isinstance(table, dict):
            raise SourceError(f'{folder / LABELS_FILE} must map file names to {{"emotion": ...}}')
        unknown = sorted(set(table) - {f.name for f in files})
        if unknown:
            raise SourceError(f"{folder / LABELS_FILE} names files that are not there: {unknown}")
    labels = tuple(labels)
    out, unlabelled = [], []
    for file in files:
        path = None
        if file.name in table:
            schedule, path = _intent(table[file.name], f"{LABELS_FILE}[{file.name!r}]", labels)
        elif (parsed := parse_clip_name(file)) is not None:
            label = canonical_label(parsed["style"])
            if label not in labels:
                continue
            schedule = EmotionSchedule.constant(Emotion.one_hot(label, labels))
        else:
            unlabelled.append(file.name)
            continue
        motion = read_motion(file)
        intended = schedule.sample(motion.fps, num_frames=motion.num_frames)
        out.append(EvaluatedMotion(file.name, motion, intended, labels, path))
    if unlabelled:
        raise SourceError(
            f"{folder}: no intended emotion for {unlabelled}; add them to {LABELS_FILE} "
            'as {"FILE.bvh": {"emotion": "happy"}} or name them dataset-N_content_style_take.bvh'
        )
    if not out:
        raise SourceError(f"{folder}: no file has an intended emotion among {list(labels)}")
    return out
