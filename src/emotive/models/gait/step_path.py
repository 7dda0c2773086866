"""Path following from points sampled ahead of each agent, as the exported step does it.

An engine keeps each agent's arc length along its path and, every frame, samples the path at
``K`` arc offsets around it, ``first + k * spacing`` metres (:class:`PathSampling`), in the
agent's frame: origin at the agent's ground position, +Z along its heading, +X to its left
(a world point ``(wx, wz)`` relative to the agent is ``(c wx - s wz, s wx + c wz)`` with
``c, s = cos, sin`` of the heading). Open paths continue straight past their ends. From
those points the step reads the path's position, tangent and curvature anywhere between
them: positions on the Catmull-Rom spline through the samples (off a 2 m circle by well
under a micrometre; straight chords between 5 cm samples would cut it by 0.16 mm), and the
formulas of :class:`~emotive.paths.GroundPath` (tangent from a chord across the point,
curvature as the turn of the tangent over :data:`~emotive.paths.bank.CURVATURE_WINDOW`
metres).

Legend: ``B`` agents, ``K`` samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from emotive.paths.bank import CURVATURE_WINDOW

#: Metres between two path samples.
SAMPLE_SPACING = 0.05
#: Samples behind the agent's arc length (so the tangent and curvature there are defined,
#: with one more for the spline).
SAMPLES_BEHIND = 4


@dataclass(frozen=True)
class PathSampling:
    """Where the path is sampled around an agent: arc offsets ``first + k * spacing``.

    Attributes:
        count: ``K`` samples.
        first: offset of the first sample, metres (negative: behind the agent).
        spacing: metres between samples.
    """

    count: int
    first: float
    spacing: float

    @classmethod
    def for_step(cls, max_step: float) -> PathSampling:
        """Enough samples for a step of up to ``max_step`` metres and the curvature there."""
        ahead = math.ceil((max_step + 0.5 * CURVATURE_WINDOW + SAMPLE_SPACING) / SAMPLE_SPACING)
        return cls(SAMPLES_BEHIND + ahead + 2, round(-SAMPLES_BEHIND * SAMPLE_SPACING, 9),
                   SAMPLE_SPACING)

    def offsets(self) -> np.ndarray:
        """``(K,)`` the arc offsets, metres."""
        return self.first + self.spacing * np.arange(self.count)

    def to_json(self) -> dict:
        """The sampling as the graph's metadata states it."""
        return {"count": self.count, "first": self.first, "spacing": self.spacing}


#: The uniform Catmull-Rom spline as weights of ``p0 .. p3`` per power of ``t`` (rows ``1, t,
#: t^2, t^3``): the segment from ``p1`` to ``p2``.
CATMULL_ROM = ((0.0, 1.0, 0.0, 0.0), (-0.5, 0.0, 0.5, 0.0), (1.0, -2.5, 2.0, -0.5),
               (-0.5, 1.5, -1.5, 0.5))


def point_at(samples: torch.Tensor, u: torch.Tensor, sampling: PathSampling) -> torch.Tensor:
    """``(B, M, 2)`` the path at arc offsets ``u`` ``(B, M)``.

    The Catmull-Rom spline through the samples ``(B, K, 2)`` (uniform: it passes through
    every sample), its four control points gathered at once.
    """
    x = (u - sampling.first) / sampling.spacing
    i = torch.floor(x).clamp(1.0, sampling.count - 3.0)
    t = x - i
    four = torch.arange(-1, 3, device=u.device)
    index = (i.long()[..., None] + four).flatten(1)
    powers = torch.stack((torch.ones_like(t), t, t * t, t * t * t), -1)
    weights = powers @ torch.tensor(CATMULL_ROM, dtype=samples.dtype, device=samples.device)
    x, z = (torch.gather(samples[..., k], 1, index).unflatten(1, (-1, 4)) for k in (0, 1))
    return torch.stack(((weights * x).sum(-1), (weights * z).sum(-1)), -1)


def path_at(samples: torch.Tensor, u: torch.Tensor, sampling: PathSampling
            ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Everything the step reads of the path, from one evaluation of the spline.

    Args:
        samples: ``(B, K, 2)`` the samples.
        u: ``(B,)`` arc offsets, metres.
        sampling: where the samples lie.

    Returns:
        The point at offset 0 ``(B, 2)``, the point at ``u`` ``(B, 2)``, the yaw of the
        tangent at ``u`` ``(B,)`` (0 faces +Z) and the signed curvature at ``u`` ``(B,)``
        (1/m, positive turning left). The tangent is the chord between the points
        ``spacing`` before and after; where the path does not move (every sample the same
        point) it is taken as +Z, straight ahead (``atan2(0, 0)`` is 0 in torch but NaN in
        ONNX's form of it). The curvature is the turn of the tangent over
        :data:`~emotive.paths.bank.CURVATURE_WINDOW` metres.
    """
    h, ds = 0.5 * CURVATURE_WINDOW, sampling.spacing
    shifts = u.new_tensor([ds, -ds, h + ds, h - ds, -h + ds, -h - ds])
    us = torch.cat((torch.zeros_like(u)[:, None], u[:, None], u[:, None] + shifts), 1)
    p = point_at(samples, us, sampling)
    d = p[:, 2::2] - p[:, 3::2]  # (B, 3, 2) chords at u, u + h, u - h
    still = (d * d).sum(-1) < 1e-20
    yaw = torch.atan2(d[..., 0], torch.where(still, torch.ones_like(d[..., 1]), d[..., 1]))
    turn = yaw[:, 1] - yaw[:, 2]
    curvature = torch.atan2(torch.sin(turn), torch.cos(turn)) / CURVATURE_WINDOW
    return p[:, 0], p[:, 1], yaw[:, 0], curvature


def to_agent_frame(points: np.ndarray, xz: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """``(B, K, 2)`` world points ``(B, K, 2)`` in the frames of agents at ``xz`` ``(B, 2)``.

    The agents face ``heading`` ``(B,)`` (radians); see the module docstring.
    """
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    d = points - xz[:, None, :]
    return np.stack((c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]), -1)
