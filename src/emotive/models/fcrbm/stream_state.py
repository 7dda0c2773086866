"""Per-agent state of the streaming FCRBM (:mod:`~emotive.models.fcrbm.stream`), and its checks.

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``C`` emotion labels, ``N`` order (past
frames), ``D`` visible units.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np
import torch

from emotive.data.emotion import EmotionSchedule
from emotive.errors import PathError
from emotive.models.fcrbm.generate import FCRBMInputError
from emotive.paths import GroundPath, waypoints

#: Allowed pace factors (times the model's own forward speed).
PACE_RANGE = (0.5, 1.5)
#: A target nearer than this (metres) leaves the agent where it stands.
MIN_TARGET_DISTANCE = 0.05
#: A path to a target leaves along the agent's heading for up to this many metres.
TARGET_LEAD = 0.75


class FCRBMAgentError(FCRBMInputError, KeyError):
    """No live agent has the id asked for (a ``KeyError`` too, as for the gait generator)."""

    __str__ = Exception.__str__


class FCRBMFrame(NamedTuple):
    """One frame of every agent, after :meth:`~emotive.models.fcrbm.stream.FCRBMStream.step`.

    Attributes:
        agents: the ``B`` agent ids, in batch order.
        rotations: ``(B, J, 4)`` local rotations, the mover's carrying the world heading.
        positions: ``(B, J, 3)`` local translations, the mover's its world position (metres).
        world: ``(B, J + E, 3)`` world positions of joints then end sites, metres.
        emotion: ``(B, C)`` emotion weights of each agent at this frame's time, over the
            stream's labels.
        root: ``(B, 2)`` ground position ``(x, z)`` of each agent, metres.
        valence_arousal: ``(B, 2)`` valence/arousal of each agent at this frame's time (-1..1
            scale; the model gets it shifted to its 1..3 scale).
    """

    agents: tuple[int, ...]
    rotations: np.ndarray
    positions: np.ndarray
    world: np.ndarray
    emotion: np.ndarray
    root: np.ndarray
    valence_arousal: np.ndarray


@dataclass
class AgentInfo:
    """Per-agent bookkeeping that is not batched: its emotion, since when, its generator."""

    schedule: EmotionSchedule
    start: int
    generator: torch.Generator


@dataclass
class Rows:
    """Batched per-agent state, one row per agent in batch order.

    ``window``/``seed`` ``(B, N, D)`` tensors; ``context``/``va`` ``(B, 2)``; ``weights``
    ``(B, C)``; ``body``/``body_prev`` ``(B, J, 4)``; ``offset`` ``(B, 2)``; ``feet``
    ``(B, 4, 3)`` the heel and toe points of the last model frame in the body's frame
    (:meth:`~emotive.models.fcrbm.stream_feet.StreamFeet.local_feet`); ``lock_*`` the foot
    lock's state (:class:`~emotive.ik.foot_lock.LockState`, one field each); the rest ``(B,)``:
    ``warm`` the warm-up frames an agent has left (0: it walks), ``stop`` its blend to the
    standing pose, ``speed`` its root speed (m/s).
    """

    window: torch.Tensor
    seed: torch.Tensor
    context: np.ndarray
    va: np.ndarray
    weights: np.ndarray
    body: np.ndarray
    body_prev: np.ndarray
    height: np.ndarray
    height_prev: np.ndarray
    arc: np.ndarray
    arc_prev: np.ndarray
    offset: np.ndarray
    pace: np.ndarray
    slot: np.ndarray
    warm: np.ndarray
    stop: np.ndarray
    feet: np.ndarray
    speed: np.ndarray
    lock_previous: np.ndarray
    lock_planted: np.ndarray
    lock_anchor: np.ndarray
    lock_correction: np.ndarray
    lock_yaw_anchor: np.ndarray
    lock_yaw_correction: np.ndarray
    lock_released: np.ndarray

    def take(self, rows: np.ndarray) -> Rows:
        """The rows ``rows`` (indices), in that order."""
        index = torch.as_tensor(rows, dtype=torch.long)
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        return Rows(**{name: value[index if isinstance(value, torch.Tensor) else rows]
                       for name, value in out.items()})

    def join(self, other: Rows) -> Rows:
        """These rows followed by ``other``'s."""
        out: dict[str, Any] = {}
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            out[f.name] = torch.cat((a, b)) if isinstance(a, torch.Tensor) else np.concatenate(
                (a, b))
        return Rows(**out)


