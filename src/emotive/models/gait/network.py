"""The affect-based autoregression network of Emotive Gaits (section 4), streaming.

Legend: ``B`` agents (batch), ``T`` frames, ``J`` joints, ``C`` emotion labels, ``L`` GRU
layers, ``H_3`` GRU width.

Encoder (section 4.1), per frame ``t``::

    gamma = [FC_enc1([a, m]); FC_enc2([sin theta, cos theta, omega, s_lowpass, kappa, m])]
    q~    = GRU_versors([q; gamma])            (the only recurrence)
    r~    = FC_root([h, s, delta; gamma])

Predictor (section 4.2)::

    q^ = normalize(FC_versors(q~))             next local rotations, unit quaternions
    [h^, s^, delta^] = [FC_h(r~), FC_s(r~), FC_delta(r~)]

The original implementation re-ran the network over the whole input window for every new
frame. Here the GRU's hidden state is carried instead: :meth:`GaitNetwork.step` advances B
agents by one frame in O(1), and :meth:`GaitNetwork.forward` runs the same weights over whole
windows for teacher-forced training; ``forward`` over T frames equals T ``step`` calls.

Input features are standardised inside the network with buffers (identity until
:meth:`GaitNetwork.set_feature_statistics` is called), so the statistics travel in the
``state_dict`` with the weights; predicted root features come out in the caller's units.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import NamedTuple

import torch
from torch import nn

from emotive.models.gait.config import (
    AFFECTIVE_SIZE,
    MOVEMENT_INPUT_NAMES,
    ROOT_FEATURE_NAMES,
    GaitConfig,
)
from emotive.transforms.rotations import quaternion_normalize

MOVEMENT_SIZE = len(MOVEMENT_INPUT_NAMES)
ROOT_SIZE = len(ROOT_FEATURE_NAMES)


class GaitInputs(NamedTuple):
    """What the network reads, for one frame (``step``) or a window (``forward``).

    Shapes below are per frame; for ``forward`` every tensor has a ``T`` axis after ``B``
    (``emotion`` may stay ``(B, C)``, held constant over the window).

    Attributes:
        rotations: ``(B, J, 4)`` current local joint rotations ``q^t`` (unit quaternions).
        affective: ``(B, 18)`` pose affective features ``a^t``; may be ``None`` when the
            config has ``use_affective=False``.
        emotion: ``(B, C)`` emotion vectors ``m`` over the config's labels (any convex
            combination; may change every frame).
        movement: ``(B, 5)`` ``[sin theta, cos theta, omega, s_lowpass, kappa]``.
        root: ``(B, 3)`` root features ``[h, s, delta]``.
    """

    rotations: torch.Tensor
    affective: torch.Tensor | None
    emotion: torch.Tensor
    movement: torch.Tensor
    root: torch.Tensor


class GaitOutputs(NamedTuple):
    """What the network predicts for the next frame (with a ``T`` axis from ``forward``).

    Attributes:
        rotations: ``(B, J, 4)`` next local rotations, unit quaternions.
        raw_rotations: ``(B, J, 4)`` the same before normalization (for the unit-norm
            penalty of the motion loss).
        root: ``(B, 3)`` next ``[h, s, delta]``.
    """

    rotations: torch.Tensor
    raw_rotations: torch.Tensor
    root: torch.Tensor


def _mlp(sizes: Sequence[int], last_activation: bool) -> nn.Sequential:
    """Linear layers through ``sizes`` with ELU between them (and after the last if asked)."""
    layers: list[nn.Module] = []
    for n, (a, b) in enumerate(itertools.pairwise(sizes)):
        layers.append(nn.Linear(a, b))
        if last_activation or n < len(sizes) - 2:
            layers.append(nn.ELU())
    return nn.Sequential(*layers)


class GaitNetwork(nn.Module):
    """Encoder and predictor of Emotive Gaits with a streaming step API.

    Args:
        config: sizes, labels and switches; kept as ``self.config`` for checkpoints.

    Example::

        net = GaitNetwork(GaitConfig(num_joints=19))
        state = net.initial_state(batch=8)
        outputs, state = net.step(frame_inputs, state)  # one frame for 8 agents
    """

    def __init__(self, config: GaitConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or GaitConfig()
        c = cfg.num_labels
        enc1_in = (AFFECTIVE_SIZE if cfg.use_affective else 0) + c
        # ELU on every fully connected layer (section 5.3), the encoder outputs included.
        self.fc_enc1 = _mlp((enc1_in, cfg.enc1_hidden, cfg.enc1_hidden, cfg.enc1_out), True)
        self.fc_enc2 = _mlp(
            (MOVEMENT_SIZE + c, cfg.enc2_hidden, cfg.enc2_hidden, cfg.enc2_out), True
        )
        gamma = cfg.enc1_out + cfg.enc2_out
        self.gru = nn.GRU(
            4 * cfg.num_joints + gamma, cfg.gru_hidden, num_layers=cfg.gru_layers,
            batch_first=True,
        )
        self.fc_root = _mlp((ROOT_SIZE + gamma, cfg.root_hidden), True)
        # The outputs are a raw quaternion and signed root features: no activation on them.
        self.fc_versors = _mlp((cfg.gru_hidden, cfg.versor_hidden, 4 * cfg.num_joints), False)
        head = (cfg.root_hidden, cfg.head_hidden, 1) if cfg.head_hidden else (cfg.root_hidden, 1)
        self.fc_h = _mlp(head, False)
        self.fc_s = _mlp(head, False)
        self.fc_delta = _mlp(head, False)
        for name, size in (("affective", AFFECTIVE_SIZE), ("movement", MOVEMENT_SIZE),
                           ("root", ROOT_SIZE)):
            self.register_buffer(f"{name}_mean", torch.zeros(size))
            self.register_buffer(f"{name}_std", torch.ones(size))

    @property
    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)

    def set_feature_statistics(
        self,
        affective: tuple[torch.Tensor, torch.Tensor] | None = None,
        movement: tuple[torch.Tensor, torch.Tensor] | None = None,
        root: tuple[torch.Tensor, torch.Tensor] | None = None,
    ) -> None:
        """Set the ``(mean, std)`` used to standardise inputs (and de-standardise ``root``).

        Args:
            affective: ``(18,)`` mean and std of the affective features.
            movement: ``(5,)`` mean and std of the movement inputs.
            root: ``(3,)`` mean and std of ``[h, s, delta]``.

        Raises:
            ValueError: a statistic of the wrong size or a non-positive std.
        """
        for name, stats in (("affective", affective), ("movement", movement), ("root", root)):
            if stats is None:
                continue
            mean_buf = getattr(self, f"{name}_mean")
            std_buf = getattr(self, f"{name}_std")
            mean = torch.as_tensor(stats[0], dtype=mean_buf.dtype).reshape(-1)
            std = torch.as_tensor(stats[1], dtype=std_buf.dtype).reshape(-1)
            if mean.shape != mean_buf.shape or std.shape != std_buf.shape:
                raise ValueError(
                    f"{name} statistics must have shape {tuple(mean_buf.shape)}, "
                    f"got {tuple(mean.shape)} and {tuple(std.shape)}"
                )
            if not bool((std > 0).all()):
                raise ValueError(f"{name} std must be positive everywhere")
            mean_buf.copy_(mean)
            std_buf.copy_(std)

    def initial_state(
        self, batch: int, dtype: torch.dtype | None = None, device: torch.device | None = None
    ) -> torch.Tensor:
        """The GRU state before any frame.

        ``(L, B, H_3)`` zeros (the parameters' dtype and device unless given).
        """
        ref = next(self.parameters())
        return torch.zeros(
            self.config.gru_layers, batch, self.config.gru_hidden,
            dtype=dtype or ref.dtype, device=device or ref.device,
        )

    def step(
        self, inputs: GaitInputs, state: torch.Tensor | None = None, normalize: bool = True
    ) -> tuple[GaitOutputs, torch.Tensor]:
        """Advance ``B`` agents by one frame.

        Args:
            inputs: one frame, shapes as in :class:`GaitInputs` (no ``T`` axis).
            state: ``(L, B, H_3)`` GRU state from the previous call, or ``None`` for
                :meth:`initial_state`.
            normalize: ``False`` leaves the rotations unnormalized (``rotations`` is then
                ``raw_rotations``), for a caller that normalizes them itself.

        Returns:
            The next frame's :class:`GaitOutputs` (``(B, J, 4)``, ``(B, J, 4)``, ``(B, 3)``)
            and the new ``(L, B, H_3)`` state.

        Raises:
            ValueError: a tensor of the wrong shape, an emotion vector whose length is not
                ``C``, or a state of the wrong shape.
        """
        (batch,) = self._check(inputs, sequence=False)
        seq = GaitInputs(*(None if x is None else x.unsqueeze(1) for x in inputs))
        outputs, state = self._run(seq, batch, 1, state, normalize)
        return GaitOutputs(*(x.squeeze(1) for x in outputs)), state

    def forward(
        self, inputs: GaitInputs, state: torch.Tensor | None = None
    ) -> tuple[GaitOutputs, torch.Tensor]:
        """Run ``B`` windows of ``T`` frames, teacher-forced (every input frame is given).

        Output frame ``t`` is the prediction for input frame ``t + 1``. Equal to ``T``
        successive :meth:`step` calls.

        Args:
            inputs: windows, every tensor with shape ``(B, T, ...)``; ``emotion`` may be
                ``(B, C)`` (constant over the window) or ``(B, T, C)``.
            state: ``(L, B, H_3)`` state to start from, or ``None`` for :meth:`initial_state`.

        Returns:
            :class:`GaitOutputs` of shapes ``(B, T, J, 4)``, ``(B, T, J, 4)``, ``(B, T, 3)``,
            and the ``(L, B, H_3)`` state after the last frame.

        Raises:
            ValueError: as for :meth:`step`.
        """
        batch, frames = self._check(inputs, sequence=True)
        if inputs.emotion.ndim == 2:
            inputs = inputs._replace(
                emotion=inputs.emotion.unsqueeze(1).expand(batch, frames, -1)
            )
        return self._run(inputs, batch, frames, state)

    def _run(
        self, inputs: GaitInputs, batch: int, frames: int, state: torch.Tensor | None,
        normalize: bool = True,
    ) -> tuple[GaitOutputs, torch.Tensor]:
        """The network on ``(B, T, ...)`` inputs; shared by :meth:`step` and :meth:`forward`."""
        cfg = self.config
        if state is None:
            state = self.initial_state(batch, inputs.rotations.dtype, inputs.rotations.device)
        elif tuple(state.shape) != (cfg.gru_layers, batch, cfg.gru_hidden):
            raise ValueError(
                f"state must have shape (L={cfg.gru_layers}, B={batch}, "
                f"H_3={cfg.gru_hidden}), got {tuple(state.shape)}"
            )
        m = inputs.emotion
        movement = (inputs.movement - self.movement_mean) / self.movement_std
        root = (inputs.root - self.root_mean) / self.root_std
        if cfg.use_affective:
            affective = (inputs.affective - self.affective_mean) / self.affective_std
            i1 = torch.cat((affective, m), -1)
        else:
            i1 = m
        gamma = torch.cat((self.fc_enc1(i1), self.fc_enc2(torch.cat((movement, m), -1))), -1)
        q = inputs.rotations.reshape(batch, frames, 4 * cfg.num_joints)
        q_latent, state = self.gru(torch.cat((q, gamma), -1), state)
        r_latent = self.fc_root(torch.cat((root, gamma), -1))
        raw = self.fc_versors(q_latent).reshape(batch, frames, cfg.num_joints, 4)
        root_next = torch.cat(
            (self.fc_h(r_latent), self.fc_s(r_latent), self.fc_delta(r_latent)), -1
        )
        root_next = root_next * self.root_std + self.root_mean
        rotations = quaternion_normalize(raw) if normalize else raw
        return GaitOutputs(rotations, raw, root_next), state

    def _check(self, inputs: GaitInputs, sequence: bool) -> tuple[int, ...]:
        """Validate shapes; return ``(B,)`` for a frame or ``(B, T)`` for a window."""
        cfg = self.config
        lead = "B, T" if sequence else "B"
        rot = inputs.rotations
        nlead = 2 if sequence else 1
        if not isinstance(rot, torch.Tensor) or rot.ndim != nlead + 2 or tuple(
            rot.shape[nlead:]
        ) != (cfg.num_joints, 4):
            shape = tuple(rot.shape) if isinstance(rot, torch.Tensor) else type(rot).__name__
            raise ValueError(
                f"rotations must have shape ({lead}, J={cfg.num_joints}, 4), got {shape}"
            )
        dims = tuple(rot.shape[:nlead])

        def check(name: str, x: torch.Tensor | None, size: int, what: str) -> None:
            if not isinstance(x, torch.Tensor):
                raise ValueError(f"{name} must be a tensor of shape ({lead}, {size}) ({what})")
            allowed = [(*dims, size)]
            if name == "emotion" and sequence:
                allowed.append((dims[0], size))
            if tuple(x.shape) not in allowed:
                raise ValueError(
                    f"{name} must have shape ({lead}, {size}) ({what}) for rotations of shape "
                    f"{tuple(rot.shape)}, got {tuple(x.shape)}"
                )

        if cfg.use_affective:
            check("affective", inputs.affective, AFFECTIVE_SIZE, "the 18 affective features")
        if isinstance(inputs.emotion, torch.Tensor) and inputs.emotion.shape[-1:] != (
            cfg.num_labels,
        ):
            raise ValueError(
                f"emotion vectors must have {cfg.num_labels} entries, one per label "
                f"{cfg.labels}, got shape {tuple(inputs.emotion.shape)}"
            )
        check("emotion", inputs.emotion, cfg.num_labels, f"weights over {cfg.labels}")
        check("movement", inputs.movement, MOVEMENT_SIZE, ", ".join(MOVEMENT_INPUT_NAMES))
        check("root", inputs.root, ROOT_SIZE, ", ".join(ROOT_FEATURE_NAMES))
        return dims


def same_hemisphere(q: torch.Tensor, reference: torch.Tensor) -> torch.Tensor:
    """``q`` with each quaternion's sign flipped where it lies opposite ``reference``.

    The motion loss compares Euler angles, which are the same for ``q`` and ``-q``, so the
    network may predict either; the data it reads is sign-continuous over time. A prediction
    fed back as the next input is put in the hemisphere of the input it followed.

    Args:
        q: ``(..., 4)`` quaternions.
        reference: ``(..., 4)`` quaternions, broadcastable to ``q``.
    """
    return torch.where((q * reference).sum(-1, keepdim=True) < 0, -q, q)
