"""``emotive info`` and ``emotive features``: look inside a BVH clip.

Heavy modules (torch through the kinematics, matplotlib) are imported inside the commands so
that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table
from rich.tree import Tree

from emotive.commands.options import RolesOpt, out_option
from emotive.errors import EmotiveError
from emotive.io.atomic import atomic_output
from emotive.io.outputs import check_output

#: Image formats ``--plot`` accepts.
PLOT_SUFFIXES = (".png", ".pdf", ".svg")

FileArg = Annotated[
    Path, typer.Argument(help="BVH file.", dir_okay=True, show_default=False)
]


def _role_rows(skeleton, role_map: str | None) -> tuple[str, dict[str, str | None], str | None]:
    """Map name, role -> joint (``None`` if missing) and the error text when roles are missing."""
    from emotive.core import roles as R

    name, index, missing = R.match_roles(skeleton, role_map)
    rows = {r: R.point_name(skeleton, index[r]) if r in index else None for r in R.ROLES}
    return name, rows, R.missing_roles_message(name, missing) if missing else None


def info(
    file: FileArg,
    roles: RolesOpt = None,
) -> None:
    """Describe a BVH clip: rig, roles, frames, duration and file-name labels."""
    from emotive.data.clips import parse_clip_name
    from emotive.io.bvh import read_bvh

    motion = read_bvh(file)
    sk = motion.skeleton
    console = Console()
    console.print(f"[bold]{file}[/bold]")
    console.print(
        f"frames: {motion.num_frames}   fps: {motion.fps:g}   "
        f"duration: {motion.duration:.2f} s   file unit: {motion.metadata.get('file_unit', '?')}"
    )
    labels = parse_clip_name(file)
    if labels:
        from emotive.data.emotion import VALENCE_AROUSAL, canonical_label

        label = canonical_label(labels["style"])
        emotion = label if label in VALENCE_AROUSAL else "none known"
        console.print(
            f"labels: dataset {labels['dataset']}, content [cyan]{labels['content']}[/cyan], "
            f"style [cyan]{labels['style']}[/cyan] (emotion label [cyan]{emotion}[/cyan]), "
            f"take {labels['take']}"
        )
    else:
        console.print("labels: none (name is not dataset-N_{content}_{style}_{take}.bvh)")

    n_ends = len(sk.end_site_parents)
    tree = Tree(f"rig: {sk.num_joints} joints, {n_ends} end sites")
    nodes: dict[int, Tree] = {}
    ends_of: dict[int, int] = {}
    for p in sk.end_site_parents:
        ends_of[int(p)] = ends_of.get(int(p), 0) + 1
    for j, name in enumerate(sk.names):
        parent = int(sk.parents[j])
        label = name + (f" [dim](+{ends_of[j]} end site)[/dim]" if j in ends_of else "")
        nodes[j] = (tree if parent < 0 else nodes[parent]).add(label)
    console.print(tree)

    map_name, rows, problem = _role_rows(sk, roles)
    table = Table(title=f"roles (map: {map_name})")
    table.add_column("role")
    table.add_column("joint")
    for role, joint in rows.items():
        table.add_row(role, joint if joint else "[red]missing[/red]")
    console.print(table)
    if problem:
        console.print(f"[red]roles not resolved:[/red] {problem}")


def features(
    file: FileArg,
    out: Annotated[Path, out_option("Output CSV, one row per frame.")],
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Also plot the features to this image (.png, .pdf, .svg).",
                     show_default=False),
    ] = None,
    roles: RolesOpt = None,
) -> None:
    """Write per-frame affective and movement features and foot contacts of a clip to CSV.

    Columns: time (s), the 18 affective features, the movement features (per frame, see
    emotive.features.movement) and the contacts (1 = foot on the ground), left then right.
    """
    import numpy as np

    from emotive.core.roles import resolve_roles
    from emotive.features.affective import (
        AFFECTIVE_FEATURE_KINDS,
        AFFECTIVE_FEATURE_NAMES,
        affective_features_np,
    )
    from emotive.features.contacts import CONTACT_NAMES, foot_contacts
    from emotive.features.movement import MOVEMENT_FEATURE_NAMES, movement_features
    from emotive.io.bvh import read_bvh

    check_output(out, None, "--out")
    if plot is not None:
        if plot.suffix.lower() not in PLOT_SUFFIXES:
            raise EmotiveError(
                f"--plot {plot}: unknown image type {plot.suffix!r}; use one of {PLOT_SUFFIXES}"
            )
        check_output(plot, PLOT_SUFFIXES, "--plot")
    motion = read_bvh(file)
    if motion.num_frames == 0:
        raise EmotiveError(f"{file} has no frames: nothing to compute")
    joint_roles = resolve_roles(motion.skeleton, roles)
    positions = motion.positions_with_end_sites()
    affective = affective_features_np(positions, joint_roles)
    contacts = foot_contacts(positions, joint_roles, motion.fps)
    movement = movement_features(positions, joint_roles, motion.fps, contacts=contacts)
    times = np.arange(motion.num_frames) / motion.fps
    table = np.column_stack((times, affective, movement.as_array(), contacts.astype(np.float64)))
    header = ",".join(("time", *AFFECTIVE_FEATURE_NAMES, *MOVEMENT_FEATURE_NAMES, *CONTACT_NAMES))
    n_float = table.shape[1] - 2
    fmt = ["%.9g"] * n_float + ["%d", "%d"]

    with atomic_output(out) as tmp:
        with open(tmp, "w", newline="\n") as fh:
            np.savetxt(fh, table, fmt=fmt, delimiter=",", header=header, comments="")
        if plot is not None:
            from emotive.render.plots import plot_features

            plot_features(
                plot, times, affective, AFFECTIVE_FEATURE_NAMES, AFFECTIVE_FEATURE_KINDS,
                movement.as_array(), MOVEMENT_FEATURE_NAMES, contacts, title=Path(file).name,
            )
    Console(stderr=True).print(
        f"wrote {out} ({motion.num_frames} frames x {table.shape[1]} columns)"
        + (f" and {plot}" if plot is not None else "")
    )
