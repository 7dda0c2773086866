"""``emotive synth classifier-study``: does the synthetic data set help emotion recognition?

Trains the perceived-emotion classifier's recipe on the real training clips alone and on the
real clips plus a synthetic data set (a share of every batch), for each seed, and compares
them on the held-out real test clips of each data set with paired tests
(:mod:`emotive.synth.classifier_study`; the main paper's augmented data set, Bhattacharya et
al. 2020, section 5.2). Progress goes to stderr; the report is written to ``--out``
atomically (JSON; NaN as ``null``) and its one-line summary is the last line of stdout.

Heavy modules are imported inside the command so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer


def _finite(value: Any) -> Any:
    """``value`` with every non-finite float replaced by ``None`` (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def classifier_study(
    synth: Annotated[
        Path, typer.Option("--synth", help="A synthetic data set folder (`emotive synth "
                           "--out DIR`); with --make, made there first with the paper's "
                           "recipe if it is not finished.", show_default=False)],
    out: Annotated[
        Path, typer.Option("--out", "-o", help="The report, a .json file (written whole or "
                           "not at all).", show_default=False)],
    seeds: Annotated[
        str, typer.Option("--seeds", help="Training seeds of both arms: 0,1,2 or a range "
                          "0-4.")] = "0,1,2",
    share: Annotated[
        float, typer.Option("--share", help="Fraction of every training batch drawn from "
                            "synthetic walks in the second arm (same batch size, steps and "
                            "epochs as the first).", min=0.0, max=1.0)] = 0.25,
    target: Annotated[
        str, typer.Option("--target", help="What a synthetic window teaches the label head: "
                          "blend (its emotion weights, a soft target), heaviest (their "
                          "heaviest label) or shuffled (a control: another walk's "
                          "blend).")] = "blend",
    copies: Annotated[
        int | None, typer.Option("--copies", help="Augmented variants of every synthetic walk "
                                 "(other rigs, mirror, frame rates); default: the recipe's "
                                 "augment_copies, as for a real clip.", min=0,
                                 show_default=False)] = None,
    limit: Annotated[
        int, typer.Option("--limit", help="Use only the first N synthetic walks (0: all).",
                          min=0)] = 0,
    config: Annotated[
        str, typer.Option("--config", help="The classifier's recipe: a TOML file or a shipped "
                          "recipe's name.")] = "classifier",
    epochs: Annotated[
        int | None, typer.Option("--epochs", help="Training epochs of both arms (default: the "
                                 "recipe's).", min=1, show_default=False)] = None,
    make: Annotated[
        bool, typer.Option("--make/--no-make", help="Make (or finish) the --synth folder with "
                           "the paper's recipe first (`emotive synth --out DIR`).",
                           metavar="")] = False,
    progress: Annotated[
        bool, typer.Option("--progress/--no-progress", help="Progress on stderr.",
                           metavar="")] = True,
) -> None:
    """Train the classifier on real clips and on real + synthetic walks; compare on real walks."""
    import json
    from dataclasses import replace

    from rich.console import Console

    from emotive.configs import resolve_config
    from emotive.eval.classifier_training import read_config
    from emotive.io.atomic import atomic_output
    from emotive.io.outputs import check_output
    from emotive.synth.classifier_data import SynthMix
    from emotive.synth.classifier_study import StudyConfig, headline, parse_seeds, run_study

    check_output(out, (".json",), "--out")
    study = StudyConfig(seeds=parse_seeds(seeds), mix=SynthMix(share=share, target=target,
                                                               copies=copies, limit=limit))
    cfg = read_config(resolve_config(config))
    if epochs is not None:
        cfg = replace(cfg, epochs=epochs)
    console = Console(stderr=True, quiet=not progress)
    if make:
        from emotive.synth.build import synthesize

        console.print(f"making or finishing {synth} with the paper's recipe ...")
        console.print(synthesize(synth, progress=progress).summary(), highlight=False,
                      soft_wrap=True)
    report = run_study(synth, cfg, study, progress=progress)
    report["command"] = ("emotive synth classifier-study " + " ".join(
        [f"--synth {synth}", f"--seeds {seeds}", f"--share {share:g}", f"--target {target}",
         *([f"--copies {copies}"] if copies is not None else []),
         *([f"--limit {limit}"] if limit else []), f"--config {config}",
         *([f"--epochs {epochs}"] if epochs is not None else []), f"--out {out}"]))
    with atomic_output(out) as tmp:
        tmp.write_text(json.dumps(_finite(report), indent=1) + "\n")
    decision = report["decision"]
    console.print(f"wrote {out}: real+synthetic is "
                  f"{'better' if decision['better'] else 'not better'} on held-out real walks "
                  f"({'; '.join(decision['reasons'])})", highlight=False, soft_wrap=True)
    typer.echo(json.dumps(_finite({"report": str(out), **headline(report)})))
