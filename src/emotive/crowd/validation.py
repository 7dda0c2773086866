"""Geometry checks of a scene, and where its agents can stand: shapely polygons in metres.

:func:`validate_scene` raises one :class:`~emotive.crowd.errors.SceneError` line naming the
group or polygon and the fix, before anything runs or is written:

* a polygon that crosses itself (shapely's ``explain_validity`` says where) or encloses no
  area (fewer than three distinct points, or all on a line);
* an obstacle outside the area;
* a spawn or goal outside the walkable area (the area less its obstacles), in part or whole;
* a goal that no walk reaches from the spawn: the walkable area shrunk by
  :data:`BODY_CLEARANCE` (a body's half width) falls apart into pieces, and the goal lies in
  none of the spawn's;
* a group with more agents than its spawn holds (:func:`spawn_sites`: standing places
  :data:`SPAWN_SPACING` apart and :data:`BODY_CLEARANCE` from walls and obstacles).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Point, Polygon
from shapely.validation import explain_validity

from emotive.crowd.errors import SceneError

if TYPE_CHECKING:  # the scene module runs these checks (load_scene): types only here
    from emotive.crowd.scene import Polygon as Ring
    from emotive.crowd.scene import Scene

__all__ = ["BODY_CLEARANCE", "ROUTE_CLEARANCE", "SPAWN_SPACING", "polygon", "route_area",
           "spawn_sites", "validate_scene", "walkable_area"]

#: Half a body's width (m): narrower gaps do not pass, spawn places keep this from walls.
BODY_CLEARANCE = 0.25
#: Distance (m) routes keep from walls and obstacle corners.
ROUTE_CLEARANCE = 0.35
#: Spacing (m) of the spawn places (a triangular lattice): hips start at least this far apart.
SPAWN_SPACING = 0.6
#: Tolerance (m²) of the containment checks.
AREA_TOLERANCE = 1e-6


def polygon(ring: Ring, where: str) -> Polygon:
    """The shapely polygon of a ring of points.

    Raises:
        SceneError: the ring crosses itself or encloses no area.
    """
    shape = Polygon(ring)
    flat = shapely.get_coordinates(shape)
    if np.linalg.matrix_rank(flat - flat[0]) < 2:
        raise SceneError(where, "the polygon is open: its points enclose no area (they lie on "
                         "a line); give at least 3 points around an area")
    if not shape.is_valid:
        raise SceneError(where, f"the polygon crosses itself ({explain_validity(shape)}); "
                         "list its corners in order around the boundary")
    if shape.area <= AREA_TOLERANCE:
        raise SceneError(where, "the polygon is open: its points enclose no area; give at "
                         "least 3 points around an area")
    return shape


def walkable_area(scene: Scene) -> Polygon | MultiPolygon:
    """The area less its obstacles.

    Raises:
        SceneError: a bad polygon, or an obstacle that lies outside the area.
    """
    where = scene.source or scene.name
    area = polygon(scene.area, f"{where}: [area] polygon")
    holes = []
    for k, ring in enumerate(scene.obstacles):
        hole = polygon(ring, f"{where}: obstacle {k + 1}")
        if not hole.intersects(area):
            raise SceneError(f"{where}: obstacle {k + 1}", "lies outside the area; move it "
                             "inside [area] polygon or remove it")
        holes.append(hole)
    return area.difference(shapely.union_all(holes)) if holes else area


def route_area(walkable: Polygon | MultiPolygon, clearance: float = ROUTE_CLEARANCE
               ) -> Polygon | MultiPolygon:
    """The walkable area shrunk by ``clearance`` (where routes and destinations lie)."""
    return walkable.buffer(-clearance, join_style="mitre")


def _pieces(shape: Polygon | MultiPolygon) -> list[Polygon]:
    if shape.is_empty:
        return []
    return list(shape.geoms) if isinstance(shape, MultiPolygon) else [shape]


def spawn_sites(spawn: Polygon, walkable: Polygon | MultiPolygon,
                spacing: float = SPAWN_SPACING) -> np.ndarray:
    """``(N, 2)`` standing places inside ``spawn``: a triangular lattice ``spacing`` apart.

    Every place lies at least :data:`BODY_CLEARANCE` inside the walkable area.
    """
    inner = spawn.intersection(walkable.buffer(-BODY_CLEARANCE, join_style="mitre"))
    if inner.is_empty:
        return np.zeros((0, 2))
    x0, y0, x1, y1 = inner.bounds
    dy = spacing * math.sqrt(3.0) / 2.0
    rows = np.arange(y0, y1 + 1e-9, dy)
    pts = [(x + (0.5 * spacing if k % 2 else 0.0), y) for k, y in enumerate(rows)
           for x in np.arange(x0, x1 + 1e-9, spacing)]
    if not pts:
        return np.zeros((0, 2))
    arr = np.asarray(pts, dtype=np.float64)
    inside = shapely.contains_xy(inner.buffer(1e-9), arr[:, 0], arr[:, 1])
    return arr[inside]


def _inside(shape: Polygon, walkable: Polygon | MultiPolygon) -> bool:
    return shape.difference(walkable).area <= AREA_TOLERANCE * max(1.0, shape.area)


def validate_scene(scene: Scene) -> Polygon | MultiPolygon:
    """Check a scene's geometry (see the module docstring); returns its walkable area.

    Raises:
        SceneError: the first problem found, naming the group or polygon and the fix.
    """
    where = scene.source or scene.name
    walkable = walkable_area(scene)
    passable = _pieces(walkable.buffer(-BODY_CLEARANCE, join_style="mitre"))
    for g in scene.groups:
        at = f"{where}: group {g.name!r}"
        spawn = polygon(g.spawn, f"{at} spawn")
        if not _inside(spawn, walkable):
            raise SceneError(f"{at} spawn", "lies outside the area or inside an obstacle; move "
                             "it inside [area] polygon and off every obstacle")
        sites = spawn_sites(spawn, walkable)
        need = g.count if g.flow == 0 else 1
        if len(sites) < need:
            raise SceneError(f"{at} spawn", f"holds {len(sites)} agent(s) at "
                             f"{SPAWN_SPACING:g} m spacing, the group asks for {need}; enlarge "
                             "the spawn polygon, lower count or give flow = agents per second")
        home = [k for k, piece in enumerate(passable)
                if shapely.contains_xy(piece, sites[:, 0], sites[:, 1]).any()]
        if g.goal.kind == "exit":
            goal = polygon(g.goal.polygon, f"{at} goal")
            if not _inside(goal, walkable):
                raise SceneError(f"{at} goal", "lies outside the area or inside an obstacle; "
                                 "move the goal polygon inside [area] polygon and off every "
                                 "obstacle")
            reached = any(passable[k].intersects(goal) for k in home)
        elif g.goal.kind == "waypoints":
            reached = True
            for n, p in enumerate(g.goal.points):
                if not walkable.contains(Point(p)):
                    raise SceneError(f"{at} goal waypoint {n + 1}", f"{list(p)} lies outside "
                                     "the area or inside an obstacle; move it inside the "
                                     "walkable area")
                reached = reached and any(
                    passable[k].buffer(BODY_CLEARANCE).contains(Point(p)) for k in home)
        else:
            reached = True
        if not reached:
            raise SceneError(f"{at} goal", "no path reaches it from the spawn (walls or "
                             f"obstacles close the way, or gaps are under "
                             f"{2 * BODY_CLEARANCE:g} m); open a way or move the goal")
    return walkable
