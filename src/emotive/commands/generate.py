"""``emotive generate``: new motion from a model of the registry.

As BVH or NPZ, with an optional preview.

``--model`` names a generator of :mod:`emotive.models.registry` (gait, the default; fcrbm;
lgb). The emotion goes through :func:`emotive.data.emotion.coerce_emotion` onto the model's
labels, the model makes a :class:`~emotive.models.api.Generated` and
:func:`emotive.render.outputs.write_generated` writes it. Each model-specific flag is defined
once here and passed through; a flag the chosen model does not take is an error naming it.

Any rig in and out (:mod:`emotive.retarget`): with ``--rig RIG.bvh`` the generated motion is
retargeted onto that rig before anything is written, so the BVH, the NPZ and the preview all
show the rig (its joint names, bone lengths, channel order and unit; the ground path is
scaled by the leg-length ratio, as the root motion is). A ``--primer`` on another rig than
the model's is retargeted onto the model's rig first.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from emotive.commands.options import (
    MOTION_OUT,
    EmotionOpt,
    EmotionScheduleOpt,
    ForceOpt,
    PreviewOpt,
    PrimerOpt,
    SecondsOpt,
    SeedOpt,
    UnitOpt,
    emotion_option,
    flag,
    input_file,
    out_option,
    read_input,
    role_joints,
    roles_option,
)

if TYPE_CHECKING:
    from emotive.core.motion import Motion
    from emotive.core.skeleton import Skeleton
    from emotive.models.api import Generated

#: Suffixes ``--out`` takes (``emotive.render.outputs.OUT_SUFFIXES``, repeated so that the
#: checks import no torch; a test checks that the two agree).
GENERATE_OUT = (*MOTION_OUT, ".npz")
#: The shapes ``--path`` names (``emotive.paths.SHAPES``, repeated likewise).
PATH_SHAPES = ("line", "circle", "figure8", "zigzag")

#: The flag of each model option (registry name -> command line).
FLAGS = {"raw": "--raw", "gibbs": "--gibbs", "root": "--root", "workers": "--workers",
         "dataset": "--dataset", "fps": "--fps"}


def model_rig(generator: Any) -> Skeleton | None:
    """The rig a generator's primers must be on, or ``None`` where it does not say.

    The gait network keeps its rig with its animation controls, the FCRBM with its frame
    codec; the LGB takes no primer.
    """
    model = getattr(generator, "model", None)
    for holder in ("controls", "codec"):
        rig = getattr(getattr(model, holder, None), "skeleton", None)
        if rig is not None:
            return rig
    return None


def primer_on_rig(primer: Motion, rig: Skeleton | None, roles: str | None = None) -> Motion:
    """The primer as it is when on ``rig`` (or when the rig is unknown), else retargeted.

    Args:
        primer: the ``--primer`` clip.
        rig: the model's rig (:func:`model_rig`).
        roles: the primer's role map (``--primer-roles``).

    Raises:
        RigError: the primer is on another rig and lacks roles (naming them and the flag).
    """
    import numpy as np

    from emotive.errors import RigError
    from emotive.retarget import resolve_rig, retarget

    if rig is None or (primer.skeleton.names == rig.names
                       and np.array_equal(primer.skeleton.parents, rig.parents)):
        return primer
    try:
        resolve_rig(primer.skeleton, roles, "primer", "--primer-roles")
    except RigError as exc:
        name = primer.metadata.get("source", primer.metadata.get("name", "the primer"))
        raise RigError(f"--primer {name} is on another rig than the model's and cannot be "
                       f"retargeted onto it: {exc}") from None
    return retarget(primer, rig, source_roles=roles)


def on_rig(generated: Generated, rig: Motion, rig_roles: str | None) -> Generated:
    """A model's output retargeted onto ``rig``, its ground path scaled like its root."""
    from dataclasses import replace

    from emotive.paths import GroundPath
    from emotive.retarget import retarget

    motion = retarget(generated.motion, rig, target_roles=rig_roles)
    path = generated.path
    if path is not None:
        path = GroundPath.from_polyline(path.points * motion.metadata["leg_scale"],
                                        path.closed, path.name)
    return replace(generated, motion=motion, path=path)


