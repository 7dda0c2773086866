"""The exported whole step on ONNX Runtime, callable like :class:`AgentStep`.

Legend as in :mod:`~emotive.models.gait.step_export`.

:class:`OnnxAgentStep` runs a file of :func:`~emotive.models.gait.step_export.export_agent_step`
on onnxruntime's CPU provider. It checks every input before the call (shapes, and finite
controls: an engine's bug named, not a NaN agent) and returns
:class:`~emotive.models.gait.step_graph.StepOutputs` of torch tensors, so
``GaitGenerator(model, step=load_agent_step(model))`` animates on ONNX Runtime with the same
host as the torch step: this is how the parity of the file is tested.
"""

from __future__ import annotations

import contextlib
import json
import tempfile
from pathlib import Path

import numpy as np
import torch

import emotive
from emotive.data.store import emotive_home
from emotive.errors import ConfigError, EmotiveError, OutputError
from emotive.models.gait.model import GaitModel
from emotive.models.gait.onnx_export import OPSET, require, weights_fingerprint
from emotive.models.gait.onnx_runtime import read_file_metadata
from emotive.models.gait.step_export import (
    STEP_FORMAT,
    STEP_INPUTS,
    STEP_META_KEYS,
    STEP_OUTPUTS,
    export_agent_step,
)
from emotive.models.gait.step_graph import StepOutputs

#: Controls that must be finite (the state inputs are the graph's own outputs).
CONTROLS: tuple[str, ...] = ("emotion", "pace", "path", "path_left", "start", "phase")


class StepInputError(EmotiveError, ValueError):
    """An input of the exported step of the wrong shape, or a control that is not finite."""


def _fix(path: Path) -> str:
    return f"export it again with `emotive export onnx --step agent --out {path}`"


def read_step_metadata(path: str | Path) -> dict[str, str]:
    """The ``metadata_props`` of a whole-step file, every key of :data:`STEP_META_KEYS` present.

    Raises:
        ConfigError: the file is missing, not an ONNX model or not an agent step of emotive.
        OnnxUnavailableError: ``onnx`` is not installed.
    """
    return read_file_metadata(path, STEP_FORMAT, STEP_META_KEYS, "agent step",
                              "emotive export onnx --step agent")


