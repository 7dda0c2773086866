"""Novel trajectories: random smooth ground paths with turns, a function of (seed, index).

The main paper's augmented data set walks "20 trajectories not present in the dataset"
(Bhattacharya et al. 2020, section 5.2). The data's root paths are short (5-8 m) straight
walks and single turns; these are long paths with several turns of random side, angle and
curvature, drawn from the ranges below (stated on the docs page, recorded in every folder's
recipe) and checked against the data by :mod:`emotive.synth.novelty`.

A path starts at the origin facing +Z. Its signed curvature along the arc length is zero on
straight stretches and a smooth bump on each turn (a raised-cosine ramp of :data:`RAMP`
metres at either end, scaled so the turn's angle is exact), so the heading and the curvature
are continuous; integrating the heading gives the ``(x, z)`` points, :data:`SPACING` apart.

Draws, for trajectory ``p`` with seed ``s`` (one NumPy generator seeded ``[s, 1, p]``; its
draw ``k > 0``, taken when the earlier ones coincide with the data, :mod:`emotive.synth.novelty`,
from one seeded ``[s, 1, p, k]``):

* length ``L = seconds x U(LENGTH_PER_SECOND) + LENGTH_MARGIN`` metres: longer than the
  fastest emotion walks in ``seconds`` (about 1.8 m/s), so no agent reaches the end and stops;
* then straight stretches of ``U(MIN_STRAIGHT, MAX_STRAIGHT)`` metres and turns alternate,
  from a straight, until the length is reached (the last piece cut there);
* per turn, an angle ``U(TURN_ANGLE_DEG)`` degrees to a random side at a curvature
  ``U(CURVATURE)`` 1/m (radius 1.25-4 m, the most the path reaches), its arc
  ``angle / curvature + RAMP``.

Short straights and many turns (about 2.5 per 10 m) set the paths apart from the data's
walks, which are straight or make one turn (:mod:`emotive.synth.novelty`).

Legend: ``P`` points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.paths import GroundPath

#: Metres of path per second of walk, ``(low, high)``.
LENGTH_PER_SECOND = (2.0, 2.5)
#: Metres added to every path's length.
LENGTH_MARGIN = 2.0
#: Angle of one turn, degrees, ``(low, high)``.
TURN_ANGLE_DEG = (30.0, 150.0)
#: Curvature on a turn, 1/m, ``(low, high)``.
CURVATURE = (0.25, 0.8)
#: Shortest and longest straight stretch between turns (and at either end), metres.
MIN_STRAIGHT = 0.5
MAX_STRAIGHT = 3.0
#: Length of the curvature's ramp at either end of a turn, metres.
RAMP = 0.5
#: Spacing of the path's points, metres.
SPACING = 0.01
#: Seed stream of the trajectories (the second entry of every generator's seed).
STREAM = 1


def ranges() -> dict[str, object]:
    """The ranges above, for the recipe and the data set card."""
    return {"length_per_second_m": list(LENGTH_PER_SECOND), "length_margin_m": LENGTH_MARGIN,
            "turn_angle_deg": list(TURN_ANGLE_DEG),
            "curvature_per_m": list(CURVATURE), "straight_m": [MIN_STRAIGHT, MAX_STRAIGHT],
            "ramp_m": RAMP, "spacing_m": SPACING}


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One novel trajectory and what it was drawn as.

    Attributes:
        index: trajectory index ``p``.
        path: the ground path.
        turn_angles_deg: ``(K,)`` signed angle of each turn, degrees (positive: left); a turn
            cut by the end of the path counts with the angle it reaches.
        max_curvature: largest ``|curvature|`` along it, 1/m.
        draw: which draw of trajectory ``p`` it is (module docstring), 0 for the first.
    """

    index: int
    path: GroundPath
    turn_angles_deg: tuple[float, ...]
    max_curvature: float
    draw: int = 0

    @property
    def turns(self) -> int:
        """Number of turns, ``K``."""
        return len(self.turn_angles_deg)

    @property
    def length(self) -> float:
        """Arc length, metres."""
        return self.path.length

    def summary(self) -> dict[str, object]:
        """JSON-able facts of the trajectory for the card."""
        return {"path_id": self.index, "draw": self.draw, "length_m": round(self.length, 2),
                "turns": self.turns,
                "turn_angles_deg": [round(a, 1) for a in self.turn_angles_deg],
                "max_curvature_per_m": round(self.max_curvature, 3)}


