"""``emotive transfer``: realtime style transfer of a BVH clip (Xia et al. 2015, MAR).

The clip, of any action and style, is translated frame by frame into a style or a blend of
styles (or a schedule of them) by online local mixtures of autoregressive models
(:mod:`emotive.models.mar`). The line it prints ends with the output's foot skate beside the
input's (the evaluation suite's measure, :func:`emotive.eval.feet.foot_skating`). The
database index is built once from the Bandai Namco data into ``$EMOTIVE_HOME/mar/``
(automatically on first use, or with ``--build-index``).

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import (
    MOTION_OUT,
    ON_INPUT_RIG,
    PreviewOpt,
    RolesOpt,
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
    from emotive.models.mar.database import MARDatabase


def open_index(index: Path | None, build: bool, force: bool) -> tuple[MARDatabase, Path]:
    """The style-transfer index at ``index``, built first if needed.

    The index at ``index`` (default location when None), built first if missing or if
    ``force``; a progress bar on stderr while building.
    """
    from rich.console import Console

    from emotive.models.mar.config import MARConfig
    from emotive.models.mar.database import MARDatabase
    from emotive.models.mar.default_index import build_default_index, default_index_path

    config = MARConfig()
    path = index if index is not None else default_index_path(config)
    if force or (not path.is_file() and (build or index is None)):
        Console(stderr=True).print(
            f"building the style-transfer index {path} from {', '.join(config.datasets)} "
            "(once; a few minutes)"
        )
        build_default_index(config, path, progress=True)
    return MARDatabase.load(path), path


def transfer(
    input: Annotated[
        Path | None, typer.Argument(help="Clip to translate: .bvh, .glb/.gltf or .fbx.",
                                    show_default=False)
    ] = None,
    style: Annotated[
        str | None,
        typer.Option("--style", help='Output style or blend, e.g. "proud=0.6,angry=0.4".',
                     show_default=False),
    ] = None,
    out: Annotated[Path | None, out_option(ON_INPUT_RIG)] = None,
    action: Annotated[
        str | None,
        typer.Option("--action", help="The input's action if known (walk, run, ...).",
                     show_default=False),
    ] = None,
    input_style: Annotated[
        str | None,
        typer.Option("--input-style", help="The input's style if known (neutral, ...).",
                     show_default=False),
    ] = None,
    rho: Annotated[
        float | None,
        typer.Option("--rho", help="Content kept for inputs unlike the data: 0 (pure style) "
                     "to 1; default 0.7.", min=0.0, max=1.0, show_default=False),
    ] = None,
    style_schedule: Annotated[
        Path | None,
        typer.Option("--style-schedule", help='JSON keyframes [{"t": 0, "emotion": "neutral"}, '
                     '{"t": 3, "emotion": "proud"}] (seconds of the input).', show_default=False),
    ] = None,
    preview: PreviewOpt = None,
    role_map: RolesOpt = None,
    unit: UnitOpt = "auto",
    index: Annotated[
        Path | None,
        typer.Option("--index", help="Index file (default: in $EMOTIVE_HOME/mar, built on "
                     "first use).", show_default=False),
    ] = None,
    build_index: Annotated[
        bool, typer.Option("--build-index", metavar="", help="Build the index (if missing) "
                     "and exit when no input is given.")
    ] = False,
    force: Annotated[
        bool, flag("force", "Replace outputs that exist already: --out and --preview, or, "
                   "with --build-index and no input, the index (rebuilt).")
    ] = False,
) -> None:
    """Translate a clip into another style, frame by frame.

    Translate a clip into another style, frame by frame (online local mixtures of
    autoregressive models).
    """
    from emotive.errors import EmotionError, OutputError
    from emotive.io.outputs import PREVIEW_SUFFIXES, check_distinct, check_output

    if input is None:
        if not build_index:
            raise OutputError("give an input clip (emotive transfer INPUT.bvh --style S --out "
                              "OUT.bvh) or --build-index")
        _, path = open_index(index, True, force)
        typer.echo(f"index ready: {path}")
        return
    if out is None:
        raise OutputError(f"{input}: give --out OUT.bvh for the translated clip")
    check_output(out, MOTION_OUT, "--out", force)
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview", force)
    check_distinct([("--out", out), ("--preview", preview)])
    input_file(input)
    roles_option(role_map)
    if (style is None) == (style_schedule is None):
        raise EmotionError(f"{input}: give exactly one of --style and --style-schedule")
    emotion_option(style if style is not None else style_schedule,
                   "--style" if style is not None else "--style-schedule")

    from rich.console import Console

    from emotive.data.emotion import EmotionSchedule
    from emotive.errors import BVHError
    from emotive.io.atomic import output_transaction
    from emotive.io.motion_files import write_motion
    from emotive.models.mar.config import TransferError
    from emotive.models.mar.transfer import parse_style, transfer_motion

    console = Console(stderr=True)
    motion = read_input(input, unit)
    if motion.num_frames == 0:
        raise BVHError(input, None, "holds no frames: there is nothing to translate")
    role_joints(motion.skeleton, role_map)
    db, _ = open_index(index, build_index, False)
    if style_schedule is not None:
        spec = EmotionSchedule.from_json(style_schedule, db.styles)
    else:
        try:
            parse_style(style, db)
        except TransferError as exc:
            raise TransferError(f"--style for {input}: {exc}") from None
        spec = style
    start = time.perf_counter()
    try:
        with console.status(f"translating {input.name}: {motion.num_frames} frames ..."):
            result = transfer_motion(motion, db, spec, action=action, input_style=input_style,
                                     rho=rho, role_map=role_map)
    except TransferError as exc:
        message = str(exc)
        raise type(exc)(message if str(input) in message else f"{input}: {message}") from None
    seconds = time.perf_counter() - start
    with output_transaction():
        write_motion(result.motion, out)
        if preview is not None:
            from emotive.render.preview import render_preview

            render_preview(result.motion, preview, title=f"{input.name} -> {spec}",
                           progress=True)
    n_in, n_out = motion.num_frames, result.motion.num_frames
    typer.echo(
        f"wrote {out}: {n_in} frames -> {n_out} frames ({result.motion.duration:.2f} s) in "
        f"style {result.motion.metadata['style']}; {1000 * seconds / n_in:.1f} ms/frame; "
        f"{result.feet_summary()}"
    )
    if preview is not None:
        console.print(f"wrote {preview}")
