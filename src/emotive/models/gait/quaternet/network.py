"""QuaterNet (Pavllo et al. 2018): a quaternion GRU predicting the next frame's joint rotations.

Legend: ``B`` agents (batch), ``T`` frames, ``J`` joints, ``L`` GRU layers, ``H`` GRU width.

Per frame ``t``::

    c    = FC_c([sin theta, cos theta, omega, s_lowpass, kappa])   (two layers, leaky ReLU)
    h    = GRU([q; c])                                             (the only recurrence)
    raw  = FC_out(h)                      absolute,   or   FC_out(h) * q   (residual)
    q^   = raw / |raw|                    next local rotations, unit quaternions

This is the baseline of Emotive Gaits (sections 5.5-5.6): no emotion, no affective features,
no root features. The movement inputs are QuaterNet's controls: its long-term locomotion model
reads the walking phase (as ``cos``, ``sin`` scaled by the speed), the speed and the direction
of the path, which ``theta``, ``s_lowpass`` and ``kappa`` carry here in the body's own frame
(every frame is heading-canonical); ``use_movement=False`` drops them (QuaterNet's short-term
model). As in QuaterNet, the GRU starts from a learned initial state. Like
:class:`~emotive.models.gait.GaitNetwork`, the hidden state is carried: :meth:`step` advances
one frame and :meth:`forward` over ``T`` frames equals ``T`` steps. The movement inputs are
standardised inside the network with buffers (identity until :meth:`set_feature_statistics`).
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import nn

from emotive.models.gait.config import MOVEMENT_INPUT_NAMES
from emotive.models.gait.quaternet.config import QuaterNetConfig
from emotive.transforms.rotations import quaternion_multiply, quaternion_normalize

MOVEMENT_SIZE = len(MOVEMENT_INPUT_NAMES)


class QuaterNetOutputs(NamedTuple):
    """The next frame's rotations (with a ``T`` axis after ``B`` from ``forward``).

    Attributes:
        rotations: ``(B, J, 4)`` next local rotations, unit quaternions.
        raw_rotations: ``(B, J, 4)`` the same before normalization (for the unit-norm
            penalty).
    """

    rotations: torch.Tensor
    raw_rotations: torch.Tensor


class QuaterNetwork(nn.Module):
    """The QuaterNet pose network with a streaming step API.

    Args:
        config: sizes and switches; kept as ``self.config`` for checkpoints.

    Example::

        net = QuaterNetwork(QuaterNetConfig())
        state = net.initial_state(batch=8)
        outputs, state = net.step(rotations, movement, state)  # (8, 22, 4), (8, 5)
    """

    def __init__(self, config: QuaterNetConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or QuaterNetConfig()
        controls = 0
        if cfg.use_movement:
            controls = cfg.control_hidden
            self.fc_controls = nn.Sequential(
                nn.Linear(MOVEMENT_SIZE, controls), nn.LeakyReLU(0.05),
                nn.Linear(controls, controls), nn.LeakyReLU(0.05),
            )
        self.gru = nn.GRU(4 * cfg.num_joints + controls, cfg.gru_hidden,
                          num_layers=cfg.gru_layers, batch_first=True)
        self.initial_hidden = nn.Parameter(
            torch.zeros(cfg.gru_layers, 1, cfg.gru_hidden).normal_(std=0.01)
        )
        self.fc_out = nn.Linear(cfg.gru_hidden, 4 * cfg.num_joints)
        self.register_buffer("movement_mean", torch.zeros(MOVEMENT_SIZE))
        self.register_buffer("movement_std", torch.ones(MOVEMENT_SIZE))

    @property
    def num_parameters(self) -> int:
        """Number of trainable parameters."""
        return sum(p.numel() for p in self.parameters() if p.requires_grad)

    def set_feature_statistics(
        self, movement: tuple[torch.Tensor, torch.Tensor] | None = None
    ) -> None:
        """Set the ``(mean, std)`` used to standardise the movement inputs.

        Args:
            movement: ``(5,)`` mean and std of the movement inputs.

        Raises:
            ValueError: a statistic of the wrong size or a non-positive std.
        """
        if movement is None:
            return
        mean = torch.as_tensor(movement[0], dtype=self.movement_mean.dtype).reshape(-1)
        std = torch.as_tensor(movement[1], dtype=self.movement_std.dtype).reshape(-1)
        if mean.shape != (MOVEMENT_SIZE,) or std.shape != (MOVEMENT_SIZE,):
            raise ValueError(
                f"movement statistics must have shape ({MOVEMENT_SIZE},), got "
                f"{tuple(mean.shape)} and {tuple(std.shape)}"
            )
        if not bool((std > 0).all()):
            raise ValueError("movement std must be positive everywhere")
        self.movement_mean.copy_(mean)
        self.movement_std.copy_(std)

    def initial_state(
        self, batch: int, dtype: torch.dtype | None = None, device: torch.device | None = None
    ) -> torch.Tensor:
        """The learned GRU state before any frame, ``(L, B, H)``."""
        h0 = self.initial_hidden.to(dtype=dtype, device=device)
        return h0.expand(-1, batch, -1).contiguous()

    def step(
        self, rotations: torch.Tensor, movement: torch.Tensor | None,
        state: torch.Tensor | None = None,
    ) -> tuple[QuaterNetOutputs, torch.Tensor]:
        """Advance ``B`` agents by one frame.

        Args:
            rotations: ``(B, J, 4)`` current local rotations (unit quaternions).
            movement: ``(B, 5)`` movement inputs; ignored (may be ``None``) with
                ``use_movement=False``.
            state: ``(L, B, H)`` state from the previous call, or ``None`` for
                :meth:`initial_state`.

        Returns:
            The next frame's :class:`QuaterNetOutputs` (``(B, J, 4)`` each) and the new state.

        Raises:
            ValueError: a tensor or state of the wrong shape.
        """
        self._check(rotations, movement, sequence=False)
        outputs, state = self._run(
            rotations.unsqueeze(1), None if movement is None else movement.unsqueeze(1), state
        )
        return QuaterNetOutputs(*(x.squeeze(1) for x in outputs)), state

    def forward(
        self, rotations: torch.Tensor, movement: torch.Tensor | None,
        state: torch.Tensor | None = None,
    ) -> tuple[QuaterNetOutputs, torch.Tensor]:
        """Run ``B`` windows of ``T`` frames, teacher-forced; equal to ``T`` :meth:`step` calls.

        Output frame ``t`` is the prediction for input frame ``t + 1``.

        Args:
            rotations: ``(B, T, J, 4)`` local rotations.
            movement: ``(B, T, 5)`` movement inputs (or ``None`` with ``use_movement=False``).
            state: ``(L, B, H)`` state to start from, or ``None`` for :meth:`initial_state`.

        Returns:
            :class:`QuaterNetOutputs` of shapes ``(B, T, J, 4)`` and the state after the last
            frame.

        Raises:
            ValueError: as for :meth:`step`.
        """
        self._check(rotations, movement, sequence=True)
        return self._run(rotations, movement, state)

    def _run(
        self, rotations: torch.Tensor, movement: torch.Tensor | None, state: torch.Tensor | None
    ) -> tuple[QuaterNetOutputs, torch.Tensor]:
        """The network on ``(B, T, ...)`` inputs; shared by :meth:`step` and :meth:`forward`."""
        cfg = self.config
        batch, frames = rotations.shape[:2]
        if state is None:
            state = self.initial_state(batch, rotations.dtype, rotations.device)
        elif tuple(state.shape) != (cfg.gru_layers, batch, cfg.gru_hidden):
            raise ValueError(
                f"state must have shape (L={cfg.gru_layers}, B={batch}, H={cfg.gru_hidden}), "
                f"got {tuple(state.shape)}"
            )
        x = rotations.reshape(batch, frames, 4 * cfg.num_joints)
        if cfg.use_movement:
            controls = self.fc_controls((movement - self.movement_mean) / self.movement_std)
            x = torch.cat((x, controls), -1)
        latent, state = self.gru(x, state)
        raw = self.fc_out(latent).reshape(batch, frames, cfg.num_joints, 4)
        if cfg.residual:
            raw = quaternion_multiply(raw, rotations)
        return QuaterNetOutputs(quaternion_normalize(raw), raw), state

    def _check(
        self, rotations: torch.Tensor, movement: torch.Tensor | None, sequence: bool
    ) -> None:
        """Validate the shapes of a frame (``sequence=False``) or of windows."""
        cfg = self.config
        lead, nlead = ("B, T", 2) if sequence else ("B", 1)
        if not isinstance(rotations, torch.Tensor) or rotations.ndim != nlead + 2 or tuple(
            rotations.shape[nlead:]
        ) != (cfg.num_joints, 4):
            shape = (tuple(rotations.shape) if isinstance(rotations, torch.Tensor)
                     else type(rotations).__name__)
            raise ValueError(
                f"rotations must have shape ({lead}, J={cfg.num_joints}, 4), got {shape}"
            )
        if not cfg.use_movement:
            return
        want = (*rotations.shape[:nlead], MOVEMENT_SIZE)
        if not isinstance(movement, torch.Tensor) or tuple(movement.shape) != want:
            shape = (tuple(movement.shape) if isinstance(movement, torch.Tensor)
                     else type(movement).__name__)
            raise ValueError(
                f"movement must have shape ({lead}, {MOVEMENT_SIZE}) "
                f"({', '.join(MOVEMENT_INPUT_NAMES)}) for rotations of shape "
                f"{tuple(rotations.shape)}, got {shape}; pass use_movement=False in the "
                "config for a network without them"
            )
