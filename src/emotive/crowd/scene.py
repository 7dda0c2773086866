"""Crowd scenes as plain values: the walkable area, its obstacles and the groups of agents.

A scene is read from TOML (``scene.toml``, see ``docs/crowd.md``) into frozen dataclasses of
tuples and numbers, so that it can be compared, hashed and serialised
(:meth:`Scene.to_dict` / :meth:`Scene.from_dict`, JSON-able) and carried by a synth shard.
This module checks the structure (keys, types, numbers); the geometry (valid polygons,
spawns and goals inside the walkable area, reachability, spawn capacity) is checked by
:func:`emotive.crowd.validation.validate_scene`, which :func:`load_scene` runs.

Coordinates are metres on the ground plane, ``[x, y]`` in the file; in the world of the
bodies (Y up) the scene's ``y`` is the world ``z``.

Goals (``goal`` of a group):

* a polygon ``[[x, y], ...]``: walk to it and leave the scene there (an exit);
* ``{ waypoints = [[x, y], ...] }``: visit the points in order and stop at the last;
* ``"wander"``: walk to random points of the area, one after the other, until the run ends.

Emotions (``emotion`` of a group): a text the project's parser takes
(:meth:`emotive.data.emotion.EmotionSchedule.parse`: ``"happy=0.7,neutral=0.3"``,
``"valence=0.5,arousal=-0.2"``), or a distribution to draw each agent's emotion from:
``{ choices = ["happy", "sad"], weights = [3, 1] }`` or
``{ valence = [lo, hi], arousal = [lo, hi] }`` (uniform).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from emotive.crowd.errors import SceneError

__all__ = ["EmotionSpec", "Goal", "Group", "Point", "Polygon", "Scene", "load_scene",
           "parse_scene"]

Point = tuple[float, float]
Polygon = tuple[Point, ...]

#: Goal kinds: leave by a polygon, visit waypoints, wander.
GOAL_KINDS = ("exit", "waypoints", "wander")
#: Limits of a group's pace factor (as the gait generator's).
PACE_LIMITS = (0.5, 1.5)
#: Largest coordinate accepted (metres): beyond, likely a unit mistake.
MAX_COORDINATE = 1.0e4


@dataclass(frozen=True)
class Goal:
    """Where a group's agents go.

    Attributes:
        kind: ``exit`` (reach ``polygon`` and leave), ``waypoints`` (visit ``points`` in order,
            stop at the last) or ``wander``.
        polygon: the exit polygon (``exit`` only).
        points: the waypoints (``waypoints`` only).
    """

    kind: str
    polygon: Polygon = ()
    points: tuple[Point, ...] = ()


@dataclass(frozen=True)
class EmotionSpec:
    """A group's emotion: one text for every agent, or a distribution to draw from.

    Attributes:
        text: an emotion text (every agent), or ``""`` for a distribution.
        choices: emotion texts to draw from.
        weights: their relative weights (as many as ``choices``).
        valence: ``(lo, hi)`` uniform range of valence, or ``()``.
        arousal: ``(lo, hi)`` uniform range of arousal, or ``()``.
    """

    text: str = ""
    choices: tuple[str, ...] = ()
    weights: tuple[float, ...] = ()
    valence: tuple[float, ...] = ()
    arousal: tuple[float, ...] = ()


@dataclass(frozen=True)
class Group:
    """Agents that spawn together and share a goal.

    Attributes:
        name: the group's name (messages, outputs).
        spawn: the polygon where its agents appear.
        goal: where they go.
        emotion: their emotion or its distribution.
        count: how many agents (with ``flow``: in all, ``0`` for no limit).
        flow: agents per second entering over time (``0``: all at the start).
        pace: ``(lo, hi)`` factor on the emotion's walking speed, drawn uniformly per agent.
    """

    name: str
    spawn: Polygon
    goal: Goal
    emotion: EmotionSpec
    count: int = 0
    flow: float = 0.0
    pace: tuple[float, float] = (1.0, 1.0)


@dataclass(frozen=True)
class Scene:
    """A walkable area with obstacles and groups of agents (see the module docstring).

    Attributes:
        area: the outer polygon of the walkable area.
        obstacles: polygons cut out of it.
        groups: the agent groups.
        name: a label (the file's stem by default).
        source: the file it was read from (for messages), ``""`` for a built value.
    """

    area: Polygon
    obstacles: tuple[Polygon, ...]
    groups: tuple[Group, ...]
    name: str = "scene"
    source: str = field(default="", compare=False)

    def to_dict(self) -> dict[str, Any]:
        """The scene as plain lists and numbers, in the file's layout (JSON/TOML-able)."""
        return {"name": self.name, "area": {
            "polygon": [list(p) for p in self.area],
            "obstacles": [{"polygon": [list(p) for p in o]} for o in self.obstacles]},
            "groups": [_group_dict(g) for g in self.groups]}

    @classmethod
    def from_dict(cls, values: Mapping[str, Any], source: str = "") -> Scene:
        """The scene of :meth:`to_dict` or of a parsed TOML file (structure checked only).

        Raises:
            SceneError: a missing or bad key (naming it and the fix).
        """
        return parse_scene(values, source)


def _group_dict(g: Group) -> dict[str, Any]:
    out: dict[str, Any] = {"name": g.name, "spawn": [list(p) for p in g.spawn]}
    if g.goal.kind == "exit":
        out["goal"] = [list(p) for p in g.goal.polygon]
    elif g.goal.kind == "waypoints":
        out["goal"] = {"waypoints": [list(p) for p in g.goal.points]}
    else:
        out["goal"] = "wander"
    e = g.emotion
    if e.text:
        out["emotion"] = e.text
    elif e.choices:
        out["emotion"] = {"choices": list(e.choices), "weights": list(e.weights)}
    else:
        out["emotion"] = {"valence": list(e.valence), "arousal": list(e.arousal)}
    if g.count:
        out["count"] = g.count
    if g.flow:
        out["flow"] = g.flow
    out["pace"] = list(g.pace)
    return out


def load_scene(path: str | Path, validate: bool = True) -> Scene:
    """Read a ``scene.toml`` and check it.

    Args:
        path: the file.
        validate: also check the geometry (:func:`~emotive.crowd.validation.validate_scene`).

    Raises:
        SceneError: a missing or unreadable file, bad TOML, or a bad key or geometry.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(str(path), f"cannot read the scene ({exc.strerror}); give an existing "
                         "scene.toml") from None
    try:
        values = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(str(path), f"not valid TOML ({exc}); fix the syntax") from None
    values = {"name": path.stem, **values}
    scene = parse_scene(values, str(path))
    if validate:
        from emotive.crowd.validation import validate_scene  # noqa: PLC0415 (shapely: optional)

        validate_scene(scene)
    return scene


def parse_scene(values: Mapping[str, Any], source: str = "") -> Scene:
    """A :class:`Scene` from parsed TOML (or :meth:`Scene.to_dict`); structure checked only.

    Raises:
        SceneError: a missing or bad key, naming it and the fix.
    """
    where = source or "scene"
    known = {"name", "area", "groups"}
    _no_unknown(values, known, where)
    area = values.get("area")
    if not isinstance(area, Mapping):
        raise SceneError(where, "no [area] table: add [area] with polygon = [[x, y], ...] in "
                         "metres")
    _no_unknown(area, {"polygon", "obstacles"}, f"{where}: [area]")
    outer = _polygon(area.get("polygon"), f"{where}: [area] polygon")
    obstacles = area.get("obstacles", [])
    if not isinstance(obstacles, list):
        raise SceneError(f"{where}: [area] obstacles", "give [[area.obstacles]] tables, each "
                         "with polygon = [[x, y], ...]")
    holes = []
    for k, o in enumerate(obstacles):
        if not isinstance(o, Mapping) or "polygon" not in o:
            raise SceneError(f"{where}: obstacle {k + 1}", "give polygon = [[x, y], ...]")
        holes.append(_polygon(o["polygon"], f"{where}: obstacle {k + 1} polygon"))
    groups = values.get("groups")
    if not isinstance(groups, list) or not groups:
        raise SceneError(where, "no [[groups]]: add at least one [[groups]] table with spawn, "
                         "count, goal and emotion")
    parsed = [_group(g, k, where) for k, g in enumerate(groups)]
    names = [g.name for g in parsed]
    for name in names:
        if names.count(name) > 1:
            raise SceneError(f"{where}: group {name!r}", "two groups have this name; give each "
                             "group its own name")
    return Scene(outer, tuple(holes), tuple(parsed), str(values.get("name", "scene")), source)


def _no_unknown(values: Mapping[str, Any], known: set[str], where: str) -> None:
    for key in values:
        if key not in known:
            raise SceneError(where, f"unknown key {key!r}; known keys: {', '.join(sorted(known))}")


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SceneError(where, f"{value!r} is not a finite number; give one in metres")
    if abs(value) > MAX_COORDINATE:
        raise SceneError(where, f"{value!r} is beyond {MAX_COORDINATE:g} m; give metres")
    return float(value)


def _point(value: Any, where: str) -> Point:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise SceneError(where, f"{value!r} is not a point; give [x, y] in metres")
    return (_number(value[0], where), _number(value[1], where))


def _polygon(value: Any, where: str) -> Polygon:
    """A polygon's points (the ring is closed implicitly; a repeated first point is dropped)."""
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise SceneError(where, "give a polygon as a list of points [[x, y], ...]")
    points = [_point(p, where) for p in value]
    if len(points) > 1 and points[0] == points[-1]:
        points.pop()
    if len(set(points)) < 3:
        raise SceneError(where, f"the polygon is open: {len(set(points))} distinct point(s) "
                         "enclose no area; give at least 3 points around an area")
    return tuple(points)


def _goal(value: Any, where: str) -> Goal:
    if value == "wander":
        return Goal("wander")
    if isinstance(value, Mapping):
        _no_unknown(value, {"waypoints"}, where)
        pts = value.get("waypoints")
        if not isinstance(pts, list) or not pts:
            raise SceneError(where, "give { waypoints = [[x, y], ...] } with at least one point")
        return Goal("waypoints", points=tuple(_point(p, where) for p in pts))
    if value is None:
        raise SceneError(where, "missing; give a polygon [[x, y], ...] to leave by, "
                         "{ waypoints = [[x, y], ...] } or \"wander\"")
    if isinstance(value, str):
        raise SceneError(where, f"unknown goal {value!r}; give a polygon, "
                         "{ waypoints = [...] } or \"wander\"")
    return Goal("exit", polygon=_polygon(value, where))


def _range(value: Any, where: str, lo: float, hi: float) -> tuple[float, float]:
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value, value]
    if not isinstance(value, list) or len(value) != 2:
        raise SceneError(where, f"give a number or a range [lo, hi] within {lo:g}..{hi:g}")
    a, b = (_number(v, where) for v in value)
    if not lo <= a <= b <= hi:
        raise SceneError(where, f"[{a:g}, {b:g}] is not a range within {lo:g}..{hi:g}; "
                         "give lo <= hi inside it")
    return (a, b)


