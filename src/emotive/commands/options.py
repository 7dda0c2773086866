"""Command-line options shared by several commands, and the training commands' body.

Command-line options shared by several commands, each defined once with one name and help
text, and the shared body of the training commands (:func:`run_training`).

Use the options as parameter annotations with the command's own default, e.g.
``config: ConfigOpt = "gait"``. Numeric ranges never clamp: a value out of
range is a one-line error (:func:`emotive.cli.main`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer


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


def length_unit(value: str) -> str:
    """Option callback: ``auto`` or a length unit the BVH reader knows (aliases resolved).

    Raises:
        typer.BadParameter: an unknown unit.
    """
    from emotive.io.bvh_limits import UNITS

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
    (:func:`emotive.io.motion_files.read_motion`).

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
        OutputError: ``out`` is a file or its folder cannot be written (before any work).
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
