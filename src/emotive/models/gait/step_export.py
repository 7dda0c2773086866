"""The whole per-frame step of gait agents as one ONNX file (``emotive export onnx --step agent``).

Legend: ``B`` agents (a dynamic axis), ``J`` joints, ``P = J + E`` points, ``C`` emotion
labels, ``K`` path samples, ``L`` GRU layers, ``H`` GRU width, ``S`` the agent row.

The graph is :class:`~emotive.models.gait.step_graph.AgentStep` traced in float32: the
network of the main paper (Sec. 4; its GRU as per-gate matrix products,
:mod:`~emotive.models.gait.gru_frame`) with the movement controls, the placement on the path,
the forward kinematics, the affective features and the causal foot lock inside. An engine samples
each agent's path around it, feeds back the state and poses its skeleton; ``docs/runtime.md``
is the contract with a worked example.

=================  ==============  ====================================================
name               shape           meaning
=================  ==============  ====================================================
``recurrent``      ``(L, B, H)``   GRU state (zeros for a new agent)
``agent``          ``(B, S)``      agent rows (:mod:`~emotive.models.gait.step_layout`)
``emotion``        ``(B, C)``      emotion weights over the labels
``pace``           ``(B,)``        factor on the emotion's walking speed (0.5-1.5)
``path``           ``(B, K, 2)``   the path around the agent, in its frame
``path_left``      ``(B,)``        metres to the end of an open path (>= 1e6: a loop)
``start``          ``(B,)``        1 for a start step of a new agent, else 0
``phase``          ``(B,)``        stepping phase of a start step, radians
``next_recurrent`` ``(L, B, H)``   GRU state to feed back
``next_agent``     ``(B, S)``      agent rows to feed back
``rotations``      ``(B, J, 4)``   local rotations (w, x, y, z), the mover's world heading
``root_position``  ``(B, 3)``      world position of the mover joint, metres
``world``          ``(B, P, 3)``   world positions of joints then end sites, metres
``contacts``       ``(B, 2, 2)``   planted heel and toe of the left and right foot
``ground``         ``(B, 3)``      ``(x, z, heading)``: the frame of the next path samples
``advance``        ``(B,)``        metres to move the agent's arc length
=================  ==============  ====================================================

Non-finite controls are read as safe values inside the graph (emotion weights 0, pace 1, a
path point at the agent, no path left), so a bad input stops an agent instead of filling its
state with NaN; the Python runner (:mod:`~emotive.models.gait.step_runtime`) refuses them
with a message instead.
"""

from __future__ import annotations

import copy
import json
import warnings
from pathlib import Path

import torch
from torch import nn

import emotive
from emotive.io.atomic import atomic_output
from emotive.models.gait.gru_frame import FrameGRU
from emotive.models.gait.model import GaitModel
from emotive.models.gait.onnx_export import OPSET, require, weights_fingerprint
from emotive.models.gait.step_graph import WARMUP_STEPS, AgentStep

#: Graph input names, in order.
STEP_INPUTS: tuple[str, ...] = ("recurrent", "agent", "emotion", "pace", "path", "path_left",
                                "start", "phase")
#: Graph output names, in order.
STEP_OUTPUTS: tuple[str, ...] = ("next_recurrent", "next_agent", "rotations", "root_position",
                                 "world", "contacts", "ground", "advance")
#: Value of the ``format`` metadata entry of a whole-step file.
STEP_FORMAT = "emotive-agent-step/1"
#: The ``metadata_props`` keys of a whole-step file.
STEP_META_KEYS: tuple[str, ...] = (
    "format", "labels", "fps", "joint_names", "parents", "end_site_parents", "mover",
    "controls", "agent_layout", "path_sampling", "warmup_steps", "loop_left", "inputs",
    "outputs", "opset", "emotive_version", "weights_sha256",
)
#: ``path_left`` at or above which a path counts as a loop.
LOOP_LEFT = 1e6


class _SafeStep(nn.Module):
    """:class:`AgentStep` behind the graph's reading of non-finite controls."""

    def __init__(self, step: AgentStep) -> None:
        super().__init__()
        self.step = step

    def forward(self, recurrent: torch.Tensor, agent: torch.Tensor, emotion: torch.Tensor,
                pace: torch.Tensor, path: torch.Tensor, path_left: torch.Tensor,
                start: torch.Tensor, phase: torch.Tensor) -> tuple[torch.Tensor, ...]:
        def safe(x: torch.Tensor, value: float) -> torch.Tensor:
            return torch.where(torch.isnan(x) | torch.isinf(x), torch.full_like(x, value), x)

        out = self.step(recurrent, agent, safe(emotion, 0.0), safe(pace, 1.0), safe(path, 0.0),
                        safe(path_left, 0.0), safe(start, 0.0), safe(phase, 0.0))
        return tuple(out)