class OnnxAgentStep:
    """A whole-step file run by onnxruntime, called like :class:`AgentStep`.

    Args:
        path: the ``.onnx`` file.
        threads: onnxruntime intra-op threads (1: the step's kernels are small).

    Attributes:
        metadata: the file's ``metadata_props``.
        shapes: input name -> shape, ``"B"`` for the batch axis.

    Raises:
        ConfigError: a missing, unreadable or foreign file.
        OnnxUnavailableError: ``onnx`` or ``onnxruntime`` is not installed.
    """

    def __init__(self, path: str | Path, threads: int = 1) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.path = Path(path)
        self.metadata = read_step_metadata(self.path)
        self.shapes = json.loads(self.metadata["inputs"])
        ort = require("onnxruntime")
        options = ort.SessionOptions()
        options.intra_op_num_threads = int(threads)
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        try:
            self._session = ort.InferenceSession(str(self.path), options,
                                                 providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own Fail/InvalidGraph types
            raise ConfigError(f"{self.path}: onnxruntime cannot load it "
                              f"({str(exc).splitlines()[0][:200]}); {_fix(self.path)}") from None
        names = tuple(i.name for i in self._session.get_inputs())
        outputs = tuple(o.name for o in self._session.get_outputs())
        if names != STEP_INPUTS or outputs != STEP_OUTPUTS:
            raise ConfigError(f"{self.path}: the graph has inputs {list(names)} and outputs "
                              f"{list(outputs)}, not {list(STEP_INPUTS)} and "
                              f"{list(STEP_OUTPUTS)}; {_fix(self.path)}")

    def __repr__(self) -> str:
        return f"OnnxAgentStep({str(self.path)!r})"

    def check(self, feeds: dict[str, np.ndarray]) -> int:
        """``B`` of the inputs, every shape and every control checked.

        Raises:
            StepInputError: naming the input, the shape it must have and what it got, or the
                control and the agents whose values are not finite.
        """
        batch = feeds["agent"].shape[0] if feeds["agent"].ndim == 2 else -1
        sizes = {"B": batch}
        for name in STEP_INPUTS:
            want = tuple(sizes.get(d, d) for d in self.shapes[name])
            got = feeds[name].shape
            if got != want:
                raise StepInputError(
                    f"{self.path.name}: input {name!r} must have shape "
                    f"({', '.join(str(d) for d in self.shapes[name])}) = {want} for B={batch} "
                    f"agents, got {got}")
        for name in CONTROLS:
            if np.isfinite(feeds[name]).all():
                continue
            bad = ~np.isfinite(feeds[name].reshape(batch, -1)).all(1)
            if bad.any():
                raise StepInputError(
                    f"{self.path.name}: control {name!r} is not finite (NaN or inf) for agents "
                    f"at batch index {np.flatnonzero(bad)[:10].tolist()}; give finite values")
        return batch

    def __call__(self, recurrent: torch.Tensor, agent: torch.Tensor, emotion: torch.Tensor,
                 pace: torch.Tensor, path: torch.Tensor, path_left: torch.Tensor,
                 start: torch.Tensor, phase: torch.Tensor) -> StepOutputs:
        """One step of ``B`` agents (arguments as :meth:`AgentStep.forward`).

        Returns:
            :class:`StepOutputs` of float32 tensors (in the inputs' dtype when that differs).

        Raises:
            StepInputError: see :meth:`check`.
        """
        args = (recurrent, agent, emotion, pace, path, path_left, start, phase)
        feeds = {n: np.ascontiguousarray(np.asarray(x.detach().cpu()), dtype=np.float32)
                 for n, x in zip(STEP_INPUTS, args, strict=True)}
        batch = self.check(feeds)
        dtype = agent.dtype
        if batch == 0:
            raise StepInputError(f"{self.path.name}: a step needs at least one agent")
        out = self._session.run(None, feeds)
        return StepOutputs(*(torch.from_numpy(x).to(dtype) for x in out))


def cached_step_path(model: GaitModel) -> Path:
    """Where :func:`load_agent_step` keeps ``model``'s export (``$EMOTIVE_HOME/onnx/``)."""
    key = weights_fingerprint(model.network)[:16]
    return emotive_home() / "onnx" / f"agent-{key}-opset{OPSET}-{emotive.__version__}.onnx"


def load_agent_step(model: GaitModel, path: str | Path | None = None,
                    threads: int = 1) -> OnnxAgentStep:
    """``model``'s whole step on ONNX Runtime, from ``path`` or from a cached export.

    Raises:
        ConfigError: the file is missing, unreadable, or exported for other weights, labels
            or another rig; naming the file and the fix.
        OnnxUnavailableError: ``onnx`` or ``onnxruntime`` is not installed.
    """
    if path is None:
        path = cached_step_path(model)
        with contextlib.suppress(ConfigError):
            if read_step_metadata(path)["weights_sha256"] != weights_fingerprint(model.network):
                path.unlink()
        if not path.is_file():
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                export_agent_step(model, path)
            except (OSError, OutputError):
                path = Path(tempfile.mkdtemp(prefix="emotive-onnx-")) / path.name
                export_agent_step(model, path)
    step = OnnxAgentStep(path, threads=threads)
    meta = step.metadata
    if (meta["weights_sha256"] != weights_fingerprint(model.network)
            or json.loads(meta["labels"]) != list(model.labels)
            or json.loads(meta["joint_names"]) != list(model.controls.skeleton.names)):
        raise ConfigError(f"{path}: the file was exported for another model (weights, labels "
                          f"or rig differ from those of {model.source}); "
                          f"{_fix(Path(path))} --weights {model.source}")
    return step