def _emotion(value: Any, where: str) -> EmotionSpec:
    from emotive.data.emotion import VA_LIMIT  # noqa: PLC0415 (only to check ranges)

    if isinstance(value, str):
        return EmotionSpec(text=value)
    if not isinstance(value, Mapping):
        raise SceneError(where, "give a text such as \"happy=0.7,neutral=0.3\" or a "
                         "distribution { choices = [...], weights = [...] } or "
                         "{ valence = [lo, hi], arousal = [lo, hi] }")
    _no_unknown(value, {"choices", "weights", "valence", "arousal"}, where)
    if "choices" in value:
        choices = value["choices"]
        if not isinstance(choices, list) or not choices or not all(
                isinstance(c, str) for c in choices):
            raise SceneError(where, "choices: give a list of emotion texts")
        weights = value.get("weights", [1.0] * len(choices))
        if not isinstance(weights, list) or len(weights) != len(choices):
            raise SceneError(where, f"weights: give {len(choices)} numbers, one per choice")
        w = tuple(_number(x, f"{where} weights") for x in weights)
        if min(w) < 0 or sum(w) <= 0:
            raise SceneError(where, "weights: give non-negative numbers, not all zero")
        return EmotionSpec(choices=tuple(choices), weights=w)
    if "valence" in value and "arousal" in value:
        return EmotionSpec(valence=_range(value["valence"], f"{where} valence", -VA_LIMIT,
                                          VA_LIMIT),
                           arousal=_range(value["arousal"], f"{where} arousal", -VA_LIMIT,
                                          VA_LIMIT))
    raise SceneError(where, "give choices = [...] (with weights) or both valence = [lo, hi] "
                     "and arousal = [lo, hi]")


