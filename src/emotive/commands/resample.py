"""``emotive resample``: new whole-body motion of one emotion, of any length.

The paper's second synthesis task (issue 7; Carreno-Medrano et al., sections 5.2, 5.3 and 6.2):
the end-effector, elbow and pelvis trajectories of every clip of the emotion are joined into one
closed sequence, resampled by the Local Grid Bootstrap
(:class:`emotive.models.lgb.model.EmotionResampler`) and rebuilt into whole-body motion by the
five IK chains, on the data's rig. The same seed gives the same file, whatever the number of
workers.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import PreviewOpt

if TYPE_CHECKING:
    from emotive.models.lgb.novelty import NoveltyReport

#: Longest motion one call makes, seconds (a day).
MAX_SECONDS = 86400.0
#: Output frame rates accepted by ``--fps``.
FPS_RANGE = (1.0, 240.0)
#: The data set read by default.
DATASET = "bandai-namco-1"


def idle_cores(most: int = 2) -> int:
    """Cores free for IK workers: the machine's cores less its 1-minute load, from 1 to
    ``most``. On a busy machine a second worker only competes with the first."""
    cores = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:  # not available on every platform
        load = 0.0
    return max(1, min(most, cores - math.floor(load)))


def novelty_line(report: NoveltyReport) -> str:
    """One line on the not-a-replay guard (:mod:`emotive.models.lgb.novelty`)."""
    head = (f"not a replay: {report.windows} 1-s windows checked against the captured clips, "
            f"closest {1000 * report.closest:.1f} mm (threshold {1000 * report.threshold:.1f} "
            f"mm); {report.redrawn} stretches redrawn")
    if report.below:
        return head + f"; {report.below} windows still at or below the threshold"
    return head


def check_request(emotion: str, seconds: float, fps: float | None) -> str:
    """Validate the command's numbers and emotion name before any data is read.

    Args:
        emotion: the emotion as typed.
        seconds: length of the motion.
        fps: output frame rate, or None for the data's.

    Returns:
        The emotion's canonical label.

    Raises:
        LGBError: ``seconds`` or ``fps`` not a finite number in range.
        EmotionError: an unknown emotion name.
    """
    import difflib

    from emotive.data.emotion import ALIASES, ALL_LABELS, canonical_label
    from emotive.errors import EmotionError
    from emotive.models.lgb.bootstrap import LGBError

    if not (math.isfinite(seconds) and 0.0 < seconds <= MAX_SECONDS):
        raise LGBError(f"--seconds {seconds}: give a finite length above 0 and at most "
                       f"{MAX_SECONDS:g} s, e.g. --seconds 600")
    if fps is not None and not (math.isfinite(fps) and FPS_RANGE[0] <= fps <= FPS_RANGE[1]):
        raise LGBError(f"--fps {fps}: give a frame rate from {FPS_RANGE[0]:g} to "
                       f"{FPS_RANGE[1]:g}, e.g. --fps 30, or leave it out for the data's rate")
    label = canonical_label(emotion)
    if label not in ALL_LABELS:
        close = difflib.get_close_matches(label, [*ALL_LABELS, *ALIASES], n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise EmotionError(f"--emotion {emotion!r}: unknown emotion{hint}; use one of "
                           f"{', '.join(ALL_LABELS)}")
    return label


def resample(
    emotion: Annotated[
        str,
        typer.Option("--emotion", "-e", help="Emotion to resample: happy, sad, angry, neutral "
                     "or another style of the data set.", show_default=False),
    ],
    out: Annotated[
        Path,
        typer.Option("--out", "-o", help="Output .bvh, on the data's rig.", show_default=False),
    ],
    seconds: Annotated[float, typer.Option("--seconds", help="Length of the motion.")] = 60.0,
    seed: Annotated[int, typer.Option(help="Seed of the draws: the same seed, the same file.")]
    = 0,
    preview: PreviewOpt = None,
    fps: Annotated[
        float | None,
        typer.Option("--fps", help="Frame rate of the output (default: the data's, 30).",
                     show_default=False),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(help="Worker processes for the inverse kinematics (the result does not "
                     "depend on it); default: the idle cores, at most 2.", min=1,
                     show_default=False),
    ] = None,
    dataset: Annotated[
        str, typer.Option(help="Data set whose clips are resampled.")
    ] = DATASET,
) -> None:
    """Resample an emotion's end-effector trajectories (Local Grid Bootstrap) into new
    whole-body motion of any length, rebuilt by inverse kinematics."""
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        Progress,
        SpinnerColumn,
        TextColumn,
        TimeElapsedColumn,
    )

    from emotive.commands.reconstruct import summary
    from emotive.data.clips import load_clips
    from emotive.io.bvh import write_bvh
    from emotive.models.gait.outputs import check_output
    from emotive.models.lgb.model import EmotionResampler

    label = check_request(emotion, seconds, fps)
    workers = workers or idle_cores()
    check_output(out, (".bvh",), "--out")
    if preview is not None:
        check_output(preview, (".mp4", ".gif"), "--preview")
    console = Console(stderr=True)
    with console.status(f"reading the {label} clips of {dataset} ..."):
        clips = load_clips(dataset)
        model = EmotionResampler.fit(clips, label, source=dataset)
    frames = max(1, round(seconds * model.fps))
    columns = (SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
               TextColumn("{task.completed}/{task.total} frames"), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=True) as bar:
        task = bar.add_task(f"resampling {label}: {frames} frames", total=frames)

        def advance(done: int, total: int) -> None:
            bar.update(task, completed=done,
                       description=f"rebuilding {label} by IK ({workers} workers)")

        result = model.generate(frames, seed, advance, workers=workers)
    motion = result.motion
    if fps is not None and abs(fps - motion.fps) > 1e-9:
        from emotive.core.ops import resample as resample_motion

        motion = resample_motion(motion, fps)
    write_bvh(motion, out)
    typer.echo(f"wrote {out}: {label}, seed {seed}: "
               f"{summary(result, model.fps, 'resampled and rebuilt')}")
    if result.novelty is not None:
        typer.echo(novelty_line(result.novelty))
    if preview is not None:
        from emotive.render.preview import render_preview

        render_preview(motion, preview, title=f"{label} resampled (seed {seed})", progress=True)
        console.print(f"wrote {preview}")
