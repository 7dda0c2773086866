"""``emotive fcrbm train`` and ``emotive fcrbm generate``: the valence/arousal FCRBM (issue 6).

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import (
    ConfigOpt,
    EpochsOpt,
    PreviewOpt,
    ResumeOpt,
    TrainOutOpt,
    run_training,
)

app = typer.Typer(help="Valence/arousal-controlled movement with a factored conditional RBM.",
                  no_args_is_help=True, add_completion=False)


@app.command("train")
def train(
    config: ConfigOpt = Path("configs/fcrbm.toml"),
    out: TrainOutOpt = Path("models/fcrbm"),
    resume: ResumeOpt = False,
    seed: Annotated[int, typer.Option(help="Seed of initialization, batches and samples.")] = 0,
    epochs: EpochsOpt = None,
) -> None:
    """Train the FCRBM by contrastive divergence on walks of every style with a valence/arousal
    entry (Ctrl-C saves; --resume continues)."""
    from rich.console import Console

    from emotive.models.fcrbm.training import load_fcrbm_settings, train_fcrbm

    result = run_training(load_fcrbm_settings, train_fcrbm, config, out, resume, seed, epochs)
    last = result.history[-1] if result.history else {}
    Console(stderr=True).print(
        f"wrote {out / 'last.pt'}, {out / 'best.pt'} and {out / 'log.csv'}: "
        f"{len(result.history)} epochs, last reconstruction error "
        f"{last.get('train_reconstruction', float('nan')):.4g}, best validation one-step error "
        f"{result.best_val:.4g}"
    )


@app.command("generate")
def generate(
    out: Annotated[
        Path, typer.Option("--out", "-o", help="Output .bvh on the training rig.",
                           show_default=False)
    ],
    valence: Annotated[
        float | None,
        typer.Option(help="Valence, 1 low .. 2 neutral .. 3 high (beyond exaggerates).",
                     show_default=False),
    ] = None,
    arousal: Annotated[
        float | None,
        typer.Option(help="Arousal, 1 low .. 2 neutral .. 3 high (beyond exaggerates).",
                     show_default=False),
    ] = None,
    emotion: Annotated[
        str | None,
        typer.Option(help='An emotion instead, e.g. "sad" or "happy=0.5,angry=0.5", converted '
                          "through the project's valence/arousal table.", show_default=False),
    ] = None,
    schedule: Annotated[
        Path | None,
        typer.Option(help='JSON keyframes [{"t": 0, "valence": 3, "arousal": 1}, '
                          '{"t": 10, "emotion": "sad"}] (seconds), interpolated linearly.',
                     show_default=False),
    ] = None,
    seconds: Annotated[float, typer.Option(help="Length of the output.", min=0.1)] = 20.0,
    primer: Annotated[
        Path | None,
        typer.Option(help="BVH clip on the training rig whose last frames start the motion "
                          "(default: the data's mean frame, warmed up).", show_default=False),
    ] = None,
    model: Annotated[
        Path | None,
        typer.Option("--model", help="FCRBM checkpoint (default: the built-in one).",
                     show_default=False),
    ] = None,
    gibbs: Annotated[
        int | None,
        typer.Option(help="Gibbs iterations per frame (default: the model's).", min=1,
                     show_default=False),
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of the hidden samples.")] = 0,
    root: Annotated[
        str,
        typer.Option(help="Root path: 'feet' rebuilds it from the stance foot so the root "
                          "cannot glide while the legs stand (a post-process); 'model' keeps "
                          "the model's own root velocity."),
    ] = "feet",
    preview: PreviewOpt = None,
) -> None:
    """Generate movement for a valence/arousal point, an emotion, or a schedule of them."""
    import numpy as np
    from rich.console import Console

    from emotive.io.bvh import read_bvh, write_bvh
    from emotive.models.fcrbm.generate import (
        FCRBMInputError,
        constant_context,
        emotion_context,
        generate_motion,
        load_fcrbm_model,
        schedule_context,
    )
    from emotive.models.gait.outputs import check_output

    check_output(out, (".bvh",), "--out")
    if preview is not None:
        check_output(preview, (".mp4", ".gif"), "--preview")
    given = [name for name, value in (("--valence/--arousal", valence if valence is not None
                                       else arousal), ("--emotion", emotion),
                                      ("--schedule", schedule)) if value is not None]
    if len(given) != 1:
        raise FCRBMInputError(
            "give exactly one of --valence and --arousal, --emotion or --schedule"
            + (f" (got {' and '.join(given)})" if given else ""))
    if (valence is None) != (arousal is None):
        raise FCRBMInputError("give both --valence and --arousal (1 low, 2 neutral, 3 high)")
    fcrbm = load_fcrbm_model(model)
    frames = max(1, round(seconds * fcrbm.fps))
    if schedule is not None:
        context = schedule_context(schedule, frames, fcrbm.fps)
    elif emotion is not None:
        context = constant_context(*emotion_context(emotion), frames)
    else:
        context = constant_context(valence, arousal, frames)
    start = read_bvh(primer) if primer is not None else None
    console = Console(stderr=True)
    with console.status(f"generating {frames} frames ..."):
        motion, _ = generate_motion(fcrbm, context, seed=seed, primer=start, gibbs=gibbs,
                                    name=out.stem, root=root)
    write_bvh(motion, out)
    v, a = np.round(context[0], 2), np.round(context[-1], 2)
    typer.echo(f"wrote {out}: {motion.num_frames} frames ({motion.num_frames / motion.fps:.1f} s)"
               f", valence/arousal {v.tolist()}" + (f" to {a.tolist()}" if schedule else ""))
    if preview is not None:
        from emotive.render.preview import render_preview

        captions = [f"valence {z[0]:.2f} arousal {z[1]:.2f}" for z in context]
        render_preview(motion, preview, captions=captions, title=f"{out.name}: FCRBM",
                       progress=True)
        Console(stderr=True).print(f"wrote {preview}")
