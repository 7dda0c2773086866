"""Stimuli of a study: made by emotive's models (with a seed) or read from given files.

Every stimulus becomes ``stimuli/ID.glb``: the skinned mannequin and its animation, exactly
``seconds`` long (longer clips are cut, shorter ones refused), which the participant page
plays looping at a fixed camera. :func:`judge_stimuli` adds the perceived-emotion
classifier's reading of each, ``stimuli/readings.json``, so that ``analyze`` can set the
classifier beside the humans and ``simulate`` can draw answers from it::

    {"classifier": "...", "labels": ["happy", "sad", "angry", "neutral"],
     "stimuli": {"s01": {"probabilities": {"happy": 0.7, ...}, "valence": 0.4,
                         "arousal": 0.3, "unsure": false, "perceived": "happy"}}}

Legend: ``T`` frames.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.study.errors import StudyError
from emotive.study.templates import StimulusRecipe

#: The roles drawn in the ``effectors`` render: the end effectors and the pelvis
#: (Carreno-Medrano et al. 2018, section 4).
EFFECTOR_ROLES = ("head", "l_wrist", "r_wrist", "l_ankle", "r_ankle", "root")
#: The classifier's reading file inside ``stimuli/``.
READINGS_FILE = "readings.json"


def stimulus_effectors(path: Path) -> list[str]:
    """Names of the joints of :data:`EFFECTOR_ROLES` in a stimulus GLB (roles unresolved: [])."""
    from emotive.core.roles import resolve_roles  # noqa: PLC0415 - torch loads only here
    from emotive.errors import EmotiveError  # noqa: PLC0415
    from emotive.io.motion_files import read_motion  # noqa: PLC0415

    try:
        roles = resolve_roles(read_motion(path).skeleton)
    except EmotiveError:
        return []
    return [roles.names[r] for r in EFFECTOR_ROLES if "/" not in roles.names[r]]


def cut(motion: Motion, seconds: float, name: str) -> Motion:
    """The first ``seconds`` of ``motion``.

    Raises:
        StudyError: the clip is shorter.
    """
    frames = round(seconds * motion.fps)
    if motion.num_frames < frames:
        raise StudyError(f"{name} lasts {motion.num_frames / motion.fps:.1f} s, shorter than "
                         f"the study's {seconds:g} s: every stimulus must be as long; choose a "
                         "smaller --seconds or a longer clip")
    from emotive.core.ops import crop  # noqa: PLC0415

    return crop(motion, 0, frames)


def _generated(recipe: StimulusRecipe, seconds: float, models: dict[str, Any]) -> Motion:
    from emotive.data.emotion import EmotionSchedule  # noqa: PLC0415
    from emotive.models.api import GenerationRequest  # noqa: PLC0415
    from emotive.models.registry import get_model  # noqa: PLC0415
    from emotive.paths import load_path  # noqa: PLC0415

    name = recipe.recipe["model"]
    if name not in models:
        models[name] = get_model(name).load("generator")
    generator = models[name]
    path = recipe.recipe.get("path")
    request = GenerationRequest(
        name=recipe.id, schedule=EmotionSchedule.parse(recipe.recipe["emotion"]),
        seconds=seconds + 0.5,
        path=load_path(path) if path and generator.capabilities.paths else None,
        seed=int(recipe.recipe["seed"]))
    return generator.generate(request).motion


def _recorded(recipe: StimulusRecipe) -> Motion:
    from emotive.data.circumplex import style_to_label  # noqa: PLC0415
    from emotive.data.clips import list_clips  # noqa: PLC0415
    from emotive.io.motion_files import read_motion  # noqa: PLC0415

    info = recipe.recipe
    clips = [c for c in list_clips(info["dataset"], contents=["walk"])
             if style_to_label(c.style) == info["style"]]
    if not clips:
        raise StudyError(f"{info['dataset']} has no walk clips labelled {info['style']!r}")
    return read_motion(clips[int(info["take"]) % len(clips)].path)


def make_motion(recipe: StimulusRecipe, seconds: float, models: dict[str, Any],
                given: Motion | None = None) -> Motion:
    """The motion of one recipe, ``seconds`` long.

    Raises:
        StudyError: a clip shorter than ``seconds``.
        DataError: the data a recorded, reconstructed or resampled stimulus needs is absent.
    """
    if given is not None:
        motion = given
    elif recipe.source in ("recorded", "reconstructed"):
        motion = _recorded(recipe)
        if recipe.source == "reconstructed":
            from emotive.ik.api import reconstruct  # noqa: PLC0415

            motion = reconstruct(cut(motion, seconds, recipe.id)).motion
    else:
        motion = _generated(recipe, seconds, models)
    return cut(motion, seconds, recipe.recipe.get("file", recipe.id))


def write_stimuli(recipes: Sequence[StimulusRecipe], folder: Path, seconds: float,
                  given: dict[str, Motion] | None = None,
                  advance: Callable[[str], None] | None = None) -> dict[str, str]:
    """Make every stimulus into ``folder/stimuli/ID.glb``.

    Args:
        recipes: what to make.
        folder: the (new) study folder.
        seconds: every stimulus's length.
        given: motions read from the user's files, by stimulus id.
        advance: called with each stimulus id once it is written (a progress bar).

    Returns:
        Stimulus id -> its file, relative to ``folder``.
    """
    from emotive.io.gltf import write_gltf  # noqa: PLC0415

    (folder / "stimuli").mkdir(parents=True, exist_ok=True)
    models: dict[str, Any] = {}
    files = {}
    for recipe in recipes:
        motion = make_motion(recipe, seconds, models, (given or {}).get(recipe.id))
        files[recipe.id] = f"stimuli/{recipe.id}.glb"
        write_gltf(motion, folder / files[recipe.id], mesh=True)
        if advance is not None:
            advance(recipe.id)
    return files


def judge_stimuli(folder: Path, ids: Sequence[str], seconds: float) -> dict[str, Any]:
    """The classifier's reading of each stimulus GLB, written to ``stimuli/readings.json``."""
    from emotive.eval.classifier import load_default_classifier  # noqa: PLC0415
    from emotive.io.atomic import atomic_output  # noqa: PLC0415
    from emotive.io.motion_files import read_motion  # noqa: PLC0415

    classifier = load_default_classifier()
    labels = list(classifier.labels)
    window = min(4.0, seconds)
    out: dict[str, Any] = {"classifier": "emotive default (src/emotive/assets/classifier)",
                           "labels": labels, "stimuli": {}}
    for sid in ids:
        judged = classifier.judge(read_motion(folder / "stimuli" / f"{sid}.glb"),
                                  window_seconds=window, hop_seconds=min(1.0, window / 2))
        probs = judged.probabilities.mean(axis=0)
        va = judged.valence_arousal.mean(axis=0)
        unsure = judged.clip_unsure
        out["stimuli"][sid] = {
            "probabilities": {k: round(float(p), 4) for k, p in zip(labels, probs, strict=True)},
            "valence": round(float(va[0]), 4), "arousal": round(float(va[1]), 4),
            "unsure": unsure, "perceived": "unsure" if unsure else labels[int(np.argmax(probs))],
        }
    with atomic_output(folder / "stimuli" / READINGS_FILE) as tmp:
        tmp.write_text(json.dumps(out, indent=1) + "\n")
    return out


def load_readings(folder: Path) -> dict[str, Any] | None:
    """``stimuli/readings.json`` of a study, or ``None`` when it was not made."""
    path = folder / "stimuli" / READINGS_FILE
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise StudyError(f"{path} is not valid JSON ({exc}); delete it, or make the study "
                         "again") from None
