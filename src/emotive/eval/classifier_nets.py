"""The perceived-emotion classifier's networks (see :mod:`emotive.eval.classifier`).

Both read ``(B, T, F)`` standardized per-frame features and give the label logits and the
auxiliary valence/arousal and shared-style outputs: :class:`EmotionClassifierNet` (a temporal
convolution network, ``"tcn"``) and :class:`EmotionGraphNet` (a spatial-temporal graph network
over the role skeleton, ``"stgcn"``), picked by :data:`ARCHITECTURES`.

Legend: ``B`` windows, ``T`` frames, ``F`` features, ``J`` joint roles.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

import numpy as np
import torch
from torch import nn

from emotive.core.roles import ROLE_PARENT, ROLES


class NetSizes(Protocol):
    """What a network reads from its :class:`~emotive.eval.classifier.ClassifierConfig`."""

    labels: tuple[str, ...]
    style_labels: tuple[str, ...]
    architecture: str
    channels: int
    blocks: int
    graph_channels: int
    graph_blocks: int
    affect_channels: int
    dropout: float

#: Number of per-frame feature columns.
NUM_FEATURES = 2 * 3 * len(ROLES) + 18 + 8

#: Feature columns holding the joint roles' positions then velocities (``2 * J * 3``).
JOINT_COLUMNS = 2 * 3 * len(ROLES)

#: The role skeleton as undirected edges: spine chain, arms from the chest, legs from the root.
ROLE_EDGES: tuple[tuple[str, str], ...] = tuple(
    (parent, role) for role, parent in ROLE_PARENT.items())


class _Block(nn.Module):
    def __init__(self, channels: int, dilation: int) -> None:
        super().__init__()
        self.conv = nn.Conv1d(channels, channels, 5, padding=2 * dilation, dilation=dilation)
        self.act = nn.ELU()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.act(self.conv(x))


class _Heads(nn.Module):
    """The heads shared by both networks on the pooled ``(B, E)`` embedding.

    Subclasses define ``embed(x)``: ``(B, T, F)`` standardized features to ``(B, E)``.
    """

    def __init__(self, config: NetSizes, width: int) -> None:
        super().__init__()
        self.drop = nn.Dropout(config.dropout)
        self.out = nn.Linear(width, len(config.labels))
        self.aux = nn.Linear(width, 2 + len(config.style_labels))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, C)`` label logits of ``(B, T, F)`` standardized features."""
        return self.out(self.drop(self.embed(x)))

    def heads(self, x: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Everything the network says about ``(B, T, F)`` standardized features.

        Returns:
            ``(B, E)`` embedding, ``(B, C)`` label logits, ``(B, 2)`` valence/arousal in
            -1..1 and ``(B, S)`` shared-style logits.
        """
        e = self.embed(x)
        h = self.drop(e)
        aux = self.aux(h)
        return e, self.out(h), torch.tanh(aux[:, :2]), aux[:, 2:]


class EmotionClassifierNet(_Heads):
    """Temporal CNN (``"tcn"``): ``(B, T, F)`` standardized features to ``(B, C)`` logits."""

    def __init__(self, config: NetSizes) -> None:
        super().__init__(config, config.channels)
        c = config.channels
        self.inp = nn.Sequential(nn.Conv1d(NUM_FEATURES, c, 5, padding=2), nn.ELU())
        self.blocks = nn.Sequential(*(_Block(c, 2 ** (k + 1)) for k in range(config.blocks)))

    def embed(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, E = channels)`` mean over time of the last block."""
        return self.blocks(self.inp(x.transpose(1, 2))).mean(-1)


def role_adjacency() -> np.ndarray:
    """Normalized adjacency of the role skeleton with self loops.

    ``D^-1/2 (A + I) D^-1/2`` with ``D`` the degrees of ``A + I`` (Kipf and Welling's
    normalization): symmetric, so a joint hears its neighbours as they hear it, and its
    largest eigenvalue is 1, so stacked blocks neither blow up nor fade the signal.

    Returns:
        ``(J, J)`` float32, rows and columns in :data:`ROLES` order.
    """
    a = np.eye(len(ROLES))
    for u, v in ROLE_EDGES:
        a[ROLES.index(u), ROLES.index(v)] = a[ROLES.index(v), ROLES.index(u)] = 1.0
    scale = 1.0 / np.sqrt(a.sum(1))
    return (scale[:, None] * a * scale[None, :]).astype(np.float32)


#: Frames seen by each temporal convolution of the graph blocks (ST-GCN's 9).
_TEMPORAL_KERNEL = 9


class _GraphBlock(nn.Module):
    """ST-GCN block, ``(B, T, J, c_in)`` to ``(B, ceil(T / stride), J, c_out)`` (c: channels).

    Channels stay last: the per-joint channel mixing is then a linear layer, and the temporal
    convolution sees a channels-last ``(B, c, T, J)`` view, the layout that the CPU kernels
    run several times faster than the default one.
    """

    def __init__(self, c_in: int, c_out: int, stride: int) -> None:
        super().__init__()
        self.stride = stride
        self.spatial = nn.Linear(c_in, c_out)
        self.temporal = nn.Conv2d(c_out, c_out, (_TEMPORAL_KERNEL, 1), stride=(stride, 1),
                                  padding=(_TEMPORAL_KERNEL // 2, 0))
        self.residual = nn.Identity() if c_in == c_out else nn.Linear(c_in, c_out)
        self.act = nn.ELU()
        # Fixed by ROLE_EDGES, so it is rebuilt on load rather than stored in the file.
        self.register_buffer("adjacency", torch.from_numpy(role_adjacency()), persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        # A is symmetric, so A @ h over the J axis gathers each joint's neighbours untransposed.
        h = self.act(self.adjacency @ self.spatial(x))
        h = self.temporal(h.permute(0, 3, 1, 2)).permute(0, 2, 3, 1)
        # Padding k // 2 on each side leaves ceil(T / stride) frames, as many as x[:, ::stride].
        return self.act(h + self.residual(x[:, ::self.stride]))


def joint_nodes(x: torch.Tensor) -> torch.Tensor:
    """Per-joint node signals of feature windows.

    Args:
        x: ``(B, T, F)`` features (the first :data:`JOINT_COLUMNS` are positions then
            velocities, each ``(J, 3)`` flattened).

    Returns:
        ``(B, T, J, 6)``: each role's position (x, y, z) then velocity (x, y, z).
    """
    b, t, _ = x.shape
    nodes = x[..., :JOINT_COLUMNS].reshape(b, t, 2, len(ROLES), 3)
    return nodes.permute(0, 1, 3, 2, 4).reshape(b, t, len(ROLES), 6)


class EmotionGraphNet(_Heads):
    """Spatial-temporal graph network (``"stgcn"``): ``(B, T, F)`` to ``(B, C)`` logits.

    The joint columns become ``(B, T, J, 6)`` node signals (:func:`joint_nodes`);
    blocks after the first halve the frame rate, as ST-GCN's later layers do, which keeps CPU
    training short and widens what each temporal convolution sees.
    """

    def __init__(self, config: NetSizes) -> None:
        super().__init__(config, config.graph_channels + config.affect_channels)
        c = config.graph_channels
        self.blocks = nn.Sequential(*(
            _GraphBlock(6 if k == 0 else c, c, 1 if k == 0 else 2)
            for k in range(config.graph_blocks)
        ))
        a = config.affect_channels
        self.affect = nn.Sequential(
            nn.Conv1d(NUM_FEATURES - JOINT_COLUMNS, a, 5, padding=2), nn.ELU(), _Block(a, 2)
        )

    def embed(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, E = graph_channels + affect_channels)``: graph and affect summaries."""
        graph = self.blocks(joint_nodes(x)).mean((1, 2))
        affect = self.affect(x[..., JOINT_COLUMNS:].transpose(1, 2)).mean(-1)
        return torch.cat((graph, affect), 1)


#: Network constructors by :attr:`~emotive.eval.classifier.ClassifierConfig.architecture`.
ARCHITECTURES: dict[str, Callable[[NetSizes], nn.Module]] = {
    "tcn": EmotionClassifierNet,
    "stgcn": EmotionGraphNet,
}


def build_net(config: NetSizes) -> nn.Module:
    """The untrained network of ``config.architecture``."""
    return ARCHITECTURES[config.architecture](config)