def path_option(path: str | None) -> None:
    """Fail fast on a ``--path`` that is no shape and no waypoint file that exists.

    Raises:
        PathError: naming the value and the fix.
    """
    from emotive.errors import PathError

    if path is None or path in PATH_SHAPES:
        return
    if not (path.endswith(".json") or Path(path).exists()):
        raise PathError(f"--path: unknown path {path!r}: use one of {', '.join(PATH_SHAPES)} or "
                        "a JSON file of [x, z] waypoints in metres")
    input_file(Path(path), "--path", None, PathError)


def check_request(model: str, out: Path, emotion: str | Path | None, path: str | None,
                  npz: Path | None, preview: Path | None, primer: Path | None,
                  checkpoint: Path | None, rig: Path | None, rig_roles: str | None,
                  primer_roles: str | None, force: bool, options: dict[str, Any],
                  flags: dict[str, str]) -> None:
    """Every check of ``emotive generate`` that needs no model: outputs, files, emotion, flags.

    Imports no torch, so that a mistake is answered at once (arguments as for
    :func:`run_generate`; ``options`` the model options given, ``flags`` the command-line
    spelling of the emotion and checkpoint options).

    Raises:
        EmotiveError: the first mistake, in one line naming it.
    """
    from emotive.errors import ConfigError
    from emotive.io.outputs import PREVIEW_SUFFIXES, check_distinct, check_output
    from emotive.models.registry import ModelError, get_model

    check_output(out, GENERATE_OUT, "--out", force)
    if npz is not None:
        check_output(npz, (".npz",), "--npz", force)
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview", force)
    check_distinct([("--out", out), ("--npz", npz), ("--preview", preview)])
    entry = get_model(model)
    unknown = [FLAGS.get(k, k) for k in options if k not in entry.option_names]
    if unknown:
        takes = ", ".join(FLAGS.get(k, k) for k in entry.option_names) or "no model flags"
        raise ModelError(f"{' and '.join(unknown)}: model {model!r} does not take "
                         f"{'them' if len(unknown) > 1 else 'it'}; it takes {takes}")
    if "generator" not in entry.kinds:
        raise ModelError(f"--model {model}: it makes no new motion (it is a "
                         f"{', '.join(entry.kinds)}); use one of the generators")
    if checkpoint is not None and not checkpoint.is_file():
        raise ConfigError(f"{flags['checkpoint']} {checkpoint}: checkpoint not found, the file "
                          f"{'is a folder' if checkpoint.is_dir() else 'does not exist'}; "
                          "check the path")
    path_option(path)
    for option, file in (("--primer", primer), ("--rig", rig)):
        if file is not None:
            input_file(file, option)
    roles_option(rig_roles, "--rig-roles")
    roles_option(primer_roles, "--primer-roles")
    if emotion is not None:
        emotion_option(emotion, flags["emotion"])


