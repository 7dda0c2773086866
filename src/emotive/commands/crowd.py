"""``emotive crowd SCENE.toml``: a crowd walking a scene, written as files.

Writes into ``--out DIR``: one BVH per agent (``agent-NNNN.bvh``, from the agent's first frame
to its last), ``agents.csv`` (each agent's group, emotion, pace, first and last frame, whether
it met its goal), ``trajectories.csv`` (PedPy's text format: ``# framerate`` header, rows
``id frame x y``, the body's root on the ground in metres), ``navigation.csv`` (the same for
the navigation agents), ``scene.json`` (the scene as run) and ``preview.mp4`` (a top view).
Every file is written atomically and all together: a bad scene or a failure writes nothing.

Heavy modules (torch, JuPedSim, matplotlib) are imported inside the command, so that
``emotive --help`` stays fast and never loads JuPedSim.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import SecondsOpt, SeedOpt, flag


def run_crowd(scene_path: Path, seconds: float, out: Path, seed: int = 0,
              avoidance: bool = True, preview: bool = True, progress: bool = True,
              navigation: str = "cfs") -> list[Path]:
    """The body of ``emotive crowd``; returns the written files.

    Raises:
        SceneError: a bad scene (nothing written). OutputError: ``out`` cannot be written.
    """
    import csv
    import io
    import json
    import sys
    import time

    import numpy as np

    from emotive.crowd.crowd import Crowd
    from emotive.crowd.scene import load_scene
    from emotive.crowd.trajectories import Recording, trajectory_text
    from emotive.data.emotion import DEFAULT_LABELS, valence_arousal, weights_from_valence_arousal
    from emotive.errors import OutputError
    from emotive.io.atomic import atomic_output, check_writable, output_transaction
    from emotive.io.bvh import write_bvh
    from emotive.models.gait.model import load_gait_model

    scene = load_scene(scene_path)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: a file has that name; give a folder")
    model = load_gait_model()
    crowd = Crowd(scene, model=model, seed=seed, avoidance=avoidance, navigation=navigation)
    frames = max(1, round(seconds * crowd.fps))
    record = Recording(model.controls.skeleton, crowd.fps)
    nav_rows = []
    start = time.monotonic()
    for f in range(frames):
        frame = crowd.step()
        record.add(frame)
        nav_rows.extend((a, frame.index, *frame.navigation[k]) for k, a in enumerate(frame.agents))
        if progress and (f + 1) % round(5 * crowd.fps) == 0:
            print(f"crowd: {(f + 1) / crowd.fps:.0f}/{seconds:g} s, {len(frame.agents)} agents, "
                  f"{time.monotonic() - start:.0f} s", file=sys.stderr, flush=True)
    reached = crowd.goal_reached()
    out.mkdir(parents=True, exist_ok=True)
    check_writable(out)
    with output_transaction() as transaction:
        table = io.StringIO()
        writer = csv.writer(table, lineterminator="\n")
        writer.writerow(["id", "group", "emotion", "label", "pace", "first_frame", "last_frame",
                         "reached", "file"])
        for a in sorted(record.tracks):
            info = crowd.info(a)
            name = f"agent-{a:04d}.bvh"
            write_bvh(record.motion(a), out / name)
            w = np.mean(np.stack(record.tracks[a].emotion[:1]), 0)
            mix = weights_from_valence_arousal(valence_arousal(w, crowd.labels), DEFAULT_LABELS)
            writer.writerow([a, info.group, info.emotion, DEFAULT_LABELS[int(np.argmax(mix))],
                             f"{info.pace:.3f}", record.tracks[a].first,
                             record.tracks[a].first + len(record.tracks[a].root) - 1,
                             int(reached[a]), name])
        with atomic_output(out / "agents.csv") as tmp:
            tmp.write_text(table.getvalue(), encoding="utf-8")
        with atomic_output(out / "trajectories.csv") as tmp:
            tmp.write_text(trajectory_text(record.table(), crowd.fps), encoding="utf-8")
        nav = np.asarray(nav_rows, dtype=np.float64).reshape(-1, 4)
        nav = nav[np.lexsort((nav[:, 0], nav[:, 1]))]
        with atomic_output(out / "navigation.csv") as tmp:
            tmp.write_text(trajectory_text(nav, crowd.fps), encoding="utf-8")
        with atomic_output(out / "scene.json") as tmp:
            run = {"seed": seed, "avoidance": avoidance, "navigation": navigation}
            tmp.write_text(json.dumps({**scene.to_dict(), **run}, indent=1), encoding="utf-8")
        if preview:
            from emotive.render.crowd_view import render_crowd

            tracks = {a: (t.first, np.stack(t.root), np.stack(t.emotion))
                      for a, t in record.tracks.items()}
            render_crowd(out / "preview.mp4", scene.area, scene.obstacles, tracks,
                         record.frames, crowd.fps, crowd.labels, progress=progress)
    return list(transaction.written)


def crowd(
    scene: Annotated[Path, typer.Argument(help="The scene: a scene.toml (see docs/crowd.md).",
                                          show_default=False)],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder to write into (created).",
                                      show_default=False)],
    seconds: SecondsOpt = 30.0,
    seed: SeedOpt = 0,
    avoidance: Annotated[
        bool, flag("avoidance", "Agents avoid each other; --no-avoidance walks them straight "
                   "through each other (the baseline that measures what avoidance saves)."),
    ] = True,
    preview: Annotated[bool, flag("preview", "Write the top-view preview.mp4.")] = True,
    navigation: Annotated[
        str, typer.Option("--navigation", help="JuPedSim's model: cfs (collision-free speed "
                          "model, keeps hips apart) or avm (anticipation velocity model, "
                          "clears counterflows faster); see docs/crowd.md."),
    ] = "cfs",
) -> None:
    """Walk a crowd through a scene: a BVH per agent, trajectories.csv and a top view."""
    written = run_crowd(scene, seconds, out, seed=seed, avoidance=avoidance, preview=preview,
                        navigation=navigation)
    typer.echo(f"wrote {len(written)} files into {out}", err=True)
