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

from emotive.commands.options import (
    ForceOpt,
    RolesOpt,
    UnitOpt,
    input_file,
    out_option,
    read_input,
    role_joints,
    roles_option,
)
from emotive.errors import EmotiveError
from emotive.io.atomic import atomic_output, output_transaction
from emotive.io.outputs import check_distinct, check_output

#: Image formats ``--plot`` accepts.
PLOT_SUFFIXES = (".png", ".pdf", ".svg")
#: The format ``features --out`` writes.
TABLE_SUFFIXES = (".csv",)

FileArg = Annotated[
    Path, typer.Argument(help="Motion file: .bvh, .glb, .gltf or .fbx.", dir_okay=True,
                         show_default=False)
]


#: Extra joints listed by name before ``info`` shortens the list.
EXTRAS_SHOWN = 12


def _role_rows(skeleton, role_map: str | None) -> tuple[str, dict[str, str | None], str | None]:
    """Map name, role -> joint (``None`` if missing) and the error text when roles are missing."""
    from emotive.core import roles as R

    try:
        joint_roles = R.resolve_roles(skeleton, role_map)
    except EmotiveError as exc:
        name, index, _ = R.match_roles(skeleton, role_map)
        rows = {r: R.point_name(skeleton, index[r]) if r in index else None for r in R.ROLES}
        return name, rows, str(exc)
    return joint_roles.map_name, dict(joint_roles.names), None


def _extras_line(skeleton, rows: dict[str, str | None]) -> str:
    """``extra joints: N (a, b, ... and M more)``: the joints that play no role."""
    used = {j.removesuffix("/end") for j in rows.values() if j}
    extras = [n for n in skeleton.names if n not in used]
    if not extras:
        return "extra joints: none"
    shown = ", ".join(extras[:EXTRAS_SHOWN])
    more = f" and {len(extras) - EXTRAS_SHOWN} more" if len(extras) > EXTRAS_SHOWN else ""
    return f"extra joints: {len(extras)} ({shown}{more})"


def info(
    file: FileArg,
    roles: RolesOpt = None,
    unit: UnitOpt = "auto",
    roles_template: Annotated[
        bool,
        typer.Option("--roles-template", metavar="",
                     help="Print the rig's role map as JSON (detected joints filled in, missing "
                     "roles null) to edit and pass back with --roles, and nothing else."),
    ] = False,
) -> None:
    """Describe a BVH clip: rig family, roles, extra joints, height, unit, frames and labels.

    With ``--roles`` the map must fit the rig: a map naming a joint the rig lacks is an error
    naming it, printed before anything else.
    """
    input_file(file)
    roles_option(roles)
    from emotive.data.clips import parse_clip_name

    motion = read_input(file, unit)
    sk = motion.skeleton
    role_joints(sk, roles)
    if roles_template:
        import json

        from emotive.core.roles import role_template

        typer.echo(json.dumps(role_template(sk, roles), indent=2))
        return
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
    console.print(f"rig family: [cyan]{map_name}[/cyan]" + (
        " (from the rig's shape: no family's joint names fit)" if map_name == "topology" else ""))
    height = motion.metadata.get("height_m")
    if height is not None:
        console.print(f"height: {height:.2f} m (standing, from the rig; file unit: "
                      f"{motion.metadata.get('file_unit', '?')})")
    table = Table(title=f"roles (map: {map_name})")
    table.add_column("role")
    table.add_column("joint")
    for role, joint in rows.items():
        table.add_row(role, joint if joint else "[red]missing[/red]")
    console.print(table)
    console.print(_extras_line(sk, rows), markup=False)
    if problem:
        console.print(f"[red]roles not resolved:[/red] {problem}", markup=True)


def features(
    file: FileArg,
    out: Annotated[Path, out_option("Output .csv, one row per frame.")],
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Also plot the features to this image (.png, .pdf, .svg).",
                     show_default=False),
    ] = None,
    roles: RolesOpt = None,
    unit: UnitOpt = "auto",
    force: ForceOpt = False,
) -> None:
    """Write per-frame affective and movement features and foot contacts of a clip to CSV.

    Columns: time (s), the 18 affective features, the movement features (per frame, see
    emotive.features.movement) and the contacts (1 = foot on the ground), left then right.
    """
    check_output(out, TABLE_SUFFIXES, "--out", force)
    if plot is not None:
        check_output(plot, PLOT_SUFFIXES, "--plot", force)
    check_distinct([("--out", out), ("--plot", plot)])
    input_file(file)
    roles_option(roles)

    import numpy as np

    from emotive.core.roles import resolve_roles
    from emotive.features.affective import (
        AFFECTIVE_FEATURE_KINDS,
        AFFECTIVE_FEATURE_NAMES,
        affective_features_np,
    )
    from emotive.features.contacts import CONTACT_NAMES, foot_contacts
    from emotive.features.movement import MOVEMENT_FEATURE_NAMES, movement_features

    motion = read_input(file, unit)
    if motion.num_frames == 0:
        raise EmotiveError(f"{file} has no frames: nothing to compute")
    role_joints(motion.skeleton, roles)
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

    with output_transaction():
        with atomic_output(out) as tmp, open(tmp, "w", newline="\n") as fh:
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