def run_generate(model: str, out: Path, emotion: str | Path | None, seconds: float,
                 path: str | None = None, npz: Path | None = None, preview: Path | None = None,
                 primer: Path | None = None, seed: int = 0, checkpoint: Path | None = None,
                 unit: str = "auto", rig: Path | None = None, rig_roles: str | None = None,
                 primer_roles: str | None = None, force: bool = False,
                 flags: dict[str, str] | None = None, **options: Any) -> None:
    """The body of ``emotive generate`` (and of its deprecated spellings).

    Args:
        model: registry name of the generator.
        out: main output, ``.bvh``, ``.glb``/``.gltf`` or ``.npz``.
        emotion: anything :func:`~emotive.data.emotion.coerce_emotion` takes (default
            neutral).
        seconds: length of the motion; at most the model's ``capabilities.max_seconds``.
        path: ground path (:func:`emotive.paths.load_path`), or ``None`` for the model's own.
        npz: extra NPZ output.
        preview: extra preview output.
        primer: BVH clip to start from, on any rig (retargeted onto the model's).
        seed: random seed.
        checkpoint: weights instead of the model's default.
        unit: length unit of the BVH files read (``--unit``).
        rig: BVH file of the rig to retarget the output onto, or ``None`` for the model's.
        rig_roles: role map of ``rig`` (see :func:`emotive.core.roles.resolve_roles`).
        primer_roles: role map of ``primer``, for a primer on another rig than the model's.
        force: replace outputs that exist (``--force``).
        flags: the command-line spelling of ``"emotion"`` and ``"checkpoint"``, for
            messages (default ``--emotion``, ``--checkpoint``).
        **options: model options; ``None`` means not given.

    Raises:
        ModelError: an unknown model, or an option the model does not take.
        RequestError: ``seconds`` beyond the model's limit.
        EmotiveError: bad emotion, path, primer, rig or output, before anything is written
            (all but those that need the model before torch is imported).
    """
    flags = {"emotion": "--emotion", "checkpoint": "--checkpoint", **(flags or {})}
    given = {k: v for k, v in options.items() if v is not None}
    check_request(model, out, emotion, path, npz, preview, primer, checkpoint, rig, rig_roles,
                  primer_roles, force, given, flags)

    import math

    import torch
    from rich.console import Console

    from emotive.data.emotion import coerce_emotion
    from emotive.errors import EmotionError
    from emotive.models.registry import get_model
    from emotive.render.outputs import write_generated

    entry = get_model(model)
    ground = primer_motion = None
    if path is not None:
        from emotive.paths import load_path

        ground = load_path(path)
    if primer is not None:
        primer_motion = read_input(primer, unit)
        role_joints(primer_motion.skeleton, primer_roles, "--primer-roles")
    rig_motion = None
    if rig is not None:
        from emotive.retarget import resolve_rig

        rig_motion = read_input(rig, unit)
        role_joints(rig_motion.skeleton, rig_roles, "--rig-roles")
        resolve_rig(rig_motion.skeleton, rig_roles, f"--rig {rig}: target", "--rig-roles")
    # The generators step one motion a frame at a time: a second thread only adds overhead.
    torch.set_num_threads(1)
    generator = entry.load("generator", weights=checkpoint, **given)
    if primer_motion is not None:
        primer_motion = primer_on_rig(primer_motion, model_rig(generator), primer_roles)
    limit = generator.capabilities.max_seconds
    if not (math.isfinite(seconds) and 0 < seconds <= limit):
        from emotive.models.api import RequestError

        raise RequestError(f"--seconds {seconds:g}: model {model!r} makes at most {limit:g} s; "
                           f"give a length above 0 and up to {limit:g}")
    try:
        schedule = coerce_emotion(emotion if emotion is not None else "neutral",
                                  generator.labels)
    except EmotionError as exc:
        raise EmotionError(f"{flags['emotion']}: {exc}") from None
    from emotive.models.api import GenerationRequest

    request = GenerationRequest(out.stem, schedule=schedule, seconds=seconds, path=ground,
                                seed=seed, primer=primer_motion)
    console = Console(stderr=True)
    # Progress bars only on a terminal: elsewhere they leave blank lines around the messages.
    bars = console.is_terminal
    generated = generator.generate(request, progress=bars)
    if rig_motion is not None:
        generated = on_rig(generated, rig_motion, rig_roles)
    written = write_generated(generated, out, npz=npz, preview=preview, progress=bars)
    if generated.summary:
        console.print(generated.summary, highlight=False)
    for item in written:
        console.print(f"wrote {item}", highlight=False)


