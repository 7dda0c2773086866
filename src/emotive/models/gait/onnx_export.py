"""The gait network's one-frame step as an ONNX file, for engines and ONNX Runtime.

Legend: ``B`` agents (a dynamic axis), ``J`` joints, ``C`` emotion labels, ``L`` GRU layers,
``H`` GRU width (``H_3``).

The exported graph is :meth:`GaitNetwork.step <emotive.models.gait.network.GaitNetwork.step>`
with the recurrent state as an input and an output, the feature standardisation (the
network's mean/std buffers) inside it, float32 throughout:

=================  ==============  ==============================================
name               shape           meaning
=================  ==============  ==============================================
``rotations``      ``(B, J, 4)``   current heading-canonical local rotations (w, x, y, z)
``affective``      ``(B, 18)``     affective features of that pose (ratios in log space;
                                   absent when the config has ``use_affective=False``)
``emotion``        ``(B, C)``      emotion weights over the labels
``movement``       ``(B, 5)``      ``[sin theta, cos theta, omega, s_lowpass, kappa]``
``root``           ``(B, 3)``      ``[h, s, delta]``
``state``          ``(L, B, H)``   GRU state (zeros for a new agent)
``next_rotations`` ``(B, J, 4)``   predicted local rotations, unit quaternions
``next_root``      ``(B, 3)``      predicted ``[h, s, delta]`` (metres, metres per frame,
                                   radians)
``next_state``     ``(L, B, H)``   GRU state to feed back next frame
=================  ==============  ==============================================

The file's ``metadata_props`` hold what a host needs besides the graph (:data:`META_KEYS`):
the format tag, the labels, the frame rate, the joint names and the mover, the network config,
the animation controls (rig, standing pose, per-label step frequency and speed, turn slowing:
:meth:`GaitControls.to_dict <emotive.models.gait.controls.GaitControls.to_dict>` as JSON), the
opset, the emotive version and a fingerprint of the weights. ``docs/runtime.md`` describes the
per-frame work around the graph.

The export uses torch's TorchScript-based exporter (``dynamo=False``): it needs only ``onnx``
(no ``onnxscript``), takes a fraction of a second and gives one ``GRU`` node; the graph is
checked with :func:`onnx.checker.check_model` before the file appears (atomically).
"""

from __future__ import annotations

import copy
import hashlib
import importlib
import json
import warnings
from pathlib import Path
from types import ModuleType

import torch
from torch import nn

import emotive
from emotive.errors import EmotiveError
from emotive.io.atomic import atomic_output
from emotive.models.gait.config import AFFECTIVE_SIZE, GaitConfig
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import MOVEMENT_SIZE, ROOT_SIZE, GaitInputs, GaitNetwork

#: ONNX opset of the exported graph; 15 is the newest that Unity Sentis imports (7-15).
OPSET = 15
#: Graph input names, in order.
INPUT_NAMES: tuple[str, ...] = ("rotations", "affective", "emotion", "movement", "root", "state")
#: Graph output names, in order.
OUTPUT_NAMES: tuple[str, ...] = ("next_rotations", "next_root", "next_state")
#: Value of the ``format`` metadata entry of a gait step file.
FORMAT = "emotive-gait-step/1"
#: The ``metadata_props`` keys every exported file holds.
META_KEYS: tuple[str, ...] = (
    "format", "labels", "fps", "joint_names", "mover", "config", "controls", "opset",
    "emotive_version", "weights_sha256",
)
#: How to install what the ONNX route needs.
INSTALL_HINT = "pip install 'emotive[onnx]'"


class OnnxUnavailableError(EmotiveError, ImportError):
    """``onnx`` or ``onnxruntime`` is not installed."""


def require(module: str) -> ModuleType:
    """Import ``onnx`` or ``onnxruntime``, or say how to install it.

    Raises:
        OnnxUnavailableError: the package is not installed.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise OnnxUnavailableError(f"the ONNX route needs the package {module!r}, which is not "
                                   f"installed; install it with: {INSTALL_HINT}") from exc


class GaitStep(nn.Module):
    """One frame of a :class:`GaitNetwork` on flat tensors, the module that is exported.

    Args:
        network: the network (used as it is; :func:`export_onnx` passes a float32 copy).
    """

    def __init__(self, network: GaitNetwork) -> None:
        super().__init__()
        self.network = network

    def forward(self, rotations: torch.Tensor, affective: torch.Tensor, emotion: torch.Tensor,
                movement: torch.Tensor, root: torch.Tensor, state: torch.Tensor
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Advance ``B`` agents by one frame (shapes in the module docstring).

        Returns:
            ``next_rotations (B, J, 4)``, ``next_root (B, 3)``, ``next_state (L, B, H)``.
        """
        uses_affective = self.network.config.use_affective
        inputs = GaitInputs(rotations, affective if uses_affective else None, emotion,
                            movement, root)
        out, new_state = self.network.step(inputs, state)
        return out.rotations, out.root, new_state


def graph_input_names(config: GaitConfig) -> tuple[str, ...]:
    """The input names of the exported graph for ``config``.

    :data:`INPUT_NAMES`, without ``affective`` when the config has ``use_affective=False``
    (the exporter drops an input the graph never reads).
    """
    return tuple(n for n in INPUT_NAMES if config.use_affective or n != "affective")