def check_pace(pace: float) -> float:
    """``pace`` as a float if it lies in :data:`PACE_RANGE`.

    Raises:
        FCRBMInputError: outside the range, not finite or not a number.
    """
    lo, hi = PACE_RANGE
    try:
        value = float(pace)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and lo <= value <= hi):
        raise FCRBMInputError(f"pace must be a number from {lo:g} to {hi:g} (times the model's "
                              f"own walking speed), got {pace!r}")
    return value


def check_path(path: Any, start: float = 0.0) -> GroundPath:
    """``path`` if it is a :class:`~emotive.paths.GroundPath` and ``start`` a finite arc length.

    Raises:
        PathError: naming what is wrong.
    """
    if not isinstance(path, GroundPath):
        raise PathError(f"an agent needs a GroundPath to follow (emotive.paths), got "
                        f"{type(path).__name__}")
    if not (isinstance(start, int | float) and math.isfinite(start)):
        raise PathError(f"start must be a finite arc length in metres, got {start!r}")
    return path


def check_seed(seed: Any) -> int:
    """``seed`` as an int if it is a whole number from 0 to ``2**63 - 1``.

    Raises:
        FCRBMInputError: anything else.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not (
            0 <= seed < 2**63):
        raise FCRBMInputError(f"an agent's seed must be a whole number from 0 to 2**63 - 1, "
                              f"got {seed!r}")
    return int(seed)


def agent_seed(seed: int, agent: int) -> int:
    """A torch seed of agent ``agent`` of a stream seeded ``seed`` (well mixed, non-negative)."""
    return int(np.random.SeedSequence([seed, agent]).generate_state(1, np.uint64)[0] >> 1)


def emotion_at(schedules: Sequence[EmotionSchedule], times: Sequence[float], labels: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 2)`` valence/arousal (-1..1) and ``(n, C)`` weights of schedules at times (s).

    Valence/arousal between keyframes is linear in the keyframes' exact points, as
    :meth:`~emotive.data.emotion.EmotionSchedule.sample_valence_arousal` samples it.

    Args:
        schedules: ``n`` schedules over ``labels`` labels.
        times: ``n`` times in seconds, one per schedule.
        labels: ``C``.
    """
    va = np.array([[np.interp(t, s.times, s.points[:, d]) for d in range(2)]
                   for s, t in zip(schedules, times, strict=True)]).reshape(-1, 2)
    weights = np.array([s.at(float(t)) for s, t in zip(schedules, times, strict=True)])
    return va, weights.reshape(-1, labels)


def target_path(here: np.ndarray, yaw: float, xz: Any) -> GroundPath:
    """A smooth path from ``here`` ``(2,)``, leaving along heading ``yaw``, to ``xz`` (metres).

    A spline through ``here``, a lead point up to :data:`TARGET_LEAD` ahead and the target; a
    target nearer than :data:`MIN_TARGET_DISTANCE` gives a 1 cm path ahead (the agent stays).

    Raises:
        PathError: ``xz`` is not two finite numbers, or lies beyond
            :data:`emotive.paths.MAX_COORDINATE`.
    """
    try:
        target = np.asarray(xz, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        target = np.full(1, np.nan)
    if target.shape != (2,) or not np.isfinite(target).all():
        raise PathError(f"set_target: the target must be two finite numbers (x, z) in metres, "
                        f"got {xz!r}")
    facing = np.array([math.sin(yaw), math.cos(yaw)])
    gap = float(np.linalg.norm(target - here))
    if gap < MIN_TARGET_DISTANCE:
        return GroundPath.from_polyline(np.stack((here, here + 0.01 * facing)), name="target")
    lead = here + min(TARGET_LEAD, 0.4 * gap) * facing
    return waypoints(np.stack((here, lead, target)), name="target")
