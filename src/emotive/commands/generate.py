"""``emotive generate``: an emotive walk along a path, as BVH or NPZ, with an optional preview.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import PreviewOpt


def generate(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Output file: .bvh (the training rig) or .npz "
                           "(joint positions and per-frame emotion).", show_default=False),
    ],
    emotion: Annotated[
        str | None,
        typer.Option("--emotion", help='Emotion weights, e.g. "happy=0.7,neutral=0.3" '
                     "(default neutral).", show_default=False),
    ] = None,
    schedule: Annotated[
        Path | None,
        typer.Option("--emotion-schedule", help='JSON keyframes, e.g. [{"t": 0, "emotion": '
                     '{"angry": 1}}, {"t": 10, "emotion": {"happy": 1}}].', show_default=False),
    ] = None,
    path: Annotated[
        str, typer.Option("--path", help="line, circle, figure8, zigzag or a JSON file of "
                          "(x, z) waypoints in metres."),
    ] = "figure8",
    seconds: Annotated[
        float, typer.Option("--seconds", help="Length of the walk.", min=0.1, max=3600.0)
    ] = 20.0,
    preview: PreviewOpt = None,
    npz: Annotated[
        Path | None,
        typer.Option("--npz", help="Also write joint positions and emotion as .npz.",
                     show_default=False),
    ] = None,
    primer: Annotated[
        Path | None,
        typer.Option("--primer", help="Start from this BVH clip of the training rig instead "
                     "of the built-in standing start.", show_default=False),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the starting step phase.")] = 0,
    raw: Annotated[
        bool, typer.Option("--raw", help="Skip the foot-contact cleanup (planted feet pinned by "
                           "inverse kinematics): the network's output as it is."),
    ] = False,
    checkpoint: Annotated[
        Path | None,
        typer.Option("--checkpoint", help="Gait checkpoint (default: the pretrained model).",
                     show_default=False),
    ] = None,
) -> None:
    """Generate a walk that follows a path with an emotion (or a schedule of emotions)."""
    import torch
    from rich.console import Console

    from emotive.data.emotion import EmotionSchedule
    from emotive.errors import EmotionError
    from emotive.io.bvh import read_bvh
    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.outputs import check_output, write_walk
    from emotive.paths import load_path

    # One agent is a few small matrix products per frame: a second thread only adds overhead.
    torch.set_num_threads(1)
    if emotion is not None and schedule is not None:
        raise EmotionError("give --emotion or --emotion-schedule, not both")
    check_output(out, (".bvh", ".npz"), "--out")
    if npz is not None:
        check_output(npz, (".npz",), "--npz")
    if preview is not None:
        check_output(preview, (".mp4", ".gif"), "--preview")
    model = load_gait_model(checkpoint)
    ground = load_path(path)
    wanted = (EmotionSchedule.from_json(schedule, model.labels) if schedule is not None
              else emotion or "neutral")
    start = read_bvh(primer) if primer is not None else None
    from emotive.models.gait.generate import generate_walks

    walk = generate_walks(model, [ground], [wanted], seconds, seed=seed, primer=start,
                          progress=True, clean_feet=not raw)[0]
    written = write_walk(walk, out, npz=npz, preview=preview, progress=True)
    console = Console(stderr=True)
    for item in written:
        console.print(f"wrote {item}")
