"""The exported gait step on ONNX Runtime, behind the :class:`GaitNetwork` surface.

Legend: ``B`` agents, ``T`` frames, ``J`` joints, ``C`` emotion labels, ``L`` GRU layers,
``H`` GRU width.

:class:`OnnxGaitNetwork` runs a file of :func:`~emotive.models.gait.onnx_export.export_onnx`
on onnxruntime's CPU provider and answers what
:class:`~emotive.models.gait.generate.GaitGenerator` asks of a network: ``config``,
``initial_state``, ``step`` (one frame, torch tensors in and out) and a call over windows (the
warm-up of new agents, one step per frame). So
``GaitGenerator(model, network=load_onnx_network(model))`` animates on ONNX Runtime.

:func:`load_onnx_network` checks that a file belongs to the model (format, labels, joints,
config, weights) and, without a file, exports the model once into the cache
(``$EMOTIVE_HOME/onnx/``, keyed by the weights' fingerprint, the opset and the emotive
version; a temporary folder when the cache cannot be written).
"""

from __future__ import annotations

import contextlib
import json
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

import emotive
from emotive.data.store import emotive_home
from emotive.errors import ConfigError, EmotiveError, OutputError
from emotive.models.gait.config import AFFECTIVE_SIZE, GaitConfig
from emotive.models.gait.model import GaitModel
from emotive.models.gait.network import MOVEMENT_SIZE, ROOT_SIZE, GaitInputs, GaitOutputs
from emotive.models.gait.onnx_export import (
    FORMAT,
    META_KEYS,
    OPSET,
    OUTPUT_NAMES,
    export_onnx,
    graph_input_names,
    onnx_metadata,
    require,
    weights_fingerprint,
)

#: onnxruntime intra-op threads unless told otherwise (a step is many tiny kernels).
DEFAULT_THREADS = 1


class GaitInputError(EmotiveError, ValueError):
    """A tensor given to :class:`OnnxGaitNetwork` of the wrong shape or kind."""


def _fix(path: Path, weights: Path | None = None) -> str:
    """How to write a good file at ``path`` (from ``weights`` when given)."""
    extra = f" --weights {weights}" if weights is not None else ""
    return f"export it again with `emotive export onnx --out {path}{extra}`"


def read_onnx_metadata(path: str | Path) -> dict[str, str]:
    """The ``metadata_props`` of a gait step file, checked for every key of :data:`META_KEYS`.

    Raises:
        ConfigError: the file is missing, not an ONNX model, or not a gait step file of
            emotive; naming the file and the fix.
        OnnxUnavailableError: ``onnx`` is not installed.
    """
    return read_file_metadata(path, FORMAT, META_KEYS, "gait step", "emotive export onnx")


def read_file_metadata(path: str | Path, fmt: str, keys: Sequence[str], kind: str,
                       command: str) -> dict[str, str]:
    """The ``metadata_props`` of an emotive ONNX file of format ``fmt``, holding ``keys``.

    Args:
        path: the file.
        fmt: the ``format`` value it must have.
        keys: the keys it must hold.
        kind: what the file is, for the messages (e.g. ``"gait step"``).
        command: the command that writes it, without ``--out`` (the fix in the messages).

    Raises:
        ConfigError: the file is missing, not an ONNX model or not of that format; naming
            the file and the fix.
        OnnxUnavailableError: ``onnx`` is not installed.
    """
    onnx = require("onnx")
    path = Path(path)
    fix = f"export it again with `{command} --out {path}`"
    if not path.is_file():
        raise ConfigError(f"{path}: no such ONNX file; write it with `{command} --out {path}`")
    try:
        proto = onnx.load(str(path), load_external_data=False)
    except Exception as exc:  # onnx raises DecodeError, ValueError, OSError, ... on bad files
        raise ConfigError(f"{path}: not a readable ONNX model ({type(exc).__name__}); "
                          f"{fix}") from None
    meta = {p.key: p.value for p in proto.metadata_props}
    missing = [k for k in keys if k not in meta]
    if meta.get("format") != fmt or missing:
        raise ConfigError(f"{path}: not an emotive {kind} file (format "
                          f"{meta.get('format')!r}, missing {missing}); {fix}")
    return meta


def check_compatible(path: str | Path, meta: dict[str, str], model: GaitModel) -> None:
    """Fail unless the file's metadata are those of ``model``'s export.

    Raises:
        ConfigError: another rig (joint names), other labels, another config or other
            weights; naming the file, what differs and the fix.
    """
    expected = onnx_metadata(model)
    what = {"joint_names": "the rig (joint names)", "labels": "the emotion labels",
            "config": "the network config", "weights_sha256": "the weights"}
    for key, name in what.items():
        if meta[key] != expected[key]:
            raise ConfigError(
                f"{path}: the file was exported for another model ({name} differ from those "
                f"of {model.source}); {_fix(Path(path), model.source)}")


