"""``emotive export onnx``: the gait network's one-frame step as an ONNX file for engines.

The file runs on ONNX Runtime (``emotive serve --backend onnx``, onnxruntime-web) and in
engines (Unity Sentis, Unreal NNE, Godot through an ONNX Runtime binding); ``docs/runtime.md``
says what a host computes around it each frame.

Heavy modules are imported inside the commands so that ``emotive --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from emotive.commands.options import out_option

app = typer.Typer(help="Export models for engines and other runtimes.", no_args_is_help=True,
                  add_completion=False)


@app.callback()
def _export() -> None:
    """Export models for engines and other runtimes."""


def _shape(dims: tuple) -> str:
    return "(" + ", ".join(str(d) for d in dims) + ")"


@app.command("onnx")
def export_onnx_command(
    out: Annotated[Path, out_option("Output .onnx file: the gait network's one-frame step "
                                    "with its recurrent state as input and output.")],
    weights: Annotated[
        Path | None,
        typer.Option("--weights", help="Gait checkpoint to export instead of the built-in "
                     "one (a last.pt or best.pt of `emotive train gait`).", show_default=False),
    ] = None,
) -> None:
    """Export the gait network's per-frame step to ONNX (dynamic batch of agents)."""
    from emotive.io.outputs import check_output
    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.onnx_export import OPSET, export_onnx, graph_signature, require

    check_output(out, (".onnx",), "--out")
    require("onnx")
    model = load_gait_model(weights)
    export_onnx(model, out)
    inputs, outputs = graph_signature(out)
    size = out.stat().st_size
    typer.echo(f"wrote {out} ({size / 1e6:.2f} MB, opset {OPSET}, {model.fps:g} fps, "
               f"{len(model.labels)} labels, {model.network.config.num_joints} joints, "
               f"from {model.source})")
    for kind, values in (("input", inputs), ("output", outputs)):
        for name, dims in values:
            typer.echo(f"  {kind:6} {name:15} {_shape(dims)}")
