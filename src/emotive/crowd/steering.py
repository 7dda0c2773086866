"""How crowd agents pick their way: the next corner of a route, and stepping aside.

Legend: ``B`` agents.

An agent walks at the next corner of its shortest route (:func:`next_corner`). An agent with
someone coming the other way in front of it steps to its right, and one behind a slower
agent going its way passes it on the left (:func:`sidestep`): pedestrians who meet prefer
to pass on one side, and in counterflow that preference forms lanes (Moussaid et al. 2009,
"Experimental study of the behavioural mechanisms underlying self-organization in human
crowds", Proc. R. Soc. B 276). JuPedSim's collision-free speed model only slows an agent
behind another and stops two that meet head on, so without these rules a dense counterflow
jams. The side (the right) is a convention; every distance here is our choice.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["CORNER_PASS", "ONCOMING_RANGE", "ONCOMING_WIDTH", "OVERTAKE_RANGE", "SIDESTEP_AHEAD",
           "SIDESTEP_RIGHT", "next_corner", "sidestep"]

#: Corners of a route nearer than this (m) are passed over for the next.
CORNER_PASS = 0.25
#: How far ahead (m) an agent looks for someone coming the other way.
ONCOMING_RANGE = 4.0
#: Sideways distance (m) within which someone ahead is in the way.
ONCOMING_WIDTH = 1.0
#: Cosine of the angle between two ways below which they are the "other way" (over 135 deg).
ONCOMING_COS = -0.7
#: How far ahead (m) an agent looks for a slower one going its way, to pass it on the left ...
OVERTAKE_RANGE = 2.5
#: ... when that one's desired speed is this much lower (m/s).
OVERTAKE_SPEED = 0.2
#: Where an agent that gives way or passes aims: this far ahead along its way (m) ...
SIDESTEP_AHEAD = 2.0
#: ... and this far to its right (giving way) or left (passing), m.
SIDESTEP_RIGHT = 0.8


def next_corner(route: np.ndarray, here: np.ndarray) -> np.ndarray:
    """``(2,)`` the corner of ``route`` ``(K, 2)`` to walk to from ``here`` ``(2,)``.

    The first corner after the start that is farther than :data:`CORNER_PASS` and not yet
    passed (``here`` lies more than :data:`CORNER_PASS` beyond it along the route's next
    leg); the route's end otherwise.
    """
    for i in range(1, len(route)):
        corner = route[i]
        if float(np.hypot(*(corner - here))) <= CORNER_PASS:
            continue
        if i + 1 < len(route):
            leg = route[i + 1] - corner
            length = float(np.hypot(*leg))
            if length > 1e-9 and float((here - corner) @ leg) / length > CORNER_PASS:
                continue
        return corner
    return route[-1]


def sidestep(ground: np.ndarray, unit: np.ndarray, moving: np.ndarray,
              speed: np.ndarray) -> np.ndarray:
    """``(B,)`` which way each agent steps aside: 1 right, -1 left, 0 not.

    Right: someone comes the other way in front (within :data:`ONCOMING_RANGE` ahead
    and :data:`ONCOMING_WIDTH` to the side). Left: otherwise, someone going the same way
    within :data:`OVERTAKE_RANGE` in front wants to walk :data:`OVERTAKE_SPEED` slower
    (the collision-free speed model would only slow down behind it).

    Args:
        ground: ``(B, 2)`` positions (m).
        unit: ``(B, 2)`` unit directions of their ways.
        moving: ``(B,)`` agents that walk somewhere.
        speed: ``(B,)`` desired speeds (m/s).
    """
    n = len(ground)
    out = np.zeros(n)
    if moving.sum() < 2:
        return out
    pairs = cKDTree(ground).query_pairs(ONCOMING_RANGE, output_type="ndarray")
    if len(pairs) == 0:
        return out
    i = np.concatenate((pairs[:, 0], pairs[:, 1]))
    j = np.concatenate((pairs[:, 1], pairs[:, 0]))
    both = moving[i] & moving[j]
    i, j = i[both], j[both]
    rel = ground[j] - ground[i]
    ahead = np.einsum("kd,kd->k", rel, unit[i])
    across = np.abs(rel[:, 0] * unit[i, 1] - rel[:, 1] * unit[i, 0])
    facing = np.einsum("kd,kd->k", unit[j], unit[i])
    in_way = (ahead > 0) & (across < ONCOMING_WIDTH)
    oncoming = np.zeros(n, dtype=bool)
    np.logical_or.at(oncoming, i, in_way & (facing < ONCOMING_COS))
    slower = np.zeros(n, dtype=bool)
    np.logical_or.at(slower, i, in_way & (ahead < OVERTAKE_RANGE) & (facing > -ONCOMING_COS)
                     & (speed[j] < speed[i] - OVERTAKE_SPEED))
    out[slower] = -1.0
    out[oncoming] = 1.0
    return out
