"""Where each crowd agent is going: exits, waypoint tours and wandering, and their progress.

An agent's :class:`GoalState` holds its current destination; :meth:`GoalState.update` moves it
on when the body arrives (within :data:`ARRIVAL_RADIUS` of a waypoint or wander point, or
inside an exit polygon) and says whether the agent is done (it left by its exit). Random
choices (where in an exit polygon to head, wander points) come from the agent's own
generator, so the same seed gives the same walks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon
from shapely.ops import nearest_points

from emotive.crowd.scene import Goal

__all__ = ["ARRIVAL_RADIUS", "GoalState", "random_point"]

#: Distance (m) at which a waypoint or wander point counts as reached.
ARRIVAL_RADIUS = 0.5
#: How far inside its exit polygon (m) an agent aims, when the polygon is that wide.
EXIT_DEPTH = 0.3
#: Tries of rejection sampling for a random point in a polygon.
_TRIES = 1000


def random_point(shape: Polygon | MultiPolygon, rng: np.random.Generator) -> tuple[float, float]:
    """A uniform random point inside ``shape`` (rejection sampling in its bounds)."""
    x0, y0, x1, y1 = shape.bounds
    for _ in range(_TRIES):
        x, y = rng.uniform(x0, x1), rng.uniform(y0, y1)
        if shape.contains(Point(x, y)):
            return (float(x), float(y))
    p = shape.representative_point()
    return (float(p.x), float(p.y))


@dataclass
class GoalState:
    """One agent's goal and its progress.

    Attributes:
        goal: the goal.
        rng: the agent's random generator (exit point, wander points).
        roam: where destinations may lie (the route area).
        exit_shape: the exit polygon (exit goals).
        destination: the point walked to now.
        index: the waypoint walked to (waypoint goals).
        reached: destinations reached (an exit counts once, when left by).
        done: the agent left by its exit.
    """

    goal: Goal
    rng: np.random.Generator
    roam: Polygon | MultiPolygon
    exit_shape: Polygon | None = None
    destination: tuple[float, float] = (0.0, 0.0)
    index: int = 0
    reached: int = 0
    done: bool = False
    standing: bool = field(default=False)
    _exit_target: Polygon | MultiPolygon | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.goal.kind == "exit":
            self.exit_shape = Polygon(self.goal.polygon)
            target = self.exit_shape.intersection(self.roam)
            target = target if not target.is_empty else self.exit_shape
            inner = target.buffer(-EXIT_DEPTH)
            self._exit_target = inner if not inner.is_empty else target
            self.destination = random_point(self._exit_target, self.rng)
        elif self.goal.kind == "waypoints":
            self.destination = self.goal.points[0]
        else:
            self.destination = random_point(self.roam, self.rng)

    def update(self, xy: np.ndarray) -> None:
        """Move on after the body at ``xy`` ``(2,)`` arrived; sets :attr:`done` at an exit."""
        if self.done:
            return
        if self.goal.kind == "exit":
            assert self.exit_shape is not None
            if shapely.contains_xy(self.exit_shape, float(xy[0]), float(xy[1])):
                self.reached, self.done = 1, True
            else:
                q = nearest_points(self._exit_target, Point(float(xy[0]), float(xy[1])))[0]
                self.destination = (float(q.x), float(q.y))
            return
        if self.standing or np.hypot(*(np.asarray(self.destination) - xy)) > ARRIVAL_RADIUS:
            return
        self.reached += 1
        if self.goal.kind == "waypoints":
            if self.index + 1 < len(self.goal.points):
                self.index += 1
                self.destination = self.goal.points[self.index]
            else:
                self.standing = True
        else:
            self.destination = random_point(self.roam, self.rng)

    @property
    def finished(self) -> bool:
        """The goal is met: left by the exit, or the last waypoint reached (wanderers: one)."""
        if self.goal.kind == "wander":
            return self.reached > 0
        return self.done or self.standing
