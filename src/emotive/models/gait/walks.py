"""Whole walks from the gait network: every (path, emotion) pair stepped in one batch.

:func:`generate_walks` (behind ``emotive generate``) runs a
:class:`~emotive.models.gait.generate.GaitGenerator` for a number of seconds and keeps its
frames as they stream, planted feet held by the causal foot lock; the offline cleanup
(:func:`clean_foot_contacts`: contacts of the whole clip pinned to their mean position and
the legs re-solved by inverse kinematics) is an explicit opt-in.

Legend: ``T`` frames, ``C`` emotion labels.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.progress import track

from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.data.emotion import EmotionLike
from emotive.features.contacts import foot_contacts
from emotive.ik.api import pin_feet
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.paths import GroundPath

__all__ = [
    "GeneratedWalk",
    "clean_foot_contacts",
    "generate_walks",
]


@dataclass(frozen=True, eq=False)
class GeneratedWalk:
    """A walk made by :func:`generate_walks`.

    Attributes:
        motion: the motion on the model's rig at the model's frame rate (frame 0 is the start
            pose), world placement in the mover joint.
        emotion: ``(T, C)`` emotion of every frame.
        labels: the ``C`` labels.
        path: the path it followed.
    """

    motion: Motion
    emotion: np.ndarray
    labels: tuple[str, ...]
    path: GroundPath


def generate_walks(
    model: GaitModel,
    paths: Sequence[GroundPath],
    emotions: Sequence[EmotionLike],
    seconds: float,
    seed: int = 0,
    primer: Motion | None = None,
    progress: bool = False,
    foot_lock: bool = True,
    clean_feet: bool = False,
) -> list[GeneratedWalk]:
    """Walks of ``seconds`` for each (path, emotion) pair, all stepped in one batch.

    The walks are exactly the generator's stream: with ``foot_lock`` (the default) planted
    feet are held by the causal lock inside every step (:mod:`emotive.ik.foot_lock`), as a
    live consumer receives them; ``False`` keeps the network's raw poses. ``clean_feet`` opts
    in to the offline cleanup of :func:`clean_foot_contacts` on top (it needs the whole clip).

    Raises:
        EmotionError, PathError, RigError: as
            :meth:`~emotive.models.gait.generate.GaitGenerator.add_agent`.
        ValueError: ``seconds`` not a positive finite number, or lists of different lengths.
    """
    if not (isinstance(seconds, int | float) and math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number, got {seconds!r}")
    if len(paths) != len(emotions):
        raise ValueError(f"{len(paths)} paths for {len(emotions)} emotions: give one each")
    gen = GaitGenerator(model, seed=seed, foot_lock=foot_lock)
    for path, emotion in zip(paths, emotions, strict=True):
        gen.add_agent(path, emotion, primer=primer)
    frames = [gen.first_frame()]
    steps = max(1, round(seconds * model.fps))
    for _ in track(range(steps), description="generating", disable=not progress,
                   console=Console(stderr=True), transient=True):
        frames.append(gen.step())
    rotations = np.stack([f.rotations for f in frames], 1)
    positions = np.stack([f.positions for f in frames], 1)
    emotion = np.stack([f.emotion for f in frames], 1)
    out = []
    for k, path in enumerate(paths):
        motion = Motion(model.controls.skeleton, rotations[k], positions[k], model.fps,
                        {"name": f"walk-{k}", "source": str(model.source), "seed": seed})
        if clean_feet:
            motion = clean_foot_contacts(motion)
        out.append(GeneratedWalk(motion, emotion[k], model.labels, path))
    return out


def clean_foot_contacts(motion: Motion) -> Motion:
    """Hold planted feet still.

    The network moves the body along the path by its predicted speed, and where the legs' stride
    does not match that speed exactly a planted foot slides. Feet touching the ground
    (:func:`emotive.features.contacts.foot_contacts` on the walk itself) are pinned where they
    landed and the leg chains re-solved by inverse kinematics (:func:`emotive.ik.api.pin_feet`); the
    hips and the upper body are unchanged.
    """
    if motion.num_frames < 3:
        return motion
    contacts = foot_contacts(motion.positions_with_end_sites(), resolve_roles(motion.skeleton),
                             motion.fps)
    return pin_feet(motion, contacts).motion.replace(metadata=motion.metadata)
