"""``emotive retarget``: play a BVH clip on another humanoid rig.

The clip's rest pose and the rig's are aligned bone by bone through the joint roles, the
clip's world rotations are carried across, bones keep the rig's lengths, the root motion is
scaled by the ratio of leg lengths and planted feet are kept planted by IK
(:func:`emotive.retarget.retarget`). The output has the rig's joint names, hierarchy,
offsets, channel order and length unit; only the rig file's skeleton is used, not its frames.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from emotive.commands.options import (
    MOTION_OUT,
    ForceOpt,
    RolesOpt,
    UnitOpt,
    input_file,
    length_unit,
    out_option,
    positive,
    read_input,
    role_joints,
    roles_option,
)

if TYPE_CHECKING:
    from emotive.core.motion import Motion


def summary(source: Motion, result: Motion, rig: Path, role_map: str | None = None,
            to_roles: str | None = None) -> str:
    """One line: frames, the rig, the leg-length scale and the foot skate before and after.

    Args:
        source: the input clip.
        result: the retargeted clip.
        rig: the rig file.
        role_map: the input's role map (``--roles``).
        to_roles: the rig's role map (``--to-roles``).
    """
    from emotive.retarget import foot_skate

    before, after = foot_skate(source, role_map), foot_skate(result, to_roles)
    ratio = f" ({after / before:.2f}x)" if before > 0 else ""
    return (
        f"{result.num_frames} frames ({result.duration:.2f} s at {result.fps:g} fps) on "
        f"{rig.name} ({result.skeleton.num_joints} joints, {result.metadata.get('file_unit')}); "
        f"leg-length scale {result.metadata['leg_scale']:.3f}; foot skate "
        f"{before:.3f} -> {after:.3f} m/s{ratio}"
    )


def retarget(
    input: Annotated[Path, typer.Argument(help="Clip to retarget: .bvh, .glb/.gltf or .fbx.",
                                             show_default=False)],
    to: Annotated[
        Path,
        typer.Option("--to", help="File of the target rig, .bvh, .glb/.gltf or .fbx (its "
                     "skeleton is used, not its frames).", show_default=False),
    ],
    out: Annotated[Path, out_option("Output .bvh (the --to rig's joint names, channel order "
                                    "and unit) or .glb/.gltf (with a skinned mannequin).")],
    fps: Annotated[
        float | None,
        typer.Option("--fps", help="Frame rate of the output (default: the input's).",
                     callback=positive, show_default=False),
    ] = None,
    role_map: RolesOpt = None,
    to_roles: Annotated[
        str | None,
        typer.Option("--to-roles", help='Role map of the --to rig: a built-in name or a JSON '
                     'file {"role": "JointName", ...}; default: detected.', show_default=False),
    ] = None,
    unit: UnitOpt = "auto",
    to_unit: Annotated[
        str,
        typer.Option("--to-unit", callback=length_unit, help="Length unit of the --to rig "
                     "file, as --unit (the output is written in it)."),
    ] = "auto",
    force: ForceOpt = False,
) -> None:
    """Play a clip on another humanoid rig: rest poses aligned per bone, feet kept planted."""
    from emotive.io.outputs import check_output

    check_output(out, MOTION_OUT, "--out", force)
    input_file(input)
    input_file(to, "--to")
    roles_option(role_map)
    roles_option(to_roles, "--to-roles")

    from emotive.errors import BVHError, RigError
    from emotive.io.motion_files import write_motion
    from emotive.retarget import retarget as retarget_motion

    motion = read_input(input, unit)
    rig = read_input(to, to_unit)
    role_joints(motion.skeleton, role_map)
    role_joints(rig.skeleton, to_roles, "--to-roles")
    if motion.num_frames == 0:
        raise BVHError(input, None, "holds no frames: there is nothing to retarget; pass a "
                       "clip with motion data")
    try:
        result = retarget_motion(motion, rig, role_map, to_roles, fps=fps)
    except RigError as exc:
        raise RigError(f"{input} -> {to}: {exc}") from None
    write_motion(result, out)
    typer.echo(f"wrote {out}: {summary(motion, result, to, role_map, to_roles)}")