def trajectory(seed: int, index: int, seconds: float, draw: int = 0) -> Trajectory:
    """Trajectory ``index`` of a recipe with ``seed`` and walks of ``seconds`` (module docstring).

    Args:
        seed: the recipe's seed.
        index: trajectory index ``p >= 0``.
        seconds: length of the walks on it, seconds.
        draw: which draw ``k >= 0`` of it (0: the first).

    Returns:
        The trajectory; the same arguments give the same points, bit for bit.
    """
    rng = np.random.default_rng([seed, STREAM, index] + ([draw] if draw else []))
    length = seconds * rng.uniform(*LENGTH_PER_SECOND) + LENGTH_MARGIN
    straights, angles, arcs = [rng.uniform(MIN_STRAIGHT, MAX_STRAIGHT)], [], []
    while sum(straights) + sum(arcs) < length:
        angle = np.radians(rng.uniform(*TURN_ANGLE_DEG)) * rng.choice((-1.0, 1.0))
        # The ramps at either end hold half the area of full curvature: one ramp in all.
        arcs.append(abs(angle) / rng.uniform(*CURVATURE) + RAMP)
        angles.append(angle)
        straights.append(rng.uniform(MIN_STRAIGHT, MAX_STRAIGHT))
    kappa = _curvature(np.array(straights), np.array(angles), np.array(arcs))
    kappa = kappa[:round(length / SPACING) + 1]
    heading = np.concatenate(([0.0], np.cumsum(0.5 * (kappa[1:] + kappa[:-1]) * SPACING)))
    steps = np.stack((np.sin(heading), np.cos(heading)), 1) * SPACING
    points = np.vstack(([0.0, 0.0], np.cumsum(0.5 * (steps[1:] + steps[:-1]), 0)))
    path = GroundPath.from_polyline(points, name=f"synth-path-{index}")
    # A turn cut short by the end of the path counts with the angle it reaches.
    starts = np.cumsum(straights[:-1]) + np.concatenate(([0.0], np.cumsum(arcs[:-1])))
    reached = [float(np.degrees(angle) * min(1.0, (length - start) / arc))
               for angle, start, arc in zip(angles, starts, arcs, strict=True) if start < length]
    return Trajectory(index, path, tuple(reached), float(np.abs(kappa).max()), draw)


def _curvature(straights: np.ndarray, angles: np.ndarray, arcs: np.ndarray) -> np.ndarray:
    """``(P,)`` curvature at every :data:`SPACING` of arc: straights and turns alternating.

    Each turn's profile is flat in its middle and a raised cosine over :data:`RAMP` metres at
    either end, scaled so that it integrates to the turn's angle (the flat part is then the
    drawn curvature, up to the sampling).
    """
    pieces = []
    for k, straight in enumerate(straights):
        pieces.append(np.zeros(max(1, round(straight / SPACING))))
        if k < len(arcs):
            n = max(3, round(arcs[k] / SPACING))
            s = (np.arange(n) + 0.5) * SPACING
            edge = np.minimum(np.minimum(s, arcs[k] - s) / RAMP, 1.0)
            shape = 0.5 - 0.5 * np.cos(np.pi * np.clip(edge, 0.0, 1.0))
            pieces.append(angles[k] * shape / (shape.sum() * SPACING))
    return np.concatenate(pieces)