def weights_fingerprint(network: GaitNetwork) -> str:
    """sha256 of a network's config and float32 weights and buffers (hex).

    Equal for the same checkpoint whatever dtype the network was cast to since (float32
    weights survive a round trip through float64 exactly).
    """
    digest = hashlib.sha256(network.config.to_json().encode())
    for name, tensor in sorted(network.state_dict().items()):
        digest.update(name.encode())
        digest.update(tensor.detach().to("cpu", torch.float32).contiguous().numpy().tobytes())
    return digest.hexdigest()


def onnx_metadata(model: GaitModel) -> dict[str, str]:
    """The ``metadata_props`` of ``model``'s export (:data:`META_KEYS`), as strings."""
    cfg = model.network.config
    skeleton = model.controls.skeleton
    return {
        "format": FORMAT,
        "labels": json.dumps(list(cfg.labels)),
        "fps": repr(float(cfg.fps)),
        "joint_names": json.dumps(list(skeleton.names)),
        "mover": str(int(model.controls.mover)),
        "config": cfg.to_json(),
        "controls": json.dumps(model.controls.to_dict()),
        "opset": str(OPSET),
        "emotive_version": emotive.__version__,
        "weights_sha256": weights_fingerprint(model.network),
    }


def example_inputs(network: GaitNetwork, batch: int = 2) -> tuple[torch.Tensor, ...]:
    """Float32 inputs of the step for ``batch`` agents, in :data:`INPUT_NAMES` order."""
    cfg = network.config
    rotations = torch.zeros(batch, cfg.num_joints, 4)
    rotations[..., 0] = 1.0
    emotion = torch.full((batch, cfg.num_labels), 1.0 / cfg.num_labels)
    return (rotations, torch.zeros(batch, AFFECTIVE_SIZE), emotion,
            torch.zeros(batch, MOVEMENT_SIZE), torch.zeros(batch, ROOT_SIZE),
            torch.zeros(cfg.gru_layers, batch, cfg.gru_hidden))


def _dynamic_axes() -> dict[str, dict[int, str]]:
    """The batch axis ``B`` of every input and output."""
    axes = {name: {0: "B"} for name in (*INPUT_NAMES, *OUTPUT_NAMES)}
    axes["state"] = axes["next_state"] = {1: "B"}
    return axes


def _trace_to(step: GaitStep, path: Path) -> None:
    """Export ``step`` to ``path`` with the TorchScript exporter, its known notices silenced.

    The exporter warns that it is the legacy one, that the shape checks of
    :meth:`GaitNetwork.step` become constants of the trace (they check the fixed axes; ``B``
    stays dynamic, as the parity tests check) and that a GRU exported with a batch other than
    1 needs its state given (it is an input here).
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)
        warnings.filterwarnings("ignore", message=".*legacy TorchScript-based ONNX export")
        warnings.filterwarnings("ignore", message=".*feature will be removed")
        warnings.filterwarnings("ignore", message=".*batch_size other than 1.*GRU")
        torch.onnx.export(
            step, example_inputs(step.network), str(path), dynamo=False, opset_version=OPSET,
            input_names=list(INPUT_NAMES), output_names=list(OUTPUT_NAMES),
            dynamic_axes=_dynamic_axes(), do_constant_folding=True,
        )


def export_onnx(model: GaitModel, out_path: str | Path) -> Path:
    """Write ``model``'s one-frame step as an ONNX file (see the module docstring).

    The file appears whole or not at all; ``model`` is not changed (a float32 copy of its
    network is exported).

    Args:
        model: the gait model (:func:`~emotive.models.gait.model.load_gait_model`).
        out_path: the ``.onnx`` file to write; its folder must exist.

    Returns:
        ``out_path`` as a :class:`~pathlib.Path`.

    Raises:
        OnnxUnavailableError: ``onnx`` is not installed.
        OutputError: the file cannot be written.
    """
    onnx = require("onnx")
    out_path = Path(out_path)
    network = copy.deepcopy(model.network).to(torch.float32).eval()
    with atomic_output(out_path) as tmp:
        _trace_to(GaitStep(network), tmp)
        proto = onnx.load(str(tmp))
        onnx.helper.set_model_props(proto, onnx_metadata(model))
        proto.producer_name = "emotive"
        proto.producer_version = emotive.__version__
        proto.doc_string = ("emotive gait network, one frame per call; inputs "
                            f"{', '.join(INPUT_NAMES)}; outputs {', '.join(OUTPUT_NAMES)}")
        onnx.checker.check_model(proto, full_check=True)
        onnx.save(proto, str(tmp))
    return out_path


def graph_signature(path: str | Path) -> tuple[list[tuple[str, tuple]], list[tuple[str, tuple]]]:
    """The ``(name, shape)`` of every input and output of an ONNX file.

    A dynamic axis appears by its name (``"B"``), a fixed one as its size.

    Raises:
        OnnxUnavailableError: ``onnx`` is not installed.
    """
    onnx = require("onnx")
    graph = onnx.load(str(path), load_external_data=False).graph

    def shapes(values) -> list[tuple[str, tuple]]:
        return [(v.name, tuple(d.dim_param or d.dim_value
                               for d in v.type.tensor_type.shape.dim)) for v in values]

    return shapes(graph.input), shapes(graph.output)
