"""Command-line options shared by several commands, and the training commands' body.

Command-line options shared by several commands, each defined once with one name and help
text, and the shared body of the training commands (:func:`run_training`).

Use the options as parameter annotations with the command's own default, e.g.
``config: ConfigOpt = "gait"``. Numeric ranges never clamp: a value out of
range is a one-line error (:func:`emotive.cli.main`).

The checks of this module (:func:`input_file`, :func:`roles_option`, :func:`emotion_option`)
run before a command imports torch or loads a model, so that a mistake costs a fraction of
a second: they import nothing heavy.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from emotive.errors import BVHError, EmotiveError, MotionFileError, RigError

if TYPE_CHECKING:
    from emotive.core.skeleton import Skeleton

#: Suffixes of the motion files the commands read (``emotive.io.motion_files.READ_SUFFIXES``,
#: repeated so that the checks import no torch; a test checks that the two agree).
MOTION_IN = (".bvh", ".glb", ".gltf", ".fbx")
#: Suffixes of the motion files the commands write (``emotive.io.motion_files.MOTION_SUFFIXES``).
MOTION_OUT = (".bvh", ".glb", ".gltf")
#: Rig families ``--roles`` names (``emotive.core.rig_names.FAMILIES``, repeated likewise).
ROLE_FAMILIES = ("bandai", "cmu", "mixamo", "unreal", "unity", "vrm", "smpl", "smplx")


def input_file(path: Path, option: str = "", suffixes: tuple[str, ...] | None = MOTION_IN,
               error: type[EmotiveError] | None = None) -> None:
    """Fail fast on an input file that does not exist, is a folder or has a foreign suffix.

    Args:
        path: the file given on the command line.
        option: the option that named it (``"--rig"``), or ``""`` for an argument.
        suffixes: the suffixes the command reads, lower case with the dot; ``None``: any.
        error: the exception to raise; default: :class:`~emotive.errors.BVHError` for a
            ``.bvh`` file, :class:`~emotive.errors.MotionFileError` for another motion file.

    Raises:
        EmotiveError: one line naming the option, the file and the fix.
    """
    where = f"{option} {path}" if option else str(path)
    if not path.exists():
        problem = "does not exist; check the path"
    elif path.is_dir():
        problem = "is a folder; give a file" + (f" ending in {' or '.join(suffixes)}"
                                                if suffixes else "")
    elif suffixes is not None and path.suffix.lower() not in suffixes:
        given = f"{path.suffix!r} is not a format it reads" if path.suffix else "no suffix"
        problem = f"{given}; give a file ending in {' or '.join(suffixes)}"
    else:
        return
    if error is not None:
        raise error(f"{where} {problem}")
    if path.suffix.lower() == ".bvh":
        raise BVHError(where, None, problem)
    raise MotionFileError(where, problem)


def roles_option(value: str | None, option: str = "--roles") -> None:
    """Fail fast on a ``--roles`` that is neither a rig family nor a JSON file that parses.

    Raises:
        RigError: naming the option, the value and the fix (``not valid JSON`` with its line
            and column, ``does not exist``).
    """
    if value is None or value in ROLE_FAMILIES:
        return
    path = Path(value)
    if not path.is_file():
        what = "is a folder" if path.is_dir() else "does not exist"
        raise RigError(f"{option} {value}: no rig family has that name and the file {what}; "
                       f"give one of {', '.join(ROLE_FAMILIES)} or a JSON role map "
                       "(`emotive info FILE --roles-template` prints one)")
    try:
        json.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as exc:
        raise RigError(f"{option} {value} cannot be read ({exc}); check the file") from None
    except json.JSONDecodeError as exc:
        raise RigError(f"{option} {value} is not valid JSON (line {exc.lineno}, column "
                       f"{exc.colno}: {exc.msg}); fix it or print a new map with `emotive "
                       "info FILE --roles-template`") from None


#: The most joints :func:`role_joints` names in one message.
JOINTS_SHOWN = 4


def role_joints(skeleton: Skeleton, value: str | None, option: str = "--roles") -> None:
    """Fail on a JSON role map that names joints the rig does not have, naming them.

    Run after the rig is read, before anything is computed from it; a family or no map
    passes (their gaps are reported by :func:`emotive.core.roles.resolve_roles`).

    Raises:
        RigError: naming the map, each joint it names that the rig lacks (with its role), and
            a few of the rig's joints.
    """
    if value is None or value in ROLE_FAMILIES:
        return
    from emotive.core.roles import load_role_map, match_roles

    mapping = load_role_map(value)
    _, _, missing = match_roles(skeleton, mapping)
    absent = [f"{mapping[r]!r} (role {r})" for r in missing if r in mapping]
    if absent:
        more = (f" and {len(absent) - JOINTS_SHOWN} more" if len(absent) > JOINTS_SHOWN
                else "")
        names = ", ".join(skeleton.names[:6])
        raise RigError(f"{option} {value} names joints the rig does not have: "
                       f"{', '.join(absent[:JOINTS_SHOWN])}{more}; its joints are {names}, "
                       f"... ({skeleton.num_joints} in all): fix the names in the map")


def emotion_option(value: str | Path, option: str) -> None:
    """Fail fast on an emotion or schedule that does not parse, before a model is loaded.

    Read over every known label (:data:`emotive.data.emotion.ALL_LABELS`): the model's own
    labels are checked again once it is loaded.

    Raises:
        EmotionError: naming the option, the value and the fix.
    """
    from emotive.data.emotion import ALL_LABELS, coerce_emotion
    from emotive.errors import EmotionError

    try:
        coerce_emotion(value, ALL_LABELS)
    except EmotionError as exc:
        raise EmotionError(f"{option}: {exc}") from None




def positive(value: float | None) -> float | None:
    """Option callback: a finite number above 0 (or the option left out).

    Raises:
        typer.BadParameter: zero, negative, NaN or infinite.
    """
    import math

    if value is not None and not (math.isfinite(value) and value > 0):
        raise typer.BadParameter(f"{value:g} is not a finite number above 0.")
    return value


#: ``--out`` help of the commands that write a clip on the input's rig.
ON_INPUT_RIG = "Output on the input's rig: .bvh, or .glb/.gltf with a skinned mannequin."


def out_option(what: str) -> Any:
    """``--out``/``-o`` with the command's own description of the file.

    E.g. ``Annotated[Path, out_option("Output .bvh, on the input's rig.")]``.
    """
    return typer.Option("--out", "-o", help=what, show_default=False)


RolesOpt = Annotated[
    str | None,
    typer.Option("--roles", help="Role map of the input rig: a family (bandai, cmu, mixamo, "
                 "unreal, unity, vrm, smpl, smplx) or a JSON file "
                 '{"role": "JointName", ...}; default: detect the family from the joint names, '
                 "else from the rig's shape. `emotive info FILE --roles-template` prints a map "
                 "to edit.",
                 show_default=False),
]
#: Spellings of ``--unit`` beyond the reader's own names.
UNIT_ALIASES = {"inch": "in", "inches": "in", "metre": "m", "meter": "m"}
#: The length units the BVH reader knows (``emotive.io.bvh_limits.UNITS``, repeated so that
#: the option's check imports no torch; a test checks that the two agree).
UNITS = ("m", "cm", "mm", "in", "cmu")


def length_unit(value: str) -> str:
    """Option callback: ``auto`` or a length unit the BVH reader knows (aliases resolved).

    Raises:
        typer.BadParameter: an unknown unit.
    """
    unit = UNIT_ALIASES.get(value.lower(), value.lower())
    if unit != "auto" and unit not in UNITS:
        raise typer.BadParameter(f"{value!r} is not a length unit; use auto or one of "
                                 f"{', '.join([*UNITS, *UNIT_ALIASES])}.")
    return unit


UnitOpt = Annotated[
    str,
    typer.Option("--unit", callback=length_unit,
                 help="Length unit of the BVH file(s) read: auto (from the figure's standing "
                 "height, 1.2-2.2 m), m, cm, mm, in (inch) or cmu (CMU's 1/0.45 inch). "
                 "glTF and FBX files are in metres unless a unit is given."),
]
#: Largest ``--seed``: NumPy's generators take seeds of 32 bits.
SEED_MAX = 2**32 - 1
SeedOpt = Annotated[
    int, typer.Option("--seed", help="Random seed: the same seed gives the same output.",
                      min=0, max=SEED_MAX)
]


def flag(name: str, help: str) -> Any:
    """A boolean option spelled ``--NAME/--no-NAME``, shown in help without a value type.

    E.g. ``raw: Annotated[bool, flag("raw", "Skip the cleanup.")] = False``.
    """
    return typer.Option(f"--{name}/--no-{name}", help=help, metavar="")


#: ``--force`` of every command that writes files: the one rule for outputs that exist
#: (:func:`emotive.io.outputs.existing_output`).
ForceOpt = Annotated[bool, flag("force", "Replace output files that exist already (without "
                                "it the command stops before any work, naming them).")]
SecondsOpt = Annotated[
    float, typer.Option("--seconds", help="Length of the output, seconds (above 0).",
                        callback=positive),
]
PreviewOpt = Annotated[
    Path | None,
    typer.Option("--preview", help="Also write a stick-figure video: .mp4 or .gif.",
                 show_default=False),
]
EmotionOpt = Annotated[
    str | None,
    typer.Option("--emotion", "-e", help='A label "sad", a blend "happy=0.7,neutral=0.3", a '
                 'point "valence=0.5,arousal=-0.2" (-1..1) or a JSON keyframe file '
                 "(default neutral).", show_default=False),
]
EmotionScheduleOpt = Annotated[
    Path | None,
    typer.Option("--emotion-schedule", help='JSON keyframes, e.g. [{"t": 0, "emotion": '
                 '"angry"}, {"t": 10, "valence": 0.8, "arousal": 0.2}] (seconds).',
                 show_default=False),
]
PrimerOpt = Annotated[
    Path | None,
    typer.Option("--primer", help="Start from this clip, .bvh, .glb/.gltf or .fbx (any "
                 "humanoid rig: retargeted onto the model's) instead of the model's own start.",
                 show_default=False),
]
ConfigOpt = Annotated[
    str, typer.Option("--config", help=r"TOML file with \[model] and \[train] sections, or "
                      "the name of a shipped recipe (see emotive.configs).")
]
TrainOutOpt = Annotated[
    Path, typer.Option("--out", help="Folder for last.pt, best.pt and log.csv.")
]
ResumeOpt = Annotated[bool, flag("resume", "Continue from the folder's last.pt.")]
EpochsOpt = Annotated[
    int | None,
    typer.Option("--epochs", help=r"Epochs in all (default: the config's \[train] epochs).",
                 min=1, show_default=False),
]
NprocOpt = Annotated[
    int,
    typer.Option("--nproc", min=1, help="Training processes on this machine, data parallel "
                 "over the same global batch (1 to its CPUs). Several machines: start the "
                 "command with torchrun instead (see the docs)."),
]


def read_input(path: Path, unit: str = "auto"):
    """Read a motion or rig file given on the command line in the ``--unit`` the user chose.

    BVH, glTF (``.glb``/``.gltf``) or FBX (through Blender), by suffix
    (:func:`emotive.io.motion_files.read_motion`). Commands check the file with
    :func:`input_file` first, before their heavy imports.

    Raises:
        BVHError: a BVH file that cannot be read (see :func:`emotive.io.bvh.read_bvh`).
        MotionFileError: a glTF or FBX file that cannot be read, or FBX without Blender.
    """
    from emotive.io.motion_files import read_motion

    return read_motion(path, unit=unit)


def deprecated(old: str, new: str) -> None:
    """Print the one deprecation line of an old command spelling on stderr."""
    typer.echo(f"deprecated: `emotive {old}` is now `emotive {new}`; the old spelling goes in "
               "0.3", err=True)


def check_training(config: str | Path, out: Path, resume: bool, force: bool,
                   run_file: str = "last.pt") -> Path:
    """The checks of a training command before its heavy imports: folder, run, config.

    Args:
        config: the command's ``--config``.
        out: the command's ``--out`` folder.
        resume: the command's ``--resume`` (``False`` for a command without one).
        force: the command's ``--force``.
        run_file: the file whose presence marks a finished or stopped run in ``out``.

    Returns:
        The config file (:func:`emotive.configs.resolve_config`).

    Raises:
        OutputError: ``out`` cannot be a folder, or holds a run and neither ``resume`` nor
            ``force`` is given.
        ConfigError: no such config file or recipe.
    """
    from emotive.configs import resolve_config
    from emotive.errors import OutputError
    from emotive.io.outputs import check_output_folder

    check_output_folder(out, "--out")
    if not (resume or force) and (out / run_file).exists():
        fix = "--resume to continue it or " if run_file == "last.pt" else ""
        raise OutputError(f"--out {out} holds a training run already ({run_file}); add {fix}"
                          "--force to train again from the start, or choose another folder")
    path = resolve_config(config)
    if not path.is_file():
        from emotive.configs import recipe_names
        from emotive.errors import ConfigError

        what = "is a folder" if path.is_dir() else "does not exist"
        raise ConfigError(f"--config {config}: the file {what}; give a TOML file or one of the "
                          f"shipped recipes {', '.join(recipe_names())}")
    return path


def run_training(load: Callable[[Path], tuple[Any, Any]], train: Callable[..., Any],
                 config: str | Path, out: Path, resume: bool, seed: int,
                 epochs: int | None, nproc: int | None = None) -> Any:
    """Read a TOML config, override its epochs if given, and train with progress bars.

    Args:
        load: reads ``config`` into ``(model config, training settings)``.
        train: ``train(model_config, settings, progress=, out_dir=, resume=, seed=)``.
        config: the command's ``--config``: a TOML file or a shipped recipe's name
            (:func:`emotive.configs.resolve_config`).
        out: the command's ``--out``.
        resume: the command's ``--resume``.
        seed: the command's ``--seed``.
        epochs: the command's ``--epochs``; ``None`` keeps the config's.
        nproc: the command's ``--nproc``, for a trainer that runs on several processes (or
            under torchrun, :func:`emotive.models.distributed.run_parallel`); ``None``: a
            trainer of one process, refused under torchrun.

    Returns:
        What ``train`` returns; ``None`` on the processes of a torchrun job but the first.

    Raises:
        OutputError: ``out`` is a file or its folder cannot be written (before any work; the
            commands call :func:`check_training` first, before their heavy imports).
        ConfigError: a bad ``--nproc``, or ``--nproc`` or a one-process trainer under torchrun.
        TrainingProcessError: a training process failed; the others were stopped.
        typer.Exit: code 130 after Ctrl-C (``train`` has saved ``last.pt``).
    """
    from dataclasses import replace

    from emotive.configs import resolve_config
    from emotive.io.outputs import check_output_folder
    from emotive.models.distributed import one_process_only, run_parallel

    check_output_folder(out, "--out")
    model_config, settings = load(resolve_config(config))
    if epochs is not None:
        settings = replace(settings, epochs=epochs)
    try:
        if nproc is None:
            one_process_only()
            return train(model_config, settings, progress=True, out_dir=out, resume=resume,
                         seed=seed)
        return run_parallel(train, model_config, settings, nproc=nproc, progress=True,
                            out_dir=out, resume=resume, seed=seed)
    except KeyboardInterrupt:
        raise typer.Exit(130) from None