def step_metadata(model: GaitModel, step: AgentStep) -> dict[str, str]:
    """The ``metadata_props`` of the whole-step file (:data:`STEP_META_KEYS`), as strings."""
    sk = model.controls.skeleton
    cfg = step.network.config
    lbh = [cfg.gru_layers, "B", cfg.gru_hidden]
    shapes = {"recurrent": lbh, "agent": ["B", step.layout.size],
              "emotion": ["B", len(model.labels)], "pace": ["B"],
              "path": ["B", step.sampling.count, 2], "path_left": ["B"], "start": ["B"],
              "phase": ["B"]}
    points = sk.num_joints + len(sk.end_site_parents)
    outputs = {"next_recurrent": lbh, "next_agent": ["B", step.layout.size],
               "rotations": ["B", sk.num_joints, 4], "root_position": ["B", 3],
               "world": ["B", points, 3], "contacts": ["B", 2, 2], "ground": ["B", 3],
               "advance": ["B"]}
    return {
        "format": STEP_FORMAT,
        "labels": json.dumps(list(model.labels)),
        "fps": repr(float(model.fps)),
        "joint_names": json.dumps(list(sk.names)),
        "parents": json.dumps([int(p) for p in sk.parents]),
        "end_site_parents": json.dumps([int(p) for p in sk.end_site_parents]),
        "mover": str(int(model.controls.mover)),
        "controls": json.dumps(model.controls.to_dict()),
        "agent_layout": json.dumps(step.layout.to_json()),
        "path_sampling": json.dumps(step.sampling.to_json()),
        "warmup_steps": str(WARMUP_STEPS),
        "loop_left": repr(LOOP_LEFT),
        "inputs": json.dumps(shapes),
        "outputs": json.dumps(outputs),
        "opset": str(OPSET),
        "emotive_version": emotive.__version__,
        "weights_sha256": weights_fingerprint(model.network),
    }


def export_agent_step(model: GaitModel, out_path: str | Path, foot_lock: bool = True) -> Path:
    """Write the whole per-frame step of ``model``'s agents as one ONNX file.

    The file appears whole or not at all and is checked by :func:`onnx.checker.check_model`;
    ``model`` is not changed (a float32 copy of its network is traced).

    Args:
        model: the gait model.
        out_path: the ``.onnx`` file to write; its folder must exist.
        foot_lock: include the causal foot lock.

    Raises:
        OnnxUnavailableError: ``onnx`` is not installed.
        OutputError: the file cannot be written.
    """
    onnx = require("onnx")
    out_path = Path(out_path)
    network = copy.deepcopy(model.network).to(torch.float32).eval()
    network.gru = FrameGRU(network.gru)
    step = AgentStep(model, torch.float32, foot_lock=foot_lock, network=network).eval()
    axes = {name: {0: "B"} for name in (*STEP_INPUTS, *STEP_OUTPUTS)}
    axes["recurrent"] = axes["next_recurrent"] = {1: "B"}
    with atomic_output(out_path) as tmp, torch.no_grad(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", message=".*legacy TorchScript-based ONNX export")
        warnings.filterwarnings("ignore", message=".*feature will be removed")
        torch.onnx.export(_SafeStep(step), step.example_inputs(LOOP_LEFT), str(tmp), dynamo=False,
                          opset_version=OPSET, input_names=list(STEP_INPUTS),
                          output_names=list(STEP_OUTPUTS), dynamic_axes=axes,
                          do_constant_folding=True)
        proto = onnx.load(str(tmp))
        onnx.helper.set_model_props(proto, step_metadata(model, step))
        proto.producer_name = "emotive"
        proto.producer_version = emotive.__version__
        proto.doc_string = ("emotive gait agents, the whole step per call; inputs "
                            f"{', '.join(STEP_INPUTS)}; outputs {', '.join(STEP_OUTPUTS)}")
        onnx.checker.check_model(proto, full_check=True)
        onnx.save(proto, str(tmp))
    return out_path
