"""A crowd as the server's engine: ``emotive serve --scene SCENE.toml``.

:class:`CrowdEngine` stands where :class:`~emotive.serve.engines.Engine` does for the
simulation thread, and steps a :class:`~emotive.crowd.crowd.Crowd`: the scene's groups spawn
and navigate with JuPedSim, their bodies walked by the gait network (``docs/crowd.md``).
Frames are the gait network's, so clients see no difference in them; what a scene adds:

* its geometry (:attr:`CrowdEngine.scene_message`): the area, the obstacles and each group's
  spawn and goal, a ``{"type": "scene", ...}`` message that every client gets when it joins
  and whenever the geometry changes (``version`` counts the changes);
* agents added at a point with waypoints to walk to (:meth:`CrowdEngine.place_agents`),
  new goals (:meth:`CrowdEngine.set_goal`; ``set_target`` is a goal of one point) and
  obstacles drawn while the crowd runs (:meth:`CrowdEngine.add_obstacle`,
  :meth:`Crowd.add_obstacle <emotive.crowd.crowd.Crowd.add_obstacle>`);
* agents the crowd spawns and lets leave by their exits on its own: the simulation takes
  them from :meth:`CrowdEngine.take_changes` after each step.

Paths do not apply: a crowd agent walks where its navigation sends it, so ``add_agent`` with a
``path`` and ``set_path`` are refused, naming what to send instead. Ground points are
``[x, z]`` metres in the world of the bodies, the scene file's ``[x, y]``.

This module is imported only with ``--scene``; it loads the crowd package, and JuPedSim when
the crowd is built (:func:`load_crowd_engine`).

Legend: ``B`` agents, ``J`` joints, ``P`` points (joints then end sites), ``C`` labels,
``K`` points of a goal or polygon.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from emotive.crowd.crowd import Crowd
from emotive.crowd.errors import SceneError
from emotive.crowd.goals import GoalState
from emotive.crowd.scene import Goal, Scene, load_scene
from emotive.crowd.validation import BODY_CLEARANCE
from emotive.data.emotion import EmotionSchedule, coerce_emotion
from emotive.errors import EmotiveError
from emotive.models.gait.agent_inputs import point_labels
from emotive.models.gait.generate import GaitFrame
from emotive.models.gait.model import load_gait_model
from emotive.paths import GroundPath
from emotive.serve.engines import gait_rest
from emotive.serve.errors import MessageError
from emotive.serve.messages import AddAgent, PlaceAgent
from emotive.serve.rig import FrameRig

__all__ = ["CrowdEngine", "load_crowd_engine", "scene_message"]

#: Decimals of the coordinates in the scene message (0.1 mm).
DECIMALS = 4
#: The reply to an agent given a path.
PATH_REFUSAL = ('with --scene an agent is added with "at": [x, z] and "goal": [x, z] (it '
                'navigates there), not with a "path"')


def _ring(points: Sequence[Sequence[float]]) -> list[list[float]]:
    return [[round(float(x), DECIMALS), round(float(y), DECIMALS)] for x, y in points]


def scene_message(scene: Scene, version: int) -> dict[str, Any]:
    """The ``{"type": "scene", ...}`` message of a scene's geometry (``docs/serve.md``).

    ``area``: ``(K, 2)`` the outer polygon; ``obstacles``: polygons; ``groups``: each one's
    ``name``, ``spawn`` polygon and ``goal`` (``{"kind": "exit", "polygon": ...}``,
    ``{"kind": "waypoints", "points": ...}`` or ``{"kind": "wander"}``); points ``[x, z]``.
    """
    groups = []
    for g in scene.groups:
        goal: dict[str, Any] = {"kind": g.goal.kind}
        if g.goal.kind == "exit":
            goal["polygon"] = _ring(g.goal.polygon)
        elif g.goal.kind == "waypoints":
            goal["points"] = _ring(g.goal.points)
        groups.append({"name": g.name, "spawn": _ring(g.spawn), "goal": goal})
    return {"type": "scene", "version": version, "name": scene.name,
            "area": _ring(scene.area), "obstacles": [_ring(o) for o in scene.obstacles],
            "groups": groups}


class CrowdEngine:
    """A :class:`~emotive.crowd.crowd.Crowd` with what the server asks of an engine.

    Stepped and commanded by the simulation thread only; :attr:`scene_message` is replaced
    whole when the geometry changes, so any thread may read it.

    Args:
        crowd: the crowd (its groups spawn at its first step).
        rest: a one-frame motion of the rig standing (the mannequin's bind pose).
        points_over: the labels a valence/arousal point blends.
    """

    #: :meth:`step` makes world positions only when asked (version-1 clients).
    partial_frames = True
    model = "gait"
    backend = "torch"

    def __init__(self, crowd: Crowd, rest: Any, points_over: Sequence[str]) -> None:
        self.crowd = crowd
        self.rest = rest
        self.skeleton = rest.skeleton
        self.mover = int(crowd.gait.graph.mover)
        self.labels: tuple[str, ...] = tuple(crowd.labels)
        self.points_over = tuple(points_over)
        self.fps = float(crowd.fps)
        sk = self.skeleton
        self.rig = FrameRig(sk.parents, sk.offsets, self.mover, sk.end_site_parents,
                            np.asarray(sk.end_site_offsets).reshape(-1, 3))
        self.version = 1
        self.scene_message = scene_message(crowd.scene, self.version)
        self._inner = crowd.walkable.buffer(-BODY_CLEARANCE)
        self._known: set[int] = set()
        self._joined: list[tuple[int, EmotionSchedule, float]] = []
        self._left: list[int] = []
        self._schedules: dict[str, EmotionSchedule] = {}
        self._agents: tuple[int, ...] = ()
        self._root = np.zeros((0, 2))

    # ----------------------------------------------------------------------------- state

    def __len__(self) -> int:
        return len(self.crowd.nav.keys)

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the agents in the scene, in frame order."""
        return self.crowd.agents

    def step(self, full: bool = True) -> GaitFrame:
        """Step the crowd one frame.

        Args:
            full: also compute the world positions ``(B, P, 3)`` (from the rotations and
                the rig, :class:`~emotive.serve.rig.FrameRig`: the placement root at its
                offset, as a version-2 client places it); ``False`` leaves ``world`` ``None``.
        """
        frame = self.crowd.step()
        for agent in frame.agents:
            if agent not in self._known:
                info = self.crowd.info(agent)
                self._known.add(agent)
                self._joined.append((agent, self._schedule(info.emotion), info.pace))
        for agent in frame.left:
            self._known.discard(agent)
            self._left.append(agent)
        self._agents, self._root = frame.agents, frame.root
        world = (self.rig.world(frame.rotations, frame.positions[:, self.mover]) if full
                 else None)
        return GaitFrame(frame.agents, frame.rotations, frame.positions, world, frame.emotion,
                         frame.root)

    def take_changes(self) -> tuple[list[tuple[int, EmotionSchedule, float]], list[int]]:
        """Agents the crowd spawned and agents that left by their exit since the last call.

        Returns:
            ``(joined, left)``: ``(id, emotion schedule, pace)`` of each new agent, and the
            ids of the agents that left (after their last frame).
        """
        joined, left = self._joined, self._left
        self._joined, self._left = [], []
        return joined, left

    def _schedule(self, emotion: str) -> EmotionSchedule:
        """The schedule of a spawned agent's emotion text (the same texts recur: cached)."""
        schedule = self._schedules.get(emotion)
        if schedule is None:
            schedule = self._schedules[emotion] = coerce_emotion(emotion, self.labels,
                                                                 self.points_over)
        return schedule

    def agent_state(self, agent: int, here: np.ndarray | None) -> dict[str, Any]:
        """A crowd agent's fields of ``GET /api/agents``: its way to its goal and its group.

        Args:
            agent: the agent.
            here: ``(2,)`` where it stands (``None``: not in a frame yet).

        Returns:
            ``path``: ``[x, z]`` points from where it stands through its goal's points still
            ahead; ``goal``: ``{"kind", "points"}`` (points still ahead); ``group`` (``""``:
            added by a client).
        """
        info = self.crowd.info(agent)
        gs = info.goal
        ahead = [] if gs.finished and gs.goal.kind != "wander" else [gs.destination]
        if gs.goal.kind == "waypoints" and not gs.standing:
            ahead += list(gs.goal.points[gs.index + 1:])
        path = ([] if here is None else [here]) + ahead
        return {"path": _ring(path), "goal": {"kind": gs.goal.kind, "points": _ring(ahead)},
                "group": info.group}

    # ----------------------------------------------------------------------------- commands

    def add_agents(self, paths: Sequence[GroundPath], schedules: Sequence[EmotionSchedule],
                   starts: Sequence[float], paces: Sequence[float]) -> list[int]:
        """Refused: a crowd agent navigates (give ``at`` and ``goal``)."""
        raise MessageError(PATH_REFUSAL)

    def place_agents(self, specs: Sequence[PlaceAgent | AddAgent]) -> list[int]:
        """Add agents standing at their points, each walking its waypoints; their ids.

        A point within :data:`~emotive.crowd.validation.BODY_CLEARANCE` of a wall or an
        obstacle is moved that far in (a body's half width).

        Raises:
            MessageError: a spec with a ``path``, a point or a waypoint off the walkable area.
        """
        ats, goals = [], []
        for spec in specs:
            if not isinstance(spec, PlaceAgent):
                raise MessageError(PATH_REFUSAL)
            ats.append(self._standing(spec.at))
            for k, p in enumerate(spec.goal):
                self._on_walkable(p, f"goal point {k + 1}" if len(spec.goal) > 1 else "goal")
            goals.append(Goal("waypoints", points=tuple((float(x), float(z))
                                                        for x, z in spec.goal)))
        ids = self.crowd.add_agents(np.asarray(ats), goals, [s.schedule for s in specs],
                                    [s.pace for s in specs])
        self._known.update(ids)
        return ids

    def _on_walkable(self, point: np.ndarray, field: str) -> None:
        x, z = (float(v) for v in point)
        if not shapely.contains_xy(self.crowd.walkable, x, z):
            raise MessageError(f'"{field}" [{x:g}, {z:g}] lies outside the walkable area '
                               "(outside the scene's area or on an obstacle): give a point "
                               "inside it")

    def _standing(self, at: np.ndarray) -> tuple[float, float]:
        """Where a new body stands: ``at``, moved off walls and obstacles by a half width."""
        self._on_walkable(at, "at")
        p = (float(at[0]), float(at[1]))
        if self._inner.is_empty:
            return p
        return self.crowd.nav.inside(p, self._inner)

    def remove_agent(self, agent: int) -> None:
        """Take an agent out of the scene."""
        self.crowd.remove_agent(agent)
        self._known.discard(agent)

    def set_emotion(self, agent: int, schedule: EmotionSchedule) -> None:
        """A new emotion or schedule: its gait and its navigation from the next frame."""
        self.crowd.set_emotion(agent, schedule)

    def set_path(self, agent: int, path: GroundPath) -> None:
        """Refused: a crowd agent walks where its navigation sends it."""
        raise MessageError("with --scene agents navigate: send set_goal (or set_target) with "
                           "the point to walk to, not a path")

    def set_target(self, agent: int, xz: Sequence[float]) -> None:
        """Walk to one ground point ``(x, z)`` (a goal of one waypoint)."""
        self.set_goal(agent, np.asarray(xz, dtype=np.float64).reshape(1, 2))

    def set_goal(self, agent: int, points: np.ndarray) -> None:
        """Walk the waypoints ``(K, 2)`` from where the agent stands, stopping at the last.

        Raises:
            MessageError: a point off the walkable area.
        """
        for k, p in enumerate(points):
            self._on_walkable(p, f"goal point {k + 1}" if len(points) > 1 else "goal")
        info = self.crowd.info(agent)
        info.goal = GoalState(Goal("waypoints", points=tuple((float(x), float(z))
                                                             for x, z in points)),
                              info.goal.rng, self.crowd.nav.route_area)

    def set_pace(self, agent: int, pace: float) -> None:
        """Walk faster or slower than the emotion does: the gait and the navigation."""
        self.crowd.info(agent).pace = float(pace)
        self.crowd.gait.set_pace(agent, pace)

    def add_obstacle(self, corners: np.ndarray) -> int:
        """Cut an obstacle ``(K, 2)`` out of the walkable area; returns its number (from 1).

        The crowd's navigation is built again over the new area
        (:meth:`Crowd.add_obstacle <emotive.crowd.crowd.Crowd.add_obstacle>`, which says
        what is refused) and :attr:`scene_message` describes the new geometry.

        Raises:
            SceneError: a polygon that crosses itself or lies outside the area, or one
                that splits the area or covers a group's spawn, exit or waypoint.
            CrowdError: bodies stand on it.
        """
        number = self.crowd.add_obstacle(np.asarray(corners, dtype=np.float64))
        self._inner = self.crowd.walkable.buffer(-BODY_CLEARANCE)
        self.version += 1
        self.scene_message = scene_message(self.crowd.scene, self.version)
        return number


def load_crowd_engine(path: str | Path, seed: int = 0) -> CrowdEngine:
    """The crowd of a scene file, with the committed gait network, ready to step.

    Everything a scene can get wrong fails here, before the server binds: the file and its
    geometry (:func:`~emotive.crowd.scene.load_scene`), its emotion texts (over the gait
    network's labels), a missing JuPedSim and an area JuPedSim refuses.

    Raises:
        SceneError: a bad scene file, naming the key or group and the fix.
        CrowdError: JuPedSim is missing, or refuses the area.
        ConfigError: the committed weights are missing or corrupt.
    """
    scene = load_scene(path)
    model = load_gait_model()
    over = point_labels(model.labels)
    where = scene.source or scene.name
    for g in scene.groups:
        for text in (g.emotion.text, *g.emotion.choices):
            if not text:
                continue
            try:
                coerce_emotion(text, model.labels, over)
            except EmotiveError as exc:
                raise SceneError(f"{where}: group {g.name!r} emotion", f"{text!r}: {exc}; "
                                 "give a label or a blend such as \"happy=0.7,neutral=0.3\"") \
                    from None
    crowd = Crowd(scene, model=model, seed=seed)
    crowd.gait.prepare()  # the traces would otherwise fall in the first measured steps
    return CrowdEngine(crowd, gait_rest(model), over)
