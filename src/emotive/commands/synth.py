"""``emotive synth``: the main paper's augmented data set, made on Ray, and what it is worth.

"Synthesized Emotive Gaits" (Bhattacharya et al. 2020, section 5.2): gaits on ``--paths``
novel trajectories with ``--emotions`` novel emotions on each, plus ``--transitions`` pairs of
those emotions per trajectory, ``--seconds`` each, into ``--out`` as shards, a manifest and a
card (:func:`emotive.synth.synthesize`). The defaults are the paper's recipe (3,000 walks of
10 s); ``--recipe small`` makes 8 walks of 4 s (:data:`emotive.synth.recipe.RECIPES`). A rerun
continues a stopped run; the folder is the same for any ``--workers`` and any cluster
(``--address``).

``emotive synth classifier-study`` (:mod:`emotive.commands.synth_study`) trains the
perceived-emotion classifier on real clips and on real clips plus such a folder, and compares
them on held-out real walks.

Heavy modules (torch, Ray) are imported inside the commands so that ``emotive --help`` stays
fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import SEED_MAX
from emotive.commands.synth_study import classifier_study

app = typer.Typer(invoke_without_command=True, add_completion=False)
app.command("classifier-study")(classifier_study)


@app.callback()
def synth(
    ctx: typer.Context,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="Folder of the data set: new, empty, or "
                                  "one this command made with the same options (it "
                                  "continues). Required to make a data set.",
                                  show_default=False)] = None,
    recipe_name: Annotated[
        str, typer.Option("--recipe", help="Named recipe whose counts and --seconds are the "
                          "defaults: paper (3,000 walks of 10 s) or small (8 walks of 4 s); "
                          "the options below change them.")] = "paper",
    paths: Annotated[
        int | None, typer.Option("--paths", help="Novel trajectories (default: the recipe's).",
                                 min=1, show_default=False)] = None,
    emotions: Annotated[
        int | None, typer.Option("--emotions", help="Novel emotions walked on every "
                                 "trajectory (default: the recipe's).", min=1,
                                 show_default=False)] = None,
    transitions: Annotated[
        int | None, typer.Option("--transitions", help="Pairs of those emotions (drawn "
                                 "without replacement) walked as a transition on every "
                                 "trajectory; at most half of --emotions (default: the "
                                 "recipe's).", min=0, show_default=False)] = None,
    seconds: Annotated[
        float | None, typer.Option("--seconds", help="Length of every walk, seconds (1 to "
                                   "600; default: the recipe's).", min=1.0, max=600.0,
                                   show_default=False)] = None,
    seed: Annotated[
        int, typer.Option("--seed", help="Random seed: the same seed gives the same data set.",
                          min=0, max=SEED_MAX)] = 0,
    model: Annotated[
        str, typer.Option("--model", "-m", help="Generator: gait (emotive gait network), fcrbm "
                          "(valence/arousal FCRBM) or lgb (end-effector resampling, needs the "
                          "data); see `emotive models`.")] = "gait",
    workers: Annotated[
        int | None, typer.Option("--workers", help="Shards made at once (default: this "
                                 "machine's CPUs, or the cluster's).", min=1,
                                 show_default=False)] = None,
    address: Annotated[
        str | None, typer.Option("--address", help="A Ray cluster's HOST:PORT (`ray start "
                                 "--head --port PORT` on one machine, `ray start --address "
                                 "HOST:PORT` on the others); default: a local Ray.",
                                 show_default=False)] = None,
    formats: Annotated[
        str, typer.Option("--formats", help="Files: npz (the shards, always written), bvh "
                          "and glb (one file per walk as well), comma-separated.")] = "npz",
    rig: Annotated[
        Path | None, typer.Option("--rig", help="Your character's rig (.bvh, .glb/.gltf or "
                                  ".fbx): every walk is retargeted onto it.",
                                  show_default=False)] = None,
    rig_roles: Annotated[
        str | None, typer.Option("--rig-roles", help="Role map of --rig: a built-in name or a "
                                 "JSON file; default: detected.", show_default=False)] = None,
    shard_size: Annotated[
        int, typer.Option("--shard-size", help="Walks per shard, made in one batch (part of "
                          "the recipe: changing it changes the data set).", min=1,
                          max=2000)] = 100,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress on stderr.",
                           metavar="")] = True,
) -> None:
    """Make the main paper's augmented data set: novel trajectories, emotions, transitions."""
    from rich.console import Console
    from typer._click.exceptions import UsageError

    if ctx.invoked_subcommand is not None:
        if out is not None:
            raise UsageError(f"--out belongs to `emotive synth` itself; give `emotive synth "
                             f"{ctx.invoked_subcommand}` its own options after its name", ctx)
        return
    if out is None:
        raise UsageError("Missing option '--out' / '-o'.", ctx)

    from emotive.synth.build import synthesize
    from emotive.synth.recipe import check_formats, named_recipe

    recipe = named_recipe(recipe_name, paths=paths, emotions=emotions, transitions=transitions,
                          seconds=seconds, seed=seed, model=model, shard_size=shard_size,
                          formats=check_formats(formats), rig_roles=rig_roles)
    report = synthesize(out, recipe, rig=rig, workers=workers, address=address,
                        progress=progress)
    Console(stderr=True).print(report.summary(), highlight=False, soft_wrap=True)