def generate(
    out: Annotated[Path, out_option("Output file: .bvh (the model's rig, or --rig), .glb/.gltf "
                                    "(with a skinned mannequin) or .npz (joint positions and "
                                    "per-frame emotion).")],
    model: Annotated[
        str, typer.Option("--model", "-m", help="Generator: gait (emotive gait network), "
                          "fcrbm (valence/arousal FCRBM) or lgb (end-effector resampling); "
                          "see `emotive models`."),
    ] = "gait",
    emotion: EmotionOpt = None,
    schedule: EmotionScheduleOpt = None,
    seconds: SecondsOpt = 20.0,
    path: Annotated[
        str | None,
        typer.Option("--path", help="Ground path: line, circle, figure8, zigzag or a JSON file "
                     "of (x, z) waypoints in metres (gait; default figure8).",
                     show_default=False),
    ] = None,
    preview: PreviewOpt = None,
    npz: Annotated[
        Path | None,
        typer.Option("--npz", help="Also write joint positions and emotion as .npz.",
                     show_default=False),
    ] = None,
    primer: PrimerOpt = None,
    primer_roles: Annotated[
        str | None,
        typer.Option("--primer-roles", help="Role map of a --primer on another rig than the "
                     "model's (it is retargeted onto the model's rig); default: detected.",
                     show_default=False),
    ] = None,
    rig: Annotated[
        Path | None,
        typer.Option("--rig", help="File of your character's rig (.bvh, .glb/.gltf or "
                     ".fbx): the motion is retargeted onto it (its joint names, bone lengths, "
                     "channels and unit).",
                     show_default=False),
    ] = None,
    rig_roles: Annotated[
        str | None,
        typer.Option("--rig-roles", help='Role map of --rig: a built-in name or a JSON file '
                     '{"role": "JointName", ...}; default: detected.', show_default=False),
    ] = None,
    unit: UnitOpt = "auto",
    seed: SeedOpt = 0,
    checkpoint: Annotated[
        Path | None,
        typer.Option("--checkpoint", help="Weights file instead of the model's built-in one.",
                     show_default=False),
    ] = None,
    raw: Annotated[
        bool, flag("raw", "gait: skip the foot-contact cleanup (planted feet pinned by "
                     "inverse kinematics): the network's output as it is."),
    ] = False,
    gibbs: Annotated[
        int | None,
        typer.Option("--gibbs", help="fcrbm: Gibbs iterations per frame (default: the "
                     "model's).", min=1, show_default=False),
    ] = None,
    root: Annotated[
        str | None,
        typer.Option("--root", help="fcrbm: 'feet' (default) rebuilds the root path from the "
                     "stance foot; 'model' keeps the model's own root velocity.",
                     show_default=False),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option("--workers", help="lgb: worker processes for the inverse kinematics (the "
                     "result does not depend on it); default: the idle cores, at most 2.",
                     min=1, show_default=False),
    ] = None,
    dataset: Annotated[
        str | None,
        typer.Option("--dataset", help="lgb: data set whose clips are resampled (default "
                     "bandai-namco-1).", show_default=False),
    ] = None,
    fps: Annotated[
        float | None,
        typer.Option("--fps", help="lgb: frame rate of the output (default: the data's, 30).",
                     min=1.0, max=240.0, show_default=False),
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Generate motion with an emotion (or a schedule of emotions) from a model."""
    from emotive.errors import EmotionError

    if emotion is not None and schedule is not None:
        raise EmotionError("give --emotion or --emotion-schedule, not both")
    run_generate(model, out, schedule if schedule is not None else emotion, seconds, path=path,
                 npz=npz, preview=preview, primer=primer, seed=seed, checkpoint=checkpoint,
                 unit=unit, rig=rig, rig_roles=rig_roles, primer_roles=primer_roles,
                 force=force, flags={"emotion": "--emotion-schedule" if schedule is not None
                                     else "--emotion"},
                 raw=True if raw else None,
                 gibbs=gibbs, root=root, workers=workers, dataset=dataset, fps=fps)
