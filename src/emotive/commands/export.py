"""``emotive export onnx|web``: gait agents' per-frame step for engines and the browser.

``--step agent`` writes the whole step (network, controls, path following, kinematics,
affective features and the foot lock in one graph); ``--step network`` the network alone. The
files run on ONNX Runtime (``emotive serve --backend onnx``, onnxruntime-web) and in engines
(Unity Sentis, Unreal NNE, Godot through an ONNX Runtime binding); ``docs/runtime.md`` is the
contract of each. ``emotive export web`` writes a static folder that runs the whole step in
the browser on onnxruntime-web (:mod:`emotive.web.export`).

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import ForceOpt, flag, input_file, out_option

app = typer.Typer(help="Export models for engines and other runtimes.", no_args_is_help=True,
                  add_completion=False)


@app.callback()
def _export() -> None:
    """Export models for engines and other runtimes."""


def _shape(dims: tuple) -> str:
    return "(" + ", ".join(str(d) for d in dims) + ")"


@app.command("onnx")
def export_onnx_command(
    out: Annotated[Path, out_option("Output .onnx file: one frame of gait agents per call, "
                                    "the state as input and output.")],
    step: Annotated[
        str,
        typer.Option("--step", help="What one call computes: 'agent' (the whole step: "
                     "network, controls, path following, kinematics, foot lock) or "
                     "'network' (the network alone; the host computes the rest, "
                     "docs/runtime.md)."),
    ] = "network",
    weights: Annotated[
        Path | None,
        typer.Option("--weights", help="Gait checkpoint to export instead of the built-in "
                     "one (a last.pt or best.pt of `emotive train gait`).", show_default=False),
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Export gait agents' per-frame step to ONNX (dynamic batch of agents)."""
    from emotive.errors import ConfigError
    from emotive.io.outputs import check_output

    if step not in ("agent", "network"):
        raise ConfigError(f"--step {step!r}: choose 'agent' (the whole step) or 'network' "
                          f"(the network alone)")
    check_output(out, (".onnx",), "--out", force)
    if weights is not None:
        input_file(weights, "--weights", None, ConfigError)

    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.onnx_export import OPSET, export_onnx, graph_signature, require
    from emotive.models.gait.step_export import export_agent_step

    require("onnx")
    model = load_gait_model(weights)
    if step == "agent":
        export_agent_step(model, out)
    else:
        export_onnx(model, out)
    inputs, outputs = graph_signature(out)
    size = out.stat().st_size
    typer.echo(f"wrote {out} ({step} step, {size / 1e6:.2f} MB, opset {OPSET}, {model.fps:g} fps, "
               f"{len(model.labels)} labels, {model.network.config.num_joints} joints, "
               f"from {model.source})")
    for kind, values in (("input", inputs), ("output", outputs)):
        for name, dims in values:
            typer.echo(f"  {kind:6} {name:15} {_shape(dims)}")


@app.command("web")
def export_web_command(
    out: Annotated[Path, out_option("Output folder: a static page that runs gait agents in "
                                    "the browser (serve it with `python -m http.server`).")],
    weights: Annotated[
        Path | None,
        typer.Option("--weights", help="Gait checkpoint to export instead of the built-in "
                     "one (a last.pt or best.pt of `emotive train gait`).", show_default=False),
    ] = None,
    force: Annotated[bool, flag("force", "Replace --out when it holds a previous export (a "
                                "folder with other files is never replaced).")] = False,
    scene: Annotated[
        Path | None,
        typer.Option("--scene", help="A crowd scene (scene.toml, docs/crowd.md) the page runs "
                     "with recast-navigation's Detour crowd; needs the crowd extra.",
                     show_default=False),
    ] = None,
) -> None:
    """Export a static folder that runs gait agents in the browser, without Python.

    The page places agents, draws their paths, sets their emotions and offers WebXR AR/VR
    like the served app; onnxruntime-web runs the whole agent step in the page. With
    --scene the page walks the scene's crowd, avoiding each other by Detour's crowd.
    """
    from emotive.errors import ConfigError
    from emotive.io.outputs import folder_name

    folder = out.expanduser().absolute()
    folder_name(out, "--out")
    if weights is not None:
        input_file(weights, "--weights", None, ConfigError)

    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.onnx_export import require
    from emotive.web.export import check_web_folder, export_web

    check_web_folder(folder, force)
    crowd = None
    if scene is not None:
        from emotive.crowd.scene import load_scene
        from emotive.web.scene import crowd_geometry

        crowd_geometry()
        crowd = load_scene(scene)
    require("onnx")
    model = load_gait_model(weights)
    done = export_web(model, folder, force=force, scene=crowd)
    typer.echo(f"wrote {done.folder} ({done.files} files, {done.total_bytes / 1e6:.1f} MB: "
               f"agent.onnx {done.graph_bytes / 1e6:.2f} MB, onnxruntime-web "
               f"{done.runtime_bytes / 1e6:.1f} MB; {model.fps:g} fps, "
               f"{len(model.labels)} labels, from {model.source})")
    if crowd is not None:
        typer.echo(f"  scene {crowd.name} (scene.json): {len(crowd.groups)} group(s), "
                   f"{done.scene_agents} agent(s)")
    typer.echo(f"  serve it: python -m http.server --bind 127.0.0.1 --directory {done.folder}")
    typer.echo("  then open http://127.0.0.1:8000/ (add ?demo=1 for four walking agents)")
