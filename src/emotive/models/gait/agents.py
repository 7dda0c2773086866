"""What :class:`~emotive.models.gait.generate.GaitGenerator` keeps per agent, as one batch.

Every field is one array (or tensor) with the agents along one axis (:data:`BATCH_AXIS`), so
that adding and removing agents is one function each (:func:`joined`, :func:`kept`) and the
fields never drift out of step. The step's own state is two tensors (the GRU state and the
agent rows of :mod:`~emotive.models.gait.step_layout`); the rest is the host's: what an engine
keeps beside the exported step.

Legend: ``B`` agents, ``S`` the agent row, ``C`` emotion labels, ``L`` GRU layers, ``H``
hidden size.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import torch

#: Axis of the agents in each field (the GRU state is ``(L, B, H)``; every other field leads
#: with ``B``).
BATCH_AXIS = {"state": 1}


@dataclass(frozen=True)
class AgentBatch:
    """Everything the generator keeps per agent, one row per agent in batch order.

    Attributes:
        state: ``(L, B, H)`` GRU state of the network.
        rows: ``(B, S)`` the step's agent rows (pose, controls, placement, foot lock).
        emotion: ``(B, C)`` current emotion weights.
        arc: ``(B,)`` arc length along the agent's path, metres.
        clock: ``(B,)`` seconds since the agent was added.
        slot: ``(B,)`` the agent's path in the generator's :class:`~emotive.paths.bank.PathBank`.
        pace: ``(B,)`` factor on the emotion's walking speed (1 = as the data walks).
    """

    state: torch.Tensor
    rows: torch.Tensor
    emotion: np.ndarray
    arc: np.ndarray
    clock: np.ndarray
    slot: np.ndarray
    pace: np.ndarray

    def __len__(self) -> int:
        return len(self.arc)

    def with_values(self, **changes: object) -> AgentBatch:
        """A batch with some fields replaced (same agents)."""
        return replace(self, **changes)


def empty_batch(state: torch.Tensor, row_size: int, labels: int, dtype: torch.dtype
                ) -> AgentBatch:
    """A batch of no agents.

    Args:
        state: ``(L, 0, H)`` the network's initial state for no agents.
        row_size: ``S``.
        labels: ``C``.
        dtype: float type of the step's tensors.
    """
    return AgentBatch(state, torch.zeros(0, row_size, dtype=dtype), np.zeros((0, labels)),
                      np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0))


def _join(a: np.ndarray | torch.Tensor, b: np.ndarray | torch.Tensor, axis: int
          ) -> np.ndarray | torch.Tensor:
    if isinstance(a, torch.Tensor):
        return torch.cat((a, b), axis)
    return np.concatenate((a, b), axis)


def joined(batch: AgentBatch, new: AgentBatch) -> AgentBatch:
    """``batch`` followed by the agents of ``new``."""
    return AgentBatch(**{
        f.name: _join(getattr(batch, f.name), getattr(new, f.name), BATCH_AXIS.get(f.name, 0))
        for f in fields(AgentBatch)
    })


def kept(batch: AgentBatch, keep: np.ndarray) -> AgentBatch:
    """The agents at batch indices ``keep`` (``(K,)`` ints), in that order."""
    idx = torch.as_tensor(keep, dtype=torch.long)
    out = {}
    for f in fields(AgentBatch):
        value = getattr(batch, f.name)
        axis = BATCH_AXIS.get(f.name, 0)
        out[f.name] = value.index_select(axis, idx) if isinstance(value, torch.Tensor) \
            else np.take(value, keep, axis=axis)
    return AgentBatch(**out)
