"""``emotive generate``: new motion from a model of the registry.

As BVH or NPZ, with an optional preview.

``--model`` names a generator of :mod:`emotive.models.registry` (gait, the default; fcrbm;
lgb). The emotion goes through :func:`emotive.data.emotion.coerce_emotion` onto the model's
labels, the model makes a :class:`~emotive.models.api.Generated` and
:func:`emotive.render.outputs.write_generated` writes it. Each model-specific flag is defined
once here and passed through; a flag the chosen model does not take is an error naming it.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from emotive.commands.options import (
    EmotionOpt,
    EmotionScheduleOpt,
    PreviewOpt,
    PrimerOpt,
    SecondsOpt,
    SeedOpt,
    out_option,
)

#: The flag of each model option (registry name -> command line).
FLAGS = {"raw": "--raw", "gibbs": "--gibbs", "root": "--root", "workers": "--workers",
         "dataset": "--dataset", "fps": "--fps"}


def run_generate(model: str, out: Path, emotion: str | Path | None, seconds: float,
                 path: str | None = None, npz: Path | None = None, preview: Path | None = None,
                 primer: Path | None = None, seed: int = 0, checkpoint: Path | None = None,
                 **options: Any) -> None:
    """The body of ``emotive generate`` (and of its deprecated spellings).

    Args:
        model: registry name of the generator.
        out: main output, ``.bvh`` or ``.npz``.
        emotion: anything :func:`~emotive.data.emotion.coerce_emotion` takes (default
            neutral).
        seconds: length of the motion; at most the model's ``capabilities.max_seconds``.
        path: ground path (:func:`emotive.paths.load_path`), or ``None`` for the model's own.
        npz: extra NPZ output.
        preview: extra preview output.
        primer: BVH clip to start from.
        seed: random seed.
        checkpoint: weights instead of the model's default.
        **options: model options; ``None`` means not given.

    Raises:
        ModelError: an unknown model, or an option the model does not take.
        RequestError: ``seconds`` beyond the model's limit.
        EmotiveError: bad emotion, path, primer or output, before anything is written.
    """
    import math

    import torch
    from rich.console import Console

    from emotive.data.emotion import coerce_emotion
    from emotive.io.outputs import PREVIEW_SUFFIXES, check_output
    from emotive.models.registry import ModelError, get_model
    from emotive.render.outputs import OUT_SUFFIXES, write_generated

    check_output(out, OUT_SUFFIXES, "--out")
    if npz is not None:
        check_output(npz, (".npz",), "--npz")
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview")
    entry = get_model(model)
    given = {k: v for k, v in options.items() if v is not None}
    unknown = [FLAGS.get(k, k) for k in given if k not in entry.option_names]
    if unknown:
        takes = ", ".join(FLAGS.get(k, k) for k in entry.option_names) or "no model flags"
        raise ModelError(f"{' and '.join(unknown)}: model {model!r} does not take "
                         f"{'them' if len(unknown) > 1 else 'it'}; it takes {takes}")
    if "generator" not in entry.kinds:
        raise ModelError(f"--model {model}: it makes no new motion (it is a "
                         f"{', '.join(entry.kinds)}); use one of the generators")
    ground = primer_motion = None
    if path is not None:
        from emotive.paths import load_path

        ground = load_path(path)
    if primer is not None:
        from emotive.io.bvh import read_bvh

        primer_motion = read_bvh(primer)
    # The generators step one motion a frame at a time: a second thread only adds overhead.
    torch.set_num_threads(1)
    generator = entry.load("generator", weights=checkpoint, **given)
    limit = generator.capabilities.max_seconds
    if not (math.isfinite(seconds) and 0 < seconds <= limit):
        from emotive.models.api import RequestError

        raise RequestError(f"--seconds {seconds:g}: model {model!r} makes at most {limit:g} s; "
                           f"give a length above 0 and up to {limit:g}")
    schedule = coerce_emotion(emotion if emotion is not None else "neutral", generator.labels)
    from emotive.models.api import GenerationRequest

    request = GenerationRequest(out.stem, schedule=schedule, seconds=seconds, path=ground,
                                seed=seed, primer=primer_motion)
    console = Console(stderr=True)
    # Progress bars only on a terminal: elsewhere they leave blank lines around the messages.
    bars = console.is_terminal
    generated = generator.generate(request, progress=bars)
    written = write_generated(generated, out, npz=npz, preview=preview, progress=bars)
    if generated.summary:
        console.print(generated.summary, highlight=False)
    for item in written:
        console.print(f"wrote {item}", highlight=False)


def generate(
    out: Annotated[Path, out_option("Output file: .bvh (the model's rig) or .npz (joint "
                                    "positions and per-frame emotion).")],
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
    seed: SeedOpt = 0,
    checkpoint: Annotated[
        Path | None,
        typer.Option("--checkpoint", help="Weights file instead of the model's built-in one.",
                     show_default=False),
    ] = None,
    raw: Annotated[
        bool, typer.Option("--raw", help="gait: skip the foot-contact cleanup (planted feet "
                           "pinned by inverse kinematics): the network's output as it is."),
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
) -> None:
    """Generate motion with an emotion (or a schedule of emotions) from a model."""
    from emotive.errors import EmotionError

    if emotion is not None and schedule is not None:
        raise EmotionError("give --emotion or --emotion-schedule, not both")
    run_generate(model, out, schedule if schedule is not None else emotion, seconds, path=path,
                 npz=npz, preview=preview, primer=primer, seed=seed, checkpoint=checkpoint,
                 raw=True if raw else None, gibbs=gibbs, root=root, workers=workers,
                 dataset=dataset, fps=fps)