def _group(g: Any, k: int, where: str) -> Group:
    if not isinstance(g, Mapping):
        raise SceneError(f"{where}: group {k + 1}", "give a [[groups]] table")
    name = str(g.get("name", f"group-{k + 1}"))
    at = f"{where}: group {name!r}"
    _no_unknown(g, {"name", "spawn", "count", "flow", "goal", "emotion", "pace"}, at)
    if "spawn" not in g:
        raise SceneError(at, "no spawn; give spawn = [[x, y], ...], the polygon where its "
                         "agents appear")
    spawn = _polygon(g["spawn"], f"{at} spawn")
    count = g.get("count", 0)
    flow = g.get("flow", 0.0)
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise SceneError(f"{at} count", f"{count!r} is not a whole number >= 0")
    if isinstance(flow, bool) or not isinstance(flow, int | float) or not (
            math.isfinite(flow) and flow >= 0):
        raise SceneError(f"{at} flow", f"{flow!r} is not agents per second >= 0")
    if count == 0 and flow == 0:
        raise SceneError(at, "no agents; give count = N, or flow = agents per second")
    goal = _goal(g.get("goal"), f"{at} goal")
    if "emotion" not in g:
        raise SceneError(at, "no emotion; give emotion = \"neutral\" or a blend such as "
                         "\"happy=0.7,neutral=0.3\"")
    emotion = _emotion(g["emotion"], f"{at} emotion")
    pace = _range(g.get("pace", 1.0), f"{at} pace", *PACE_LIMITS)
    return Group(name, spawn, goal, emotion, int(count), float(flow), pace)
