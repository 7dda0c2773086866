"""Navigation on JuPedSim, tied back to the bodies every frame.

Legend: ``N`` navigation agents, in the order of :attr:`Navigation.keys`.

Each body has one navigation agent in a JuPedSim simulation of the walkable area with the
collision-free speed model V2 (per-agent parameters; Tordeux, Chraibi and Seyfried 2016), or
the anticipation velocity model (AVM; Xu, Chraibi and Seyfried 2021: agents anticipate where
their neighbours go and slide along walls). Every agent is in one journey of a single
direct-steering stage, so the caller sets each agent's target (the next corner of its route,
from JuPedSim's :class:`RoutingEngine` over the walkable area shrunk by
:data:`~emotive.crowd.validation.ROUTE_CLEARANCE`) and JuPedSim's operational model does the
rest: slowing for the agent ahead (the time gap), turning aside from neighbours (the
neighbour repulsion) and from walls.

Which model. ``bench/crowd_navigation_models.py`` runs one two-way corridor under the same
tie-back with both (numbers in ``docs/crowd.md``). The AVM empties it in about 60 % of the
frames with a third of the body-to-navigation gap, but lets hips come closer (0.38 m against
0.46 m at the closest there, and under 0.3 m in the tests' smaller corridor, where the
collision-free speed model keeps them apart). The collision-free speed model is the default:
it keeps the 0.3 m between hips, and being first order (its velocity a function of the
positions, no memory) it loses nothing when the tie-back adds its agents again every frame,
while the AVM's velocity memory is reset each frame. Its cost: it backs off in head-on
meetings, so counterflows clear more slowly.

Tying back. JuPedSim 1.4 agent positions are read only; the model state (desired speed,
radius, time gap, repulsion) can change between iterations, the position cannot. So at every
frame :meth:`Navigation.advance` removes every navigation agent and adds it again where its
body stands, with its current parameters, then iterates one frame (``substeps`` iterations of
``1 / (fps * substeps)`` seconds). What that costs is measured in ``docs/crowd.md``.

JuPedSim refuses to add an agent closer than its radius to a wall or closer than the sum of
radii to another agent. Bodies can come that close (the gait walks where it is sent, not
exactly), so an agent is added with the radius that fits and its own radius is set right after
(the model then stops it until the neighbours' repulsion parts them); a body outside the
walkable area is added at the nearest point inside.

With ``avoidance=False`` the agents do not see each other: each walks straight at its target
at its desired speed (the baseline for measuring what avoidance saves).

JuPedSim is imported here only, inside the functions that need it: ``import emotive`` and the
other commands never load it (the ``crowd`` extra).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np
import shapely
from scipy.spatial import cKDTree
from shapely.geometry import MultiPolygon, Point, Polygon
from shapely.ops import nearest_points

from emotive.crowd.emotion_table import NavParams
from emotive.crowd.errors import CrowdError
from emotive.crowd.validation import ROUTE_CLEARANCE, route_area

__all__ = ["MODELS", "SUBSTEPS", "Navigation", "import_jupedsim"]

#: JuPedSim iterations per gait frame (1/90 s at 30 fps; JuPedSim recommends 0.01 s).
SUBSTEPS = 3
#: Operational models: collision-free speed model V2, anticipation velocity model.
MODELS = ("cfs", "avm")
#: Smallest radius (m) an agent is added with when its body stands too close to another.
MIN_ADD_RADIUS = 0.005
#: Gap (m) kept below the distance limits when adding an agent.
ADD_MARGIN = 1e-3


@functools.lru_cache(maxsize=64)
def _shrunk(shape: Polygon | MultiPolygon) -> Polygon | MultiPolygon:
    """``shape`` 1 mm smaller, so that a nearest point on it lies strictly inside.

    Cached: an area is shrunk once, not at each point that falls outside it.
    """
    return shape.buffer(-1e-3)


def import_jupedsim() -> Any:
    """The ``jupedsim`` module.

    Raises:
        CrowdError: it is not installed (naming the extra to install).
    """
    try:
        import jupedsim  # noqa: PLC0415 (optional and heavy: the crowd extra)
    except ImportError:
        raise CrowdError("crowds need JuPedSim: pip install 'emotive[crowd]'") from None
    return jupedsim


class Navigation:
    """Navigation agents over a walkable area, re-synced to the bodies each frame.

    Args:
        walkable: the walkable area (area less obstacles).
        fps: frame rate of the bodies.
        avoidance: agents avoid each other (JuPedSim); ``False``: straight walks.
        substeps: JuPedSim iterations per frame.
        model: ``cfs`` (the collision-free speed model V2, the default) or ``avm`` (the
            anticipation velocity model); see the module docstring.
    """

    def __init__(self, walkable: Polygon | MultiPolygon, fps: float, avoidance: bool = True,
                 substeps: int = SUBSTEPS, model: str = "cfs") -> None:
        jps = import_jupedsim()
        self.fps = float(fps)
        self.avoidance = bool(avoidance)
        self.substeps = int(substeps)
        self.walkable = walkable
        self._inner = walkable.buffer(-0.03)
        self._boundary = walkable.boundary
        routes = route_area(walkable, ROUTE_CLEARANCE)
        self.route_area = routes if not routes.is_empty else walkable
        self._router = jps.RoutingEngine(self.route_area)
        if model not in MODELS:
            raise CrowdError(f"navigation model {model!r}: give one of {', '.join(MODELS)}")
        self.model = model
        operational = (jps.CollisionFreeSpeedModelV2() if model == "cfs"
                       else jps.AnticipationVelocityModel(rng_seed=0))
        self._sim = jps.Simulation(model=operational, geometry=walkable,
                                   dt=1.0 / (self.fps * self.substeps))
        self._stage = self._sim.add_direct_steering_stage()
        self._journey = self._sim.add_journey(jps.JourneyDescription([self._stage]))
        self._params_type = (jps.CollisionFreeSpeedModelV2AgentParameters if model == "cfs"
                             else jps.AnticipationVelocityModelAgentParameters)
        self.keys: list[int] = []
        self._params: dict[int, NavParams] = {}
        self._targets: dict[int, tuple[float, float]] = {}
        self._ids: dict[int, int] = {}

    # ----------------------------------------------------------------------------- agents

    def add(self, key: int, params: NavParams, target: Sequence[float]) -> None:
        """Add the navigation agent of body ``key`` (placed at the next :meth:`advance`)."""
        if key in self._params:
            raise CrowdError(f"navigation agent {key} exists already")
        self.keys.append(key)
        self._params[key] = params
        self.set_target(key, target)

    def remove(self, key: int) -> None:
        """Remove the navigation agent of body ``key``."""
        self.keys.remove(key)
        del self._params[key]
        del self._targets[key]
        jid = self._ids.pop(key, None)
        if jid is not None:
            self._sim.mark_agent_for_removal(jid)

    def set_params(self, key: int, params: NavParams) -> None:
        """New parameters for an agent (from its emotion); they apply from the next frame."""
        self._params[key] = params

    def params(self, key: int) -> NavParams:
        """The agent's current parameters."""
        return self._params[key]

    def set_target(self, key: int, target: Sequence[float]) -> None:
        """Steer an agent towards a point (inside the route area)."""
        self._targets[key] = self.inside((float(target[0]), float(target[1])), self.route_area)

    def set_targets(self, keys: Sequence[int], targets: np.ndarray) -> None:
        """:meth:`set_target` for many agents: ``targets`` ``(K, 2)`` for ``keys``."""
        pts = np.asarray(targets, dtype=np.float64).reshape(-1, 2)
        ok = shapely.contains_xy(self.route_area, pts[:, 0], pts[:, 1])
        for key, p, good in zip(keys, pts, ok, strict=True):
            xy = (float(p[0]), float(p[1]))
            self._targets[key] = xy if good else self.inside(xy, self.route_area)

    def route(self, start: Sequence[float], goal: Sequence[float]) -> np.ndarray:
        """``(K, 2)`` the shortest route's corners from ``start`` to ``goal`` (both included)."""
        a = self.inside((float(start[0]), float(start[1])), self.route_area)
        b = self.inside((float(goal[0]), float(goal[1])), self.route_area)
        return np.asarray(self._router.compute_waypoints(a, b), dtype=np.float64)

    @staticmethod
    def inside(p: tuple[float, float], shape: Polygon | MultiPolygon) -> tuple[float, float]:
        """``p``, or the nearest point of ``shape`` when ``p`` lies outside it."""
        if shapely.contains_xy(shape, p[0], p[1]):
            return p
        q = nearest_points(_shrunk(shape), Point(p))[0]
        return (float(q.x), float(q.y))

    # ----------------------------------------------------------------------------- stepping

    def advance(self, positions: np.ndarray) -> np.ndarray:
        """Put every agent where its body is, move them one frame, return where they went.

        Args:
            positions: ``(N, 2)`` body positions in :attr:`keys` order, metres.

        Returns:
            ``(N, 2)`` the navigation agents' positions one frame later.
        """
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        if len(pos) != len(self.keys):
            raise CrowdError(f"advance: {len(pos)} positions for {len(self.keys)} agents")
        if not self.avoidance:
            return self._straight(pos)
        self._resync(pos)
        self._sim.iterate(self.substeps)
        return np.array([self._sim.agent(self._ids[k]).position if k in self._ids else pos[i]
                         for i, k in enumerate(self.keys)], dtype=np.float64).reshape(-1, 2)

    def _straight(self, pos: np.ndarray) -> np.ndarray:
        """Each agent one frame straight at its target at its desired speed."""
        out = pos.copy()
        for i, k in enumerate(self.keys):
            d = np.asarray(self._targets[k]) - pos[i]
            gap = float(np.hypot(*d))
            step = min(self._params[k].desired_speed / self.fps, gap)
            if gap > 1e-9:
                out[i] = pos[i] + d / gap * step
        return out

    def _resync(self, pos: np.ndarray) -> None:
        """Remove every agent and add it again at ``pos`` with its current parameters."""
        for jid in self._ids.values():
            self._sim.mark_agent_for_removal(jid)
        if self._ids:
            self._sim.iterate(1)   # removals take effect in an iteration (no agents move)
        self._ids = {}
        n = len(self.keys)
        if n == 0:
            return
        inside = shapely.contains_xy(self._inner, pos[:, 0], pos[:, 1])
        for i in np.flatnonzero(~inside):
            pos[i] = self.inside((pos[i, 0], pos[i, 1]), self._inner)
        wall = shapely.distance(self._boundary, shapely.points(pos))
        near = np.full(n, np.inf)
        if n > 1:
            d, _ = cKDTree(pos).query(pos, k=2)
            near = d[:, 1]
        radii = np.array([self._params[k].radius for k in self.keys])
        fit = np.minimum(radii, np.minimum(0.5 * near, wall) - ADD_MARGIN)
        order = np.argsort(fit)[::-1]   # the roomiest first: the cramped ones fit around them
        for i in order:
            self._add_one(self.keys[i], pos[i], max(float(fit[i]), MIN_ADD_RADIUS))

    def _add_one(self, key: int, xy: np.ndarray, radius: float) -> None:
        p = self._params[key]
        args = {"journey_id": self._journey, "stage_id": self._stage,
                "desired_speed": max(p.desired_speed, 1e-3), "time_gap": p.time_gap,
                "strength_neighbor_repulsion": p.yield_strength,
                "range_neighbor_repulsion": p.yield_range}
        for r in (radius, MIN_ADD_RADIUS):
            try:
                jid = self._sim.add_agent(self._params_type(position=(float(xy[0]),
                                                                      float(xy[1])),
                                                            radius=r, **args))
            except RuntimeError:
                continue
            agent = self._sim.agent(jid)
            agent.model.radius = p.radius
            agent.target = self._targets[key]
            self._ids[key] = jid
            return
        # Two bodies on the same spot: this one waits a frame without a navigation agent.

    def rebuilt(self, walkable: Polygon | MultiPolygon) -> Navigation:
        """A navigation over another walkable area, with these agents, parameters and targets.

        For geometry that changes while a crowd runs (an obstacle added): JuPedSim builds its
        simulation and routing for one geometry, so both are built again. Nothing is carried
        over but the agents' keys (in order), parameters and targets (kept inside the new
        route area); the next :meth:`advance` adds every agent where its body stands, as each
        frame's tie-back does.

        Raises:
            CrowdError: JuPedSim refuses the area (e.g. it is not one connected piece).
        """
        try:
            nav = Navigation(walkable, self.fps, avoidance=self.avoidance,
                             substeps=self.substeps, model=self.model)
        except RuntimeError as exc:
            raise CrowdError(f"JuPedSim cannot navigate the new walkable area ({exc}); keep "
                             "it one connected piece") from None
        for key in self.keys:
            nav.add(key, self._params[key], self._targets[key])
        return nav