class OnnxGaitNetwork:
    """A gait step file run by onnxruntime, with the streaming surface of ``GaitNetwork``.

    Inputs may be any float dtype; the graph computes in float32 and the outputs come back in
    the dtype of ``inputs.rotations``.

    Args:
        path: the ``.onnx`` file (:func:`~emotive.models.gait.onnx_export.export_onnx`).
        threads: onnxruntime intra-op threads (1: the step's kernels are too small to share).

    Attributes:
        config: the network config the file was exported with.
        path: the file.
        metadata: its ``metadata_props``.

    Raises:
        ConfigError: a missing, unreadable or foreign file (:func:`read_onnx_metadata`).
        ValueError: ``threads`` below 1.
        OnnxUnavailableError: ``onnx`` or ``onnxruntime`` is not installed.
    """

    def __init__(self, path: str | Path, threads: int = DEFAULT_THREADS) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.path = Path(path)
        self.metadata = read_onnx_metadata(self.path)
        try:
            self.config = GaitConfig.from_dict(json.loads(self.metadata["config"]))
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{self.path}: bad network config in the file ({exc}); "
                              f"{_fix(self.path)}") from None
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
        expected = graph_input_names(self.config)
        if set(names) != set(expected) or outputs != OUTPUT_NAMES:
            raise ConfigError(f"{self.path}: the graph has inputs {list(names)} and outputs "
                              f"{list(outputs)}, not {list(expected)} and "
                              f"{list(OUTPUT_NAMES)}; {_fix(self.path)}")
        self._feeds = expected
        self.threads = int(threads)

    def __repr__(self) -> str:
        return f"OnnxGaitNetwork({str(self.path)!r}, threads={self.threads})"

    def initial_state(self, batch: int, dtype: torch.dtype | None = None,
                      device: torch.device | None = None) -> torch.Tensor:
        """``(L, B, H)`` zeros, the GRU state before any frame (float32 unless ``dtype``)."""
        return torch.zeros(self.config.gru_layers, batch, self.config.gru_hidden,
                           dtype=dtype or torch.float32, device=device)

    def step(self, inputs: GaitInputs, state: torch.Tensor | None = None
             ) -> tuple[GaitOutputs, torch.Tensor]:
        """Advance ``B`` agents by one frame, as :meth:`GaitNetwork.step`.

        Args:
            inputs: one frame, shapes as in :class:`~emotive.models.gait.network.GaitInputs`
                (``affective`` may be ``None`` when the config has ``use_affective=False``).
            state: ``(L, B, H)`` from the previous call, or ``None`` for zeros.

        Returns:
            :class:`GaitOutputs` (``raw_rotations`` is the normalized ``rotations``: the graph
            returns only those) and the new ``(L, B, H)`` state, in the dtype of
            ``inputs.rotations``.

        Raises:
            GaitInputError: a tensor of the wrong shape or a state of the wrong shape.
        """
        batch = self._check(inputs, state)
        dtype = inputs.rotations.dtype
        if state is None:
            state = self.initial_state(batch, dtype)
        if batch == 0:
            return GaitOutputs(inputs.rotations.clone(), inputs.rotations.clone(),
                               inputs.root.clone()), state.clone()
        tensors = {"rotations": inputs.rotations, "affective": inputs.affective,
                   "emotion": inputs.emotion, "movement": inputs.movement, "root": inputs.root,
                   "state": state}
        feed = {name: _np(tensors[name]) for name in self._feeds}
        rot, root, new_state = self._session.run(None, feed)
        rot = torch.from_numpy(rot).to(dtype)
        return GaitOutputs(rot, rot, torch.from_numpy(root).to(dtype)), torch.from_numpy(
            new_state).to(dtype)

    def __call__(self, inputs: GaitInputs, state: torch.Tensor | None = None
                 ) -> tuple[GaitOutputs, torch.Tensor]:
        """Run ``B`` windows of ``T`` frames teacher-forced, one :meth:`step` per frame.

        As :meth:`GaitNetwork.forward`: every tensor ``(B, T, ...)``, ``emotion`` ``(B, C)``
        or ``(B, T, C)``; returns outputs with a ``T`` axis and the state after the last frame.

        Raises:
            GaitInputError: a tensor without the ``(B, T)`` axes.
        """
        rot = inputs.rotations
        if not isinstance(rot, torch.Tensor) or rot.ndim != 4 or rot.shape[1] < 1:
            raise GaitInputError(f"windows need rotations of shape (B, T >= 1, J, 4) for "
                                 f"{self.path}, got {_shape(rot)}")
        outputs = []
        for t in range(rot.shape[1]):
            frame = GaitInputs(*(
                None if x is None else (x if name == "emotion" and x.ndim == 2 else x[:, t])
                for name, x in zip(GaitInputs._fields, inputs, strict=True)))
            out, state = self.step(frame, state)
            outputs.append(out)
        return GaitOutputs(*(torch.stack(x, 1) for x in zip(*outputs, strict=True))), state

    forward = __call__

    def _check(self, inputs: GaitInputs, state: torch.Tensor | None) -> int:
        """``B`` of one frame's inputs, every shape checked."""
        cfg = self.config
        rot = inputs.rotations
        if not isinstance(rot, torch.Tensor) or rot.ndim != 3 or tuple(rot.shape[1:]) != (
                cfg.num_joints, 4):
            raise GaitInputError(f"rotations must have shape (B, J={cfg.num_joints}, 4) for "
                                 f"{self.path}, got {_shape(rot)}")
        batch = rot.shape[0]
        sizes = {"emotion": (cfg.num_labels, f"weights over {cfg.labels}"),
                 "movement": (MOVEMENT_SIZE, "sin/cos phase, omega, s_lowpass, kappa"),
                 "root": (ROOT_SIZE, "h, s, delta")}
        if cfg.use_affective or inputs.affective is not None:
            sizes["affective"] = (AFFECTIVE_SIZE, "the 18 affective features")
        for name, (size, what) in sizes.items():
            x = getattr(inputs, name)
            if not isinstance(x, torch.Tensor) or tuple(x.shape) != (batch, size):
                raise GaitInputError(f"{name} must have shape (B={batch}, {size}) ({what}) for "
                                     f"{self.path}, got {_shape(x)}")
        expected = (cfg.gru_layers, batch, cfg.gru_hidden)
        if state is not None and (not isinstance(state, torch.Tensor)
                                  or tuple(state.shape) != expected):
            raise GaitInputError(f"state must have shape (L={expected[0]}, B={batch}, "
                                 f"H={expected[2]}) for {self.path}, got {_shape(state)}")
        return batch


