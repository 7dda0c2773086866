"""A crowd: gait bodies walking where their JuPedSim navigation agents send them.

Legend: ``B`` agents (in :attr:`Crowd.agents` order), ``J`` joints, ``C`` emotion labels.

:class:`Crowd` sits beside :class:`~emotive.models.gait.generate.GaitGenerator` and drives
one: every body has a navigation agent (:class:`~emotive.crowd.navigation.Navigation`). One
:meth:`Crowd.step` (one frame, ``1 / fps`` seconds):

1. spawns the agents due (a group's ``count`` at the first frame, or its ``flow`` over time,
   on free places of its spawn polygon);
2. moves each agent's goal on (:mod:`~emotive.crowd.goals`) and steers its navigation agent at
   the next corner of its route there;
3. sets each agent's navigation parameters from its emotion *now*
   (:func:`~emotive.crowd.emotion_table.navigation_rows`: the desired speed is the gait's own
   walking pace for the emotion, personal space and yielding come from the table), so an
   emotion changed mid-walk changes the navigation at the next frame;
4. ties every navigation agent to where its body stands and moves it one frame
   (:meth:`Navigation.advance <emotive.crowd.navigation.Navigation.advance>`): that is the
   short-horizon plan;
5. sends each body along a path towards its plan (:meth:`GaitGenerator.set_path`): a
   straight path in the plan's direction (turned from the body's heading by at most
   :data:`MAX_TURN` a frame), as long as makes the gait's target speed the navigation agent's
   speed (the gait slows over the last
   :data:`~emotive.models.gait.generate.STOP_DISTANCE` metres of a path, and never walks past
   its end); the gait network walks it (:meth:`GaitGenerator.step`);
6. lets agents that reached their exit leave (this frame is their last).

The frame (:class:`CrowdFrame`) holds every body and, beside each, where its navigation agent
went, so the gap between the two (the tie-back error) can be measured.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import shapely
from scipy.spatial import cKDTree

from emotive.crowd.emotion_table import NavParams, navigation_rows
from emotive.crowd.errors import CrowdError, SceneError
from emotive.crowd.goals import GoalState, random_point
from emotive.crowd.navigation import Navigation
from emotive.crowd.scene import EmotionSpec, Goal, Group, Scene
from emotive.crowd.steering import SIDESTEP_AHEAD, SIDESTEP_RIGHT, next_corner, sidestep
from emotive.crowd.validation import (
    AREA_TOLERANCE,
    BODY_CLEARANCE,
    ROUTE_CLEARANCE,
    SPAWN_SPACING,
    polygon,
    route_area,
    spawn_sites,
    validate_scene,
    walkable_area,
)
from emotive.data.emotion import EmotionLike
from emotive.models.gait.generate import STOP_DISTANCE, GaitGenerator, to_model_schedule
from emotive.models.gait.model import GaitModel
from emotive.paths import GroundPath

__all__ = ["AgentInfo", "Crowd", "CrowdFrame", "draw_emotion"]

#: Frames between two routings of an agent (its route is kept in between) ...
ROUTE_EVERY = 15
#: ... unless its destination moved farther than this (m).
ROUTE_MOVED = 0.5
#: An agent that moved less than this (m) over :data:`STALL_FRAMES` frames is stalled.
STALL_DISTANCE = 0.2
#: Frames over which an agent's progress is judged (2 s at 30 fps).
STALL_FRAMES = 60
#: Neighbour repulsion range (m) of a stalled agent: JuPedSim's default, shorter than the
#: table's, so that it squeezes past instead of being held off by everyone near it.
STALL_RANGE = 0.1
#: A plan shorter than this (m) stops the body where it stands.
MIN_LEAD = 0.02
#: A navigation agent slower than this (m/s) is waiting: its body stands.
STAND_SPEED = 0.15
#: Largest turn of a body's path from its heading per frame (radians; 450 degrees/s at 30 fps).
MAX_TURN = math.radians(15.0)
#: A body keeps its path while the new one would turn less than this (radians) ...
KEEP_ANGLE = math.radians(2.0)
#: ... and change its remaining length by less than this (m, 5 % of the gait's target speed).
KEEP_LEAD = 0.05
@dataclass(frozen=True)
class CrowdFrame:
    """One frame of every body, after :meth:`Crowd.step`.

    Attributes:
        index: frame number (0 is the first stepped frame).
        time: seconds since the start, ``(index + 1) / fps``.
        agents: the ``B`` agent ids.
        rotations: ``(B, J, 4)`` local rotations (the mover's carrying the world heading).
        positions: ``(B, J, 3)`` local translations (the mover's: its world position, metres).
        root: ``(B, 2)`` ground position ``(x, y)`` of each body (the scene's plane).
        navigation: ``(B, 2)`` where each navigation agent went this frame.
        emotion: ``(B, C)`` each agent's emotion.
        left: agents that reached their exit at this frame (their last).
    """

    index: int
    time: float
    agents: tuple[int, ...]
    rotations: np.ndarray
    positions: np.ndarray
    root: np.ndarray
    navigation: np.ndarray
    emotion: np.ndarray
    left: tuple[int, ...]


@dataclass
class AgentInfo:
    """What a crowd knows of one agent.

    Attributes:
        group: its group's name (``""`` for an agent added by hand).
        emotion: the emotion it was given (text, or a description).
        pace: factor on its emotion's walking speed.
        goal: its goal and progress.
        first_frame: the first frame it appears in.
        last_frame: the last frame it appeared in (so far).
    """

    group: str
    emotion: str
    pace: float
    goal: GoalState
    first_frame: int
    last_frame: int = -1


def draw_emotion(spec: EmotionSpec, rng: np.random.Generator) -> str:
    """One agent's emotion text from a group's spec (the text itself, or a draw)."""
    if spec.text:
        return spec.text
    if spec.choices:
        w = np.asarray(spec.weights, dtype=np.float64)
        return spec.choices[int(rng.choice(len(spec.choices), p=w / w.sum()))]
    v = rng.uniform(*spec.valence)
    a = rng.uniform(*spec.arousal)
    return f"valence={v:.3f},arousal={a:.3f}"


@dataclass
class _Spawner:
    """A group's spawning state."""

    group: Group
    sites: np.ndarray
    rng: np.random.Generator
    spawned: int = 0
    due: float = 0.0


class Crowd:
    """Bodies of the gait network walking a scene with JuPedSim navigation (module docstring).

    Args:
        scene: the scene (checked here).
        model: the gait model (default: the built-in one).
        seed: seed of every random choice (spawn places, drawn emotions and paces, exit
            points, wander points, the gait's starting phases).
        avoidance: navigation agents avoid each other; ``False`` walks them straight through
            (the baseline).
        spawn: spawn the scene's groups; ``False`` starts empty (add agents by hand).
        navigation: JuPedSim's operational model, ``cfs`` or ``avm``
            (:class:`~emotive.crowd.navigation.Navigation`).

    Example::

        crowd = Crowd(load_scene("examples/scenes/corridor.toml"), seed=1)
        frame = crowd.step()        # frame.root: every body's ground position
        crowd.set_emotion(frame.agents[0], "angry")
    """

    def __init__(self, scene: Scene, model: GaitModel | None = None, seed: int = 0,
                 avoidance: bool = True, spawn: bool = True, navigation: str = "cfs") -> None:
        if model is None:
            from emotive.models.gait.model import load_gait_model  # noqa: PLC0415 (weights)

            model = load_gait_model()
        self.scene = scene
        self.seed = int(seed)
        self.walkable = validate_scene(scene)
        self.gait = GaitGenerator(model, seed=self.seed)
        self.fps = float(model.fps)
        self.labels = tuple(model.labels)
        self.nav = Navigation(self.walkable, self.fps, avoidance=avoidance, model=navigation)
        self._walk_speed = np.asarray(model.controls.speed, dtype=np.float64) * self.fps
        self._info: dict[int, AgentInfo] = {}
        self._ground: dict[int, np.ndarray] = {}
        self._path_end: dict[int, np.ndarray] = {}
        self._routes: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._since: dict[int, tuple[int, np.ndarray, bool]] = {}
        self._stuck: set[int] = set()
        self._emotion: dict[int, np.ndarray] = {}
        self._next_rng = 0
        self.frame_index = 0
        self._spawners = [
            _Spawner(g, spawn_sites(polygon(g.spawn, g.name), self.walkable),
                     np.random.default_rng([self.seed, k]))
            for k, g in enumerate(scene.groups)] if spawn else []

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the agents in the scene, in frame order."""
        return tuple(self.nav.keys)

    def info(self, agent: int) -> AgentInfo:
        """What the crowd knows of an agent (also after it left)."""
        try:
            return self._info[agent]
        except KeyError:
            raise CrowdError(f"no agent with id {agent}") from None

    @property
    def all_agents(self) -> tuple[int, ...]:
        """Every agent that ever was in the scene, by id."""
        return tuple(sorted(self._info))

    def nav_params(self, agent: int) -> NavParams:
        """The navigation parameters the agent walks with now."""
        self._index(agent)
        return self.nav.params(agent)

    def add_agents(self, positions: np.ndarray, goals: Sequence[Goal],
                   emotions: Sequence[EmotionLike], paces: Sequence[float] | None = None,
                   group: str = "") -> list[int]:
        """Add agents standing at ``positions`` ``(N, 2)`` with their goals; returns their ids.

        Raises:
            EmotionError: a bad emotion. ValueError: a pace outside 0.5-1.5.
        """
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
        n = len(pos)
        paces = [1.0] * n if paces is None else [float(p) for p in paces]
        states = []
        for _ in range(n):
            rng = np.random.default_rng([self.seed, 1_000_003, self._next_rng])
            self._next_rng += 1
            states.append(rng)
        goal_states = [GoalState(g, r, self.nav.route_area) for g, r in zip(goals, states,
                                                                            strict=True)]
        paths = []
        for p, gs in zip(pos, goal_states, strict=True):
            route = self.nav.route(p, gs.destination)
            ahead = route[1] if len(route) > 1 else np.asarray(gs.destination)
            d = ahead - p
            norm = float(np.hypot(*d))
            u = d / norm if norm > 1e-6 else np.array([1.0, 0.0])
            paths.append(GroundPath.from_polyline(np.stack((p, p + 0.5 * u)), name="spawn"))
        ids = self.gait.add_agents(paths, list(emotions), paces=paces)
        for a, p, e, pace, gs in zip(ids, pos, emotions, paces, goal_states, strict=True):
            weights = to_model_schedule(e, self.labels).at(0.0)
            self._emotion[a] = np.asarray(weights, dtype=np.float64).reshape(-1)
            self._ground[a] = p.copy()
            self._info[a] = AgentInfo(group, e if isinstance(e, str) else repr(e), pace, gs,
                                      self.frame_index)
            self.nav.add(a, self._params(a), gs.destination)
        return ids

    def add_agent(self, position: Sequence[float], goal: Goal, emotion: EmotionLike = "neutral",
                  pace: float = 1.0) -> int:
        """Add one agent (see :meth:`add_agents`); returns its id."""
        return self.add_agents(np.asarray([position]), [goal], [emotion], [pace])[0]

    def remove_agent(self, agent: int) -> None:
        """Take an agent out of the scene.

        Raises:
            CrowdError: no agent in the scene has that id.
        """
        self._index(agent)
        self.gait.remove_agent(agent)
        self.nav.remove(agent)
        del self._ground[agent]
        self._path_end.pop(agent, None)
        self._routes.pop(agent, None)
        self._since.pop(agent, None)

    def set_emotion(self, agent: int, emotion: EmotionLike) -> None:
        """Give an agent a new emotion (or schedule, from now): its gait and its navigation.

        Raises:
            CrowdError: unknown agent. EmotionError: a bad emotion.
        """
        self._index(agent)
        self.gait.set_emotion(agent, emotion)
        self._emotion[agent] = np.asarray(to_model_schedule(emotion, self.labels).at(0.0),
                                          dtype=np.float64).reshape(-1)
        self.nav.set_params(agent, self._params(agent))

    def _index(self, agent: int) -> int:
        try:
            return self.nav.keys.index(agent)
        except ValueError:
            raise CrowdError(f"no agent with id {agent} in the scene; agents: "
                             f"{list(self.nav.keys)[:20]}") from None

    def _params(self, agent: int) -> NavParams:
        row = navigation_rows(self._emotion[agent][None], self.labels, self._walk_speed,
                              np.array([self._info[agent].pace]))[0]
        return NavParams(*(float(x) for x in row))

    # ----------------------------------------------------------------------------- spawning

    def _spawn_due(self) -> None:
        taken = np.array(list(self._ground.values())).reshape(-1, 2)
        tree = cKDTree(taken) if len(taken) else None
        for s in self._spawners:
            g = s.group
            if g.flow == 0:
                want = g.count if self.frame_index == 0 else 0
            else:
                s.due += g.flow / self.fps
                left = (g.count - s.spawned) if g.count else math.inf
                want = int(min(math.floor(s.due), left))
            if want <= 0:
                continue
            free = s.sites
            if tree is not None and len(free):
                d, _ = tree.query(free)
                free = free[d >= SPAWN_SPACING]
            take = min(want, len(free))
            if take == 0:
                continue
            pick = free[np.sort(s.rng.choice(len(free), size=take, replace=False))]
            emotions = [draw_emotion(g.emotion, s.rng) for _ in range(take)]
            paces = [float(s.rng.uniform(*g.pace)) for _ in range(take)]
            self.add_agents(pick, [g.goal] * take, emotions, paces, group=g.name)
            s.spawned += take
            s.due -= take if g.flow else 0
            if len(pick):
                taken = np.vstack((taken, pick))
                tree = cKDTree(taken)

    # ----------------------------------------------------------------------------- stepping

    def _steer(self, keys: list[int], ground: np.ndarray) -> None:
        """Move goals on and aim each navigation agent at its route's next corner.

        An agent that steps aside (:func:`~emotive.crowd.steering.sidestep`: someone comes
        the other way, or a slower one walks ahead) aims instead
        :data:`~emotive.crowd.steering.SIDESTEP_AHEAD` along its way and
        :data:`~emotive.crowd.steering.SIDESTEP_RIGHT` to its right or left.
        :meth:`Navigation.set_targets` keeps the point inside the route area, so in a
        corridor the side step ends at the wall's clearance.
        """
        n = len(keys)
        targets = np.zeros((n, 2))
        moving = np.zeros(n, dtype=bool)
        for k, key in enumerate(keys):
            gs = self._info[key].goal
            gs.update(ground[k])
            if gs.standing:
                targets[k] = ground[k]
                continue
            targets[k] = next_corner(self._route(key, ground[k], gs.destination), ground[k])
            moving[k] = True
        way = targets - ground
        dist = np.hypot(way[:, 0], way[:, 1])
        moving &= dist > 1e-6
        unit = np.zeros_like(way)
        unit[moving] = way[moving] / dist[moving, None]
        speed = np.array([self.nav.params(key).desired_speed for key in keys])
        side = sidestep(ground, unit, moving, speed) if self.nav.avoidance else np.zeros(n)
        stuck = moving & (side > 0) & self._stalled(keys, ground)
        side[stuck] = -1.0
        self._stuck = {key for key, s in zip(keys, stuck, strict=True) if s}
        aside = side != 0
        right = np.stack((unit[:, 1], -unit[:, 0]), axis=1)
        targets[aside] = (ground[aside] + unit[aside] * np.minimum(SIDESTEP_AHEAD,
                                                                     dist[aside])[:, None]
                          + right[aside] * (SIDESTEP_RIGHT * side[aside])[:, None])
        self.nav.set_targets(keys, targets)

    def _stalled(self, keys: list[int], ground: np.ndarray) -> np.ndarray:
        """``(B,)`` agents stalled: moved under :data:`STALL_DISTANCE` in :data:`STALL_FRAMES`.

        Each agent is judged once per :data:`STALL_FRAMES` of its own, and the verdict
        holds until the next. A stalled agent that walks somewhere sides the other way
        (:meth:`_steer`): two agents that block each other head on, each stepping to its
        right into a wall or a neighbour, both try the left, which is again one consistent
        side, and they pass.
        """
        out = np.zeros(len(keys), dtype=bool)
        for k, key in enumerate(keys):
            since = self._since.get(key)
            if since is None or self.frame_index - since[0] >= STALL_FRAMES:
                stalled = (since is not None
                           and float(np.hypot(*(ground[k] - since[1]))) < STALL_DISTANCE)
                since = (self.frame_index, ground[k].copy(), stalled)
                self._since[key] = since
            out[k] = since[2]
        return out

    def _route(self, key: int, here: np.ndarray, destination: tuple[float, float]) -> np.ndarray:
        """``(K, 2)`` agent ``key``'s route corners to ``destination`` (JuPedSim's routing).

        Routed again every :data:`ROUTE_EVERY` frames (spread over the agents) or when the
        destination moved more than :data:`ROUTE_MOVED`; in between the last route serves
        (:func:`next_corner` skips the corners passed).
        """
        cached = self._routes.get(key)
        dest = np.asarray(destination, dtype=np.float64)
        if (cached is None or (self.frame_index + key) % ROUTE_EVERY == 0
                or float(np.hypot(*(cached[0] - dest))) > ROUTE_MOVED):
            route = self.nav.route(here, destination)
            self._routes[key] = (dest, route)
            return route
        return cached[1]

    def _body_path(self, key: int, here: np.ndarray, plan: np.ndarray, yaw: float,
                   speed: float) -> GroundPath | None:
        """The path that walks body ``key`` at ``here`` towards its navigation ``plan``.

        A straight path (no curvature, so the gait adds no lean into a turn) in the plan's
        direction, turned from the body's heading by at most :data:`MAX_TURN` per frame, as
        long as the distance that makes the gait's target speed the navigation's speed.
        ``None`` when the body's current path already runs that way (within
        :data:`KEEP_ANGLE` and :data:`KEEP_LEAD`): setting a path costs far more than a step.
        A plan slower than :data:`STAND_SPEED` stops the body: a waiting navigation agent
        jitters by millimetres a frame, and a body sent after each jitter walks in circles.
        """
        step = plan - here
        gap = float(np.hypot(*step))
        v_nav = gap * self.fps
        lead = max(gap, STOP_DISTANCE * min(v_nav / max(speed, 1e-6), 1.0))
        facing = np.array([math.sin(yaw), math.cos(yaw)])
        if lead < MIN_LEAD or v_nav < STAND_SPEED:
            end = here + 0.01 * facing
        else:
            want = math.atan2(step[0], step[1])
            turn = math.remainder(want - yaw, math.tau)
            heading = yaw + max(-MAX_TURN, min(MAX_TURN, turn))
            end = here + lead * np.array([math.sin(heading), math.cos(heading)])
        last = self._path_end.get(key)
        if last is not None and lead >= MIN_LEAD:
            left = last - here
            remaining = float(np.hypot(*left))
            along = end - here
            cos = float(left @ along) / max(remaining * lead, 1e-12)
            if abs(remaining - lead) < KEEP_LEAD and cos > math.cos(KEEP_ANGLE):
                return None
        self._path_end[key] = end
        return GroundPath.from_polyline(np.stack((here, end)), name="navigation")

    def step(self) -> CrowdFrame:
        """Advance every agent one frame (see the module docstring) and return the frame."""
        self._spawn_due()
        keys = list(self.nav.keys)
        if tuple(keys) != self.gait.agents:
            raise CrowdError("the crowd's bodies and navigation agents fell out of step")
        ground = np.array([self._ground[k] for k in keys]).reshape(-1, 2)
        self._steer(keys, ground)
        if keys:
            rows = navigation_rows(np.stack([self._emotion[k] for k in keys]), self.labels,
                                   self._walk_speed,
                                   np.array([self._info[k].pace for k in keys]))
            for key, row in zip(keys, rows, strict=True):
                params = NavParams(*(float(x) for x in row))
                if self._info[key].goal.standing:
                    params = NavParams(1e-3, *(float(x) for x in row[1:]))
                elif key in self._stuck:
                    params = replace(params, yield_range=min(params.yield_range, STALL_RANGE))
                self.nav.set_params(key, params)
        plan = self.nav.advance(ground)
        yaw = self.gait.agent_field("heading") if keys else np.zeros(0)
        changed, paths = [], []
        for k, key in enumerate(keys):
            path = self._body_path(key, ground[k], plan[k], float(yaw[k]),
                                   self.nav.params(key).desired_speed)
            if path is not None:
                changed.append(key)
                paths.append(path)
        self.gait.set_paths(changed, paths)
        frame = self.gait.step()
        left = []
        for k, key in enumerate(keys):
            self._ground[key] = frame.root[k].copy()
            self._emotion[key] = frame.emotion[k].astype(np.float64)
            info = self._info[key]
            info.last_frame = self.frame_index
            info.goal.update(frame.root[k])
            if info.goal.done:
                left.append(key)
        out = CrowdFrame(self.frame_index, (self.frame_index + 1) / self.fps, tuple(keys),
                         frame.rotations, frame.positions, frame.root.copy(), plan,
                         frame.emotion, tuple(left))
        for key in left:
            self.remove_agent(key)
        self.frame_index += 1
        return out

    def goal_reached(self) -> dict[int, bool]:
        """Whether each agent that ever was in the scene met its goal (see ``GoalState``)."""
        return {a: info.goal.finished for a, info in self._info.items()}

    def inside_goal(self, agent: int, xy: np.ndarray) -> bool:
        """Whether ``xy`` lies in the agent's exit polygon (exit goals)."""
        shape = self._info[agent].goal.exit_shape
        return shape is not None and bool(shapely.contains_xy(shape, *map(float, xy)))

    def add_obstacle(self, ring: Sequence[Sequence[float]]) -> int:
        """Cut one more obstacle out of the walkable area while the crowd runs.

        Args:
            ring: ``(K, 2)`` its corners in order, metres on the scene's plane.

        Returns:
            its number among the scene's obstacles (from 1).

        It is refused (nothing changes) when its polygon crosses itself or encloses no area
        (:func:`~emotive.crowd.validation.polygon`), lies outside the area, splits the
        walkable area or closes a way under ``2 * ROUTE_CLEARANCE`` wide (JuPedSim navigates
        one connected area), covers part of a group's exit, a group's waypoint, or the spawn
        of a group whose agents still enter, or when a body stands on it or within
        :data:`~emotive.crowd.validation.BODY_CLEARANCE` of it: a body is walked, never
        moved, so none may end up inside an obstacle. Otherwise the navigation is built again
        over the new area with the same agents, parameters and targets
        (:meth:`Navigation.rebuilt <emotive.crowd.navigation.Navigation.rebuilt>`), goals
        roam the new route area, a destination left on the obstacle (an agent's own
        waypoint) moves to the nearest point of the route area (a wanderer draws a new one),
        and the spawn places are computed again.

        Raises:
            SceneError: a bad polygon, or one that breaks the scene as above.
            CrowdError: bodies stand on it (naming them).
        """
        where = f"{self.scene.source or self.scene.name}: new obstacle"
        corners = tuple((float(x), float(y)) for x, y in ring)
        shape = polygon(corners, where)
        if not shape.intersects(polygon(self.scene.area, f"{where}: area")):
            raise SceneError(where, "lies outside the area; draw it inside the area")
        scene = Scene(self.scene.area, (*self.scene.obstacles, corners), self.scene.groups,
                      self.scene.name, self.scene.source)
        walkable = walkable_area(scene)
        if walkable.is_empty or walkable.geom_type != "Polygon" or \
                route_area(walkable).geom_type != "Polygon":
            raise SceneError(where, "splits the walkable area or closes a way (routes keep "
                             f"{ROUTE_CLEARANCE:g} m from walls, so a way narrower than "
                             f"{2 * ROUTE_CLEARANCE:g} m is closed); leave a wider way around it")
        for s in self._spawners:
            g = s.group
            entering = self.frame_index == 0 or (g.flow > 0 and (not g.count
                                                                 or s.spawned < g.count))
            covered = []
            if entering and shape.intersection(polygon(g.spawn, g.name)).area > AREA_TOLERANCE:
                covered.append(f"the spawn of group {g.name!r}, where agents still enter")
            if g.goal.kind == "exit" and shape.intersection(
                    polygon(g.goal.polygon, g.name)).area > AREA_TOLERANCE:
                covered.append(f"the exit of group {g.name!r}")
            if any(shapely.intersects_xy(shape, x, y) for x, y in g.goal.points):
                covered.append(f"a waypoint of group {g.name!r}")
            if covered:
                raise SceneError(where, f"covers {covered[0]}; draw it elsewhere")
        keys = list(self.nav.keys)
        if keys:
            ground = np.array([self._ground[k] for k in keys])
            near = [keys[i] for i in np.flatnonzero(
                shapely.distance(shape, shapely.points(ground)) < BODY_CLEARANCE)]
            if near:
                shown = ", ".join(map(str, near[:20])) + (", ..." if len(near) > 20 else "")
                raise CrowdError(f"{where}: agent(s) {shown} stand on it or within "
                                 f"{BODY_CLEARANCE:g} m of it; draw it where nobody stands "
                                 "(bodies are walked, never moved)")
        nav = self.nav.rebuilt(walkable)
        self.scene, self.walkable, self.nav = scene, walkable, nav
        self._routes.clear()
        for s in self._spawners:
            s.sites = spawn_sites(polygon(s.group.spawn, s.group.name), walkable)
        for key in keys:
            gs = self._info[key].goal
            gs.roam = nav.route_area
            if not shapely.contains_xy(walkable, *gs.destination):
                gs.destination = (random_point(nav.route_area, gs.rng)
                                  if gs.goal.kind == "wander"
                                  else nav.inside(gs.destination, nav.route_area))
        return len(scene.obstacles)
