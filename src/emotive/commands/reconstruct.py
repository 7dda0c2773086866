"""``emotive reconstruct``: rebuild a BVH clip from its own end-effector trajectories.

The paper's motion reconstruction task (issue 7; Carreno-Medrano et al., sections 5.1 and 6.1):
the pelvis path and the targets of the five chains (end effectors and elbows, in chain frames)
are taken from the clip, and the whole body is solved back from them alone by
:func:`emotive.ik.reconstruct`. The output is on the input's rig.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import (
    MOTION_OUT,
    ON_INPUT_RIG,
    ForceOpt,
    PreviewOpt,
    RolesOpt,
    UnitOpt,
    input_file,
    out_option,
    read_input,
    role_joints,
    roles_option,
)

if TYPE_CHECKING:
    from emotive.ik import IKResult


def summary(result: IKResult, fps: float, verb: str = "rebuilt") -> str:
    """One summary line of a reconstruction.

    One line: frames, clip and solve seconds, per-chain target residual, frames left off
    target after the solver's retries, and clamped targets.

    Args:
        result: the reconstruction.
        fps: the clip's frame rate.
        verb: what was done to the frames (``"rebuilt"``, ``"resampled and rebuilt"``).
    """
    import numpy as np

    from emotive.ik.solver import OFF_TARGET

    n = result.motion.num_frames
    residual = ", ".join(
        f"{name} {1000 * r.mean():.2f}/{1000 * r.max():.2f}" if len(r) else f"{name} -"
        for name, r in result.residuals.items()
    )
    clamped = [
        f"{name} {len(u)} ({', '.join(sorted(set(u.targets)))}; up to "
        f"{1000 * float(np.max(u.distances)):.1f} mm beyond reach)"
        for name, u in result.unreachable.items()
        if len(u)
    ]
    off = [
        f"{name} {len(f)} ({100 * len(f) / max(n, 1):.1f} %, up to "
        f"{1000 * float(result.residuals[name][f].max()):.0f} mm)"
        for name, f in result.off_target.items()
        if len(f)
    ]
    return (
        f"{n} frames ({n / fps:.2f} s) {verb} in {result.seconds:.2f} s "
        f"({result.ms_per_frame:.1f} ms/frame); target residual mean/max mm: {residual}; "
        f"frames off target by more than {1000 * OFF_TARGET:g} mm after retries: "
        f"{'; '.join(off) if off else 'none'}; "
        f"unreachable targets clamped: {'; '.join(clamped) if clamped else 'none'}"
    )


def reconstruct(
    input: Annotated[Path, typer.Argument(help="Clip to rebuild: .bvh, .glb/.gltf or .fbx.",
                                             show_default=False)],
    out: Annotated[Path, out_option(ON_INPUT_RIG)],
    role_map: RolesOpt = None,
    unit: UnitOpt = "auto",
    preview: PreviewOpt = None,
    force: ForceOpt = False,
) -> None:
    """Rebuild a clip from its own pelvis, end-effector and elbow trajectories by IK."""
    from emotive.io.outputs import PREVIEW_SUFFIXES, check_distinct, check_output

    check_output(out, MOTION_OUT, "--out", force)
    if preview is not None:
        check_output(preview, PREVIEW_SUFFIXES, "--preview", force)
    check_distinct([("--out", out), ("--preview", preview)])
    input_file(input)
    roles_option(role_map)

    from rich.console import Console

    from emotive.errors import BVHError, RigError
    from emotive.ik import IKError
    from emotive.ik import reconstruct as ik_reconstruct
    from emotive.io.atomic import output_transaction
    from emotive.io.motion_files import write_motion

    motion = read_input(input, unit)
    role_joints(motion.skeleton, role_map)
    if motion.num_frames == 0:
        raise BVHError(
            input,
            None,
            "holds no frames: there is nothing to rebuild; pass a clip with motion data",
        )
    console = Console(stderr=True)
    try:
        with console.status(f"rebuilding {input.name}: {motion.num_frames} frames ..."):
            result = ik_reconstruct(motion, role_map=role_map)
    except (RigError, IKError) as exc:
        # The IK names chains and roles; the user needs to know which file they belong to.
        raise type(exc)(f"{input}: {exc}") from None
    # The rebuilt clip keeps the input's metadata, so it is written in the input's length unit.
    rebuilt = result.motion
    with output_transaction():
        write_motion(rebuilt, out)
        if preview is not None:
            from emotive.render.preview import render_preview

            render_preview(rebuilt, preview, title=f"{input.name} rebuilt", progress=True)
    typer.echo(f"wrote {out}: {summary(result, motion.fps)}")
    if preview is not None:
        console.print(f"wrote {preview}")
