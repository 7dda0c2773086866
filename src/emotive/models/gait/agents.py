"""The per-agent state of :class:`~emotive.models.gait.generate.GaitGenerator`, as one batch.

Every field is one array (or tensor) with the agents along one axis (:data:`BATCH_AXIS`), so
that adding and removing agents is one function each (:func:`joined`, :func:`kept`) and the
fields never drift out of step.

Legend: ``B`` agents, ``J`` joints, ``C`` emotion labels, ``L`` GRU layers, ``H`` hidden size.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import torch

from emotive.ik.foot_lock import LockState, initial_lock_state

#: Axis of the agents in each field (the GRU state is ``(L, B, H)``; every other field leads
#: with ``B``).
BATCH_AXIS = {"state": 1}


@dataclass(frozen=True)
class AgentBatch:
    """Everything the generator keeps per agent, one row per agent in batch order.

    Attributes:
        state: ``(L, B, H)`` GRU state of the network.
        rotations: ``(B, J, 4)`` current heading-canonical local rotations.
        root: ``(B, 3)`` current root features ``[h, s, delta]``.
        affective: ``(B, 18)`` affective features of the current pose.
        emotion: ``(B, C)`` current emotion weights.
        theta: ``(B,)`` stepping phase, radians.
        speed_lowpass: ``(B,)`` low-passed target speed, metres per frame.
        arc: ``(B,)`` arc length along the agent's path, metres.
        delta: ``(B,)`` low-passed facing offset into turns, radians.
        clock: ``(B,)`` seconds since the agent was added.
        kappa: ``(B,)`` curvature input ``s^2 |k|``.
        heading: ``(B,)`` world yaw, radians (0 faces +Z).
        offset: ``(B, 2)`` gap to the path still to close after a path change, metres.
        slot: ``(B,)`` the agent's path in the generator's :class:`~emotive.paths.bank.PathBank`.
        pace: ``(B,)`` factor on the emotion's walking speed (1 = as the data walks).
        curvature: ``(B,)`` signed curvature of each agent's path at its arc, 1/m (kept from
            the step that moved it there, so a step looks each path up once).
        feet_previous: ``(B, 2, 2, 3)`` unlocked heel and toe positions of the last frame.
        feet_planted: ``(B, 2, 2)`` which heels and toes are planted.
        feet_anchor: ``(B, 2, 2)`` where each planted point is held ``(x, z)``.
        feet_correction: ``(B, 2, 2)`` each foot's horizontal correction, metres (see
            :mod:`emotive.ik.foot_lock`).
        feet_yaw_anchor: ``(B, 2)`` world yaw each foot in contact is held at, radians.
        feet_yaw_correction: ``(B, 2)`` each foot's yaw correction, radians.
        feet_released: ``(B, 2)`` frames since each foot's contact ended.
    """

    state: torch.Tensor
    rotations: torch.Tensor
    root: torch.Tensor
    affective: torch.Tensor
    emotion: np.ndarray
    theta: np.ndarray
    speed_lowpass: np.ndarray
    arc: np.ndarray
    delta: np.ndarray
    clock: np.ndarray
    kappa: np.ndarray
    heading: np.ndarray
    offset: np.ndarray
    slot: np.ndarray
    pace: np.ndarray
    curvature: np.ndarray
    feet_previous: np.ndarray
    feet_planted: np.ndarray
    feet_anchor: np.ndarray
    feet_correction: np.ndarray
    feet_yaw_anchor: np.ndarray
    feet_yaw_correction: np.ndarray
    feet_released: np.ndarray

    @property
    def feet(self) -> LockState:
        """The foot-lock fields as the :func:`~emotive.ik.foot_lock.lock_feet` state."""
        return LockState(self.feet_previous, self.feet_planted, self.feet_anchor,
                         self.feet_correction, self.feet_yaw_anchor, self.feet_yaw_correction,
                         self.feet_released)

    def with_feet(self, feet: LockState, **changes: object) -> AgentBatch:
        """A batch with the foot-lock state (and any other fields) replaced."""
        return replace(self, feet_previous=feet.previous, feet_planted=feet.planted,
                       feet_anchor=feet.anchor, feet_correction=feet.correction,
                       feet_yaw_anchor=feet.yaw_anchor, feet_yaw_correction=feet.yaw_correction,
                       feet_released=feet.released, **changes)

    def __len__(self) -> int:
        return len(self.theta)

    def with_values(self, **changes: object) -> AgentBatch:
        """A batch with some fields replaced (same agents)."""
        return replace(self, **changes)


def empty_batch(state: torch.Tensor, joints: int, labels: int, dtype: torch.dtype
                ) -> AgentBatch:
    """A batch of no agents.

    Args:
        state: ``(L, 0, H)`` the network's initial state for no agents.
        joints: ``J``.
        labels: ``C``.
        dtype: float type of the network tensors.
    """
    return AgentBatch(
        state, torch.zeros(0, joints, 4, dtype=dtype), torch.zeros(0, 3, dtype=dtype),
        torch.zeros(0, 18, dtype=dtype), np.zeros((0, labels)), *(np.zeros(0) for _ in range(7)),
        np.zeros((0, 2)), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
        *initial_lock_state(0),
    )


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
