"""``emotive study init``: a new study folder from a template, all or nothing.

The folder is built beside its destination under a temporary name (stimuli, readings,
``study.toml``) and renamed into place at the end, so an interrupted ``init`` leaves no
half-made study.
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from emotive.core.motion import Motion
from emotive.study.config import STUDY_FILE, load_study
from emotive.study.errors import StudyError
from emotive.study.stimuli import judge_stimuli, write_stimuli
from emotive.study.templates import (
    TEMPLATES,
    StimulusRecipe,
    affect_grid_recipes,
    design,
    gaits_recipes,
    sources_recipes,
    study_toml,
)

#: Default stimuli of each template (per source and label for ``sources``).
DEFAULT_COUNTS = {"gaits": 8, "affect-grid": 9, "sources": 1}


def _data_present() -> bool:
    from emotive.data.store import dataset_state  # noqa: PLC0415

    return dataset_state("bandai-namco-1").state != "missing"


def _given(folder: Path) -> tuple[list[StimulusRecipe], dict[str, Motion]]:
    from emotive.eval.sources import read_folder  # noqa: PLC0415

    recipes, motions = [], {}
    for i, clip in enumerate(read_folder(folder)):
        sid = f"s{i + 1:02d}"
        weights = clip.intended[0]
        # A clip whose intended emotion changes has no one intended emotion to compare with.
        constant = bool(np.allclose(clip.intended, weights[None, :], atol=1e-6))
        intended = ",".join(f"{label}={w:.3g}" for label, w in zip(clip.labels, weights,
                                                                    strict=True) if w > 0)
        intended = intended if constant else ""
        recipes.append(StimulusRecipe(sid, "given", intended, {"file": clip.name}))
        motions[sid] = clip.motion
    return recipes, motions


def _recipes(template: str, count: int, seed: int) -> list[StimulusRecipe]:
    if template == "gaits":
        return gaits_recipes(count, seed)
    if template == "affect-grid":
        return affect_grid_recipes(count, seed, recorded=_data_present())
    if not _data_present():
        raise StudyError("the 'sources' template shows motion capture, its IK reconstruction "
                         "and LGB resampling, which need the Bandai Namco data: run `emotive "
                         "data fetch bandai-namco-1`, or give your own clips with --stimuli")
    return sources_recipes(count, seed)


def create_study(folder: Path, template: str, stimuli: Path | None = None,
                 count: int | None = None, seconds: float = 10.0, seed: int = 0,
                 advance: Callable[[str], None] | None = None,
                 on_total: Callable[[int], None] | None = None) -> Path:
    """Make a study folder (see the module docstring).

    Args:
        folder: the new folder (must not exist, or be empty).
        template: one of :data:`~emotive.study.templates.TEMPLATES`.
        stimuli: a folder of BVH/glTF/FBX files with their intended emotions (a
            ``labels.json`` or Bandai Namco names) used instead of generated stimuli.
        count: stimuli to generate (default :data:`DEFAULT_COUNTS`).
        seconds: every stimulus's length.
        seed: the study's seed (stimuli, orders, conditions).
        advance: called with each stimulus id once made.
        on_total: called once with the number of stimuli to make.

    Returns:
        The folder.

    Raises:
        StudyError: a bad template, count or folder; data the template needs is absent.
    """
    if template not in TEMPLATES:
        raise StudyError(f"--template {template!r} is not one of {', '.join(TEMPLATES)}")
    count = DEFAULT_COUNTS[template] if count is None else count
    if not 1 <= count <= 100:
        raise StudyError(f"--count {count}: give 1 to 100 stimuli")
    if not 1.0 <= seconds <= 120.0:
        raise StudyError(f"--seconds {seconds:g}: give 1 to 120 seconds")
    folder = folder.expanduser().absolute()
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise StudyError(f"{folder} already exists and is not empty: choose a new folder "
                         "(a study's files and responses belong together)")
    if not folder.parent.is_dir():
        raise StudyError(f"{folder.parent} does not exist: create it first")
    d = design(template)
    given: dict[str, Motion] = {}
    if stimuli is not None:
        recipes, given = _given(stimuli)
    else:
        recipes = _recipes(template, count, seed)
    conditions = None
    if d.conditions:
        conditions = {c["name"]: [r.id for r in recipes if r.source == c["name"]]
                      for c in d.conditions}
        if stimuli is not None or not all(conditions.values()):
            conditions = {c["name"]: [r.id for r in recipes] for c in d.conditions}
    if on_total is not None:
        on_total(len(recipes))
    work = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        files = write_stimuli(recipes, work, seconds, given, advance)
        (work / STUDY_FILE).write_text(study_toml(d, recipes, files, seconds, seed, conditions),
                                       encoding="utf-8")
        load_study(work)
        judge_stimuli(work, [r.id for r in recipes], seconds)
        work.chmod(0o755)
        if folder.exists():
            folder.rmdir()
        work.rename(folder)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return folder