def _shape(x: Any) -> str:
    return str(tuple(x.shape)) if isinstance(x, torch.Tensor) else type(x).__name__


def _np(x: torch.Tensor) -> np.ndarray:
    """A contiguous float32 NumPy view (or copy) of a CPU tensor."""
    return np.ascontiguousarray(x.detach().cpu().numpy(), dtype=np.float32)


def cached_onnx_path(model: GaitModel) -> Path:
    """Where :func:`load_onnx_network` keeps ``model``'s export.

    ``$EMOTIVE_HOME/onnx/gait-<fingerprint>-opset<N>-<version>.onnx``.
    """
    key = weights_fingerprint(model.network)[:16]
    return emotive_home() / "onnx" / f"gait-{key}-opset{OPSET}-{emotive.__version__}.onnx"


def _export_cached(model: GaitModel) -> Path:
    """The cached export of ``model``, written now if absent or stale (a temp folder if need be)."""
    path = cached_onnx_path(model)
    with contextlib.suppress(ConfigError):
        if read_onnx_metadata(path)["weights_sha256"] == weights_fingerprint(model.network):
            return path
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return export_onnx(model, path)
    except (OSError, OutputError):
        folder = Path(tempfile.mkdtemp(prefix="emotive-onnx-"))
        return export_onnx(model, folder / path.name)


def load_onnx_network(model: GaitModel, path: str | Path | None = None,
                      threads: int = DEFAULT_THREADS) -> OnnxGaitNetwork:
    """``model``'s network on ONNX Runtime, from ``path`` or from a cached export.

    Args:
        model: the gait model whose network the file must be.
        path: a file of ``emotive export onnx``; ``None`` exports ``model`` into the cache
            (:func:`cached_onnx_path`) unless it is there already.
        threads: onnxruntime intra-op threads.

    Raises:
        ConfigError: the file is missing, unreadable, or exported for another model (rig,
            labels, config or weights); naming the file and the fix.
        OnnxUnavailableError: ``onnx`` or ``onnxruntime`` is not installed.
    """
    path = _export_cached(model) if path is None else Path(path)
    network = OnnxGaitNetwork(path, threads=threads)
    check_compatible(path, network.metadata, model)
    return network
