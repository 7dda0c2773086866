"""``emotive preview``: a stick-figure video of a BVH clip.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    ForceOpt,
    UnitOpt,
    input_file,
    out_option,
    positive,
    read_input,
)


def preview(
    file: Annotated[Path, typer.Argument(help="Motion file: .bvh, .glb/.gltf or .fbx.",
                                            show_default=False)],
    out: Annotated[Path, out_option("Output video: .mp4 or .gif.")],
    path: Annotated[
        str | None,
        typer.Option("--path", help="Also draw a ground path: line, circle, figure8, zigzag or "
                     "a JSON file of [x, z] waypoints in metres.", show_default=False),
    ] = None,
    caption: Annotated[
        str | None, typer.Option("--caption", help="Text shown beside the time.")
    ] = None,
    fps: Annotated[
        float | None,
        typer.Option("--fps", help="Output frame rate (default: the clip's, at most 30).",
                     callback=positive, max=240.0, show_default=False),
    ] = None,
    width: Annotated[int, typer.Option(help="Width in pixels.", min=64, max=3840)] = 640,
    height: Annotated[int, typer.Option(help="Height in pixels.", min=64, max=2160)] = 480,
    unit: UnitOpt = "auto",
    force: ForceOpt = False,
) -> None:
    """Render a clip as a stick figure following the character, with its trail on the ground."""
    from emotive.commands.generate import path_option
    from emotive.io.outputs import PREVIEW_SUFFIXES, check_output

    check_output(out, PREVIEW_SUFFIXES, "--out", force)
    input_file(file)
    path_option(path)

    from rich.console import Console

    from emotive.paths import load_path
    from emotive.render.preview import render_preview

    ground = load_path(path).points if path is not None else None
    motion = read_input(file, unit)
    captions = [caption] * motion.num_frames if caption else None
    render_preview(
        motion, out, path_xz=ground, captions=captions, title=file.name, fps=fps,
        size=(width, height), progress=True,
    )
    Console(stderr=True).print(f"wrote {out} ({motion.duration:.1f} s)")
