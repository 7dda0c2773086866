"""Control messages into commands: every field checked before the simulation sees it.

:func:`to_command` turns one parsed message (:func:`emotive.serve.limits.parse_message`) into
a :class:`Command` for the simulation thread; paths become
:class:`~emotive.paths.GroundPath` objects (:func:`parse_path`) and emotions
:class:`~emotive.data.emotion.EmotionSchedule` objects over the engine's labels, through the
project's one coercion (:func:`~emotive.data.emotion.coerce_emotion`). Text that
:func:`~emotive.data.emotion.coerce_emotion` would read as a file name is refused, so a
client can never make the server open a file. Every problem raises
:class:`~emotive.serve.errors.MessageError` naming the field and the fix.

The messages of a server with a scene (``--scene``: a crowd navigating an area with
obstacles) are read here too, whatever the server runs: ``add_agent`` with ``"at"`` and
``"goal"`` (a :class:`PlaceAgent`), ``set_goal``, ``add_obstacle`` and ``scene``; the
simulation refuses them without a scene, and a ``path`` agent with one
(:mod:`~emotive.serve.commands`). Ground points are ``[x, z]`` metres, the scene file's
``[x, y]``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from emotive.data.emotion import EmotionSchedule, coerce_emotion
from emotive.errors import EmotiveError
from emotive.models.gait.agent_inputs import PACE_RANGE
from emotive.paths import GroundPath, circle, figure8, line, waypoints, zigzag
from emotive.serve.errors import MessageError

#: Built-in shapes a path may name, with the size parameters each takes.
SHAPES = {"circle": (circle, ("radius",)), "figure8": (figure8, ("radius",)),
          "line": (line, ("length",)), "zigzag": (zigzag, ("leg", "angle", "count"))}
#: Longest path a message may ask for, metres (paths are sampled every centimetre).
MAX_PATH_METRES = 500.0
#: Every coordinate (path points, a shape's center, a target) lies within this many metres of
#: the origin.
MAX_COORDINATE = 250.0
#: Most points a drawn path may have (checking and smoothing 10,000 points took 12 ms on a
#: 2-core development machine, well within one 33 ms frame).
MAX_PATH_POINTS = 10_000
#: Most keyframes a schedule may have: each is one emotion to read and blend (75 us each on
#: the same machine, so 256 take 19 ms, within a frame; 20,000 took 1.5 s).
MAX_KEYFRAMES = 256
#: Most points of an agent's goal (waypoints visited in order).
MAX_GOAL_POINTS = 64
#: Most corners of an obstacle polygon.
MAX_POLYGON_POINTS = 256
#: Rough length in metres of each shape from its size parameters (defaults as the shapes').
_SHAPE_LENGTH = {
    "circle": lambda k: 2 * math.pi * k.get("radius", 2.0),
    "figure8": lambda k: 4 * math.pi * k.get("radius", 2.0),
    "line": lambda k: k.get("length", 10.0),
    "zigzag": lambda k: k.get("leg", 2.5) * (k.get("count", 6) + 1),
}
#: Fields each message type may carry besides ``type`` and ``ref``.
FIELDS: dict[str, tuple[str, ...]] = {
    "add_agent": ("path", "emotion", "schedule", "pace", "start", "at", "goal"),
    "set_emotion": ("id", "emotion", "schedule"),
    "set_path": ("id", "path"),
    "set_target": ("id", "target"),
    "set_pace": ("id", "pace"),
    "remove_agent": ("id",),
    "ping": ("t",),
    "state": (),
    "start_recording": (),
    "stop_recording": ("id",),
    "set_goal": ("id", "goal"),
    "add_obstacle": ("polygon",),
    "scene": (),
}


@dataclass(frozen=True)
class Command:
    """One checked request for the simulation thread.

    Attributes:
        kind: the message type (a key of :data:`FIELDS`).
        agent: the agent id it concerns, or ``None``.
        value: its checked argument: an :class:`AddAgent` or a :class:`PlaceAgent`, a
            schedule, a path, a ``(2,)`` target, a pace, a recording id, ``(K, 2)`` goal
            points or obstacle corners, or ``None``.
    """

    kind: str
    agent: int | None = None
    value: Any = None


@dataclass(frozen=True)
class AddAgent:
    """A new agent: its path, emotion schedule, start (arc length, metres) and pace."""

    path: GroundPath
    schedule: EmotionSchedule
    start: float = 0.0
    pace: float = 1.0


@dataclass(frozen=True)
class PlaceAgent:
    """A new crowd agent (``--scene``): where it stands and the points it walks to.

    Attributes:
        at: ``(2,)`` ground point ``[x, z]``, metres.
        goal: ``(K, 2)`` waypoints, visited in order; it stops at the last.
        schedule: its emotion schedule.
        pace: factor on its emotion's walking speed.
    """

    at: np.ndarray
    goal: np.ndarray
    schedule: EmotionSchedule
    pace: float = 1.0


def _number(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MessageError(f'"{field}" must be a finite number, got {value!r}')
    return float(value)


def _coordinate(value: Any, field: str) -> float:
    x = _number(value, field)
    if abs(x) > MAX_COORDINATE:
        raise MessageError(f'"{field}" coordinate {x:g} is beyond the scene: coordinates are '
                           f"metres within {MAX_COORDINATE:g} of the origin")
    return x


def agent_id(message: Mapping[str, Any]) -> int:
    """The ``id`` field: a whole number.

    Raises:
        MessageError: missing or not an integer.
    """
    value = message.get("id")
    if isinstance(value, bool) or not isinstance(value, int):
        raise MessageError(f'"{message["type"]}" needs "id", the whole-number id of an agent '
                           f'(from its "agent" reply), got {value!r}')
    return value


def _points(value: Any, where: str) -> np.ndarray:
    """``(N, 2)`` points of a list of ``[x, z]`` pairs, at least two."""
    if not isinstance(value, list) or not all(
            isinstance(p, list) and len(p) == 2 for p in value):
        raise MessageError(f"{where}: a path's points are a list of [x, z] pairs in metres")
    if len(value) > MAX_PATH_POINTS:
        raise MessageError(f"{where}: {len(value)} points are more than the limit of "
                           f"{MAX_PATH_POINTS}; send fewer (the path is smoothed anyway)")
    if not all(type(c) is int or type(c) is float for p in value for c in p):
        bad = next(c for p in value for c in p if not (type(c) is int or type(c) is float))
        _number(bad, "path")
    try:
        pts = np.array(value, dtype=np.float64)
    except OverflowError:
        raise MessageError(f"{where}: a coordinate is beyond float range; coordinates are "
                           f"metres within {MAX_COORDINATE:g} of the origin") from None
    if not np.isfinite(pts).all():
        _number(float(pts[~np.isfinite(pts)][0]), "path")
    far = np.abs(pts) > MAX_COORDINATE
    if far.any():
        _coordinate(float(pts[far][0]), "path")
    _check_length(float(np.linalg.norm(np.diff(pts.reshape(-1, 2), axis=0), axis=1).sum()),
                  where)
    if len(pts) < 2:
        raise MessageError(f"{where}: a path needs at least two [x, z] points, got {len(pts)}; "
                           'use "target" to walk to one point')
    return pts.reshape(-1, 2)


def _check_length(metres: float, where: str) -> None:
    if metres > MAX_PATH_METRES:
        raise MessageError(f"{where} is about {metres:.0f} m long; the server's limit is "
                           f"{MAX_PATH_METRES:g} m: draw a shorter path")


def _shape(spec: Mapping[str, Any]) -> GroundPath:
    name = spec.get("shape")
    if name not in SHAPES:
        raise MessageError(f'path shape {name!r} is unknown; use one of {", ".join(SHAPES)}')
    make, sizes = SHAPES[name]
    unknown = set(spec) - {"shape", "center", *sizes}
    if unknown:
        raise MessageError(f"path shape {name} takes {', '.join(('center', *sizes))}; unknown "
                           f"{', '.join(sorted(unknown))}")
    kwargs = {k: _number(spec[k], k) for k in sizes if k in spec}
    if "count" in kwargs:
        if kwargs["count"] != int(kwargs["count"]) or not 1 <= kwargs["count"] <= 1000:
            raise MessageError(f'"count" must be a whole number 1-1000, got {spec["count"]!r}')
        kwargs["count"] = int(kwargs["count"])
    _check_length(_SHAPE_LENGTH[name](kwargs), f"path shape {name}")
    path = make(**kwargs)
    if "center" not in spec:
        return path
    center = spec["center"]
    if not (isinstance(center, list) and len(center) == 2):
        raise MessageError(f'"center" must be [x, z] in metres, got {center!r}')
    middle = 0.5 * (path.points.min(0) + path.points.max(0))
    shift = np.array([_coordinate(c, "center") for c in center]) - middle
    return GroundPath.from_polyline(path.points + shift, closed=path.closed, name=path.name)


def parse_path(value: Any) -> GroundPath:
    """A ``PATH`` of ``docs/serve.md``: points, ``{"points", "closed"}`` or a shape.

    ``None`` is the default circle. A shape with ``"center"`` is moved so that the middle of
    its bounding box lies there.

    Raises:
        MessageError: a bad form, fewer than two points, non-finite or out-of-range numbers.
    """
    try:
        if value is None:
            return circle()
        if isinstance(value, str):
            return _shape({"shape": value})
        if isinstance(value, list):
            return waypoints(_points(value, "path"), name="drawn")
        if isinstance(value, Mapping) and "shape" in value:
            return _shape(value)
        if isinstance(value, Mapping) and "points" in value:
            unknown = set(value) - {"points", "closed"}
            closed = value.get("closed", False)
            if unknown or not isinstance(closed, bool):
                raise MessageError('a points path is {"points": [[x, z], ...], "closed": '
                                   "true|false}")
            return waypoints(_points(value["points"], "path"), closed=closed, name="drawn")
    except MessageError:
        raise
    except EmotiveError as exc:
        raise MessageError(f"bad path: {exc}") from None
    raise MessageError('"path" must be [[x, z], ...], {"points": [...], "closed": bool}, a '
                       'shape name ("circle", "figure8", "line", "zigzag") or {"shape": ..., '
                       '"center": [x, z], ...}')


def parse_emotion(message: Mapping[str, Any], labels: Sequence[str],
                  default: str | None = None, points_over: Sequence[str] | None = None
                  ) -> EmotionSchedule:
    """The ``emotion`` or ``schedule`` field as a schedule over ``labels``.

    Args:
        message: the control message.
        labels: the engine's ``C`` labels.
        default: the emotion when the message has neither field (``None``: one is required).
        points_over: the labels a valence/arousal point blends (the engine's; ``None``: all).

    Raises:
        MessageError: both or (without ``default``) neither field, text that looks like a
            file name or keyframes, or what :func:`coerce_emotion` refuses.
    """
    has_emotion, has_schedule = "emotion" in message, "schedule" in message
    if has_emotion and has_schedule:
        raise MessageError('give "emotion" or "schedule", not both')
    if not (has_emotion or has_schedule):
        if default is None:
            raise MessageError(f'"{message["type"]}" needs "emotion" (e.g. "happy=0.7,'
                               'neutral=0.3") or "schedule" ([{"t": 0, "emotion": ...}, ...])')
        return coerce_emotion(default, labels, points_over)
    value = message["emotion"] if has_emotion else message["schedule"]
    if has_schedule and not isinstance(value, list):
        raise MessageError('"schedule" is a list of keyframes [{"t": 0, "emotion": ...}, ...]')
    if has_schedule and len(value) > MAX_KEYFRAMES:
        raise MessageError(f'"schedule" has {len(value)} keyframes, more than the limit of '
                           f"{MAX_KEYFRAMES}: send fewer (they are blended linearly, so a few "
                           "keyframes describe a long schedule)")
    if has_emotion and not isinstance(value, str | Mapping):
        raise MessageError('"emotion" is text such as "happy=0.7,neutral=0.3" or "sad", or an '
                           'object {"happy": 0.7} or {"valence": v, "arousal": a}')
    if isinstance(value, str) and (value.strip().startswith("[") or "/" in value
                                   or "\\" in value or value.strip().endswith(".json")):
        raise MessageError(f'"emotion" {value[:80]!r} is not an emotion: give a label such as '
                           '"sad" or weights such as "happy=0.7,neutral=0.3"')
    try:
        return coerce_emotion(value, labels, points_over)
    except EmotiveError as exc:
        raise MessageError(str(exc)) from None
    except (TypeError, ValueError) as exc:
        raise MessageError(f"bad emotion {str(value)[:80]!r}: {exc}") from None


def _pace(value: Any) -> float:
    lo, hi = PACE_RANGE
    pace = _number(value, "pace")
    if not lo <= pace <= hi:
        raise MessageError(f'"pace" must be between {lo:g} and {hi:g}, got {pace:g}')
    return pace


def _target(value: Any) -> np.ndarray:
    if not (isinstance(value, list) and len(value) == 2):
        raise MessageError(f'"target" must be [x, z] in metres, got {value!r}')
    return np.array([_coordinate(c, "target") for c in value])


def _ground_point(value: Any, field: str) -> np.ndarray:
    """``(2,)`` one ``[x, z]`` point of field ``field``."""
    if not (isinstance(value, list) and len(value) == 2):
        raise MessageError(f'"{field}" must be a point [x, z] in metres, got {str(value)[:80]}')
    return np.array([_coordinate(c, field) for c in value])


def _goal(value: Any) -> np.ndarray:
    """``(K, 2)`` a goal: one point ``[x, z]`` or waypoints ``[[x, z], ...]``."""
    if isinstance(value, list) and value and all(isinstance(p, list) for p in value):
        if len(value) > MAX_GOAL_POINTS:
            raise MessageError(f'"goal" has {len(value)} points, more than the limit of '
                               f"{MAX_GOAL_POINTS}: send fewer waypoints")
        return np.stack([_ground_point(p, "goal") for p in value])
    if value is None:
        raise MessageError('"goal" is missing: give a point [x, z] or waypoints '
                           "[[x, z], ...] in metres")
    return _ground_point(value, "goal")[None]


def _ring(value: Any) -> np.ndarray:
    """``(K, 2)`` an obstacle's corners, at least three (a repeated first corner dropped)."""
    if not isinstance(value, list) or not all(isinstance(p, list) for p in value):
        raise MessageError('"polygon" must be the corners [[x, z], ...] of an obstacle in '
                           "metres, in order around it")
    if len(value) > MAX_POLYGON_POINTS:
        raise MessageError(f'"polygon" has {len(value)} corners, more than the limit of '
                           f"{MAX_POLYGON_POINTS}: draw a simpler obstacle")
    pts = [_ground_point(p, "polygon") for p in value]
    if len(pts) > 1 and np.array_equal(pts[0], pts[-1]):
        pts.pop()
    if len({tuple(p) for p in pts}) < 3:
        raise MessageError(f'"polygon" has {len(pts)} distinct corner(s): an obstacle needs at '
                           "least 3 around an area")
    return np.stack(pts)


def _place_agent(message: Mapping[str, Any], labels: Sequence[str],
                 points_over: Sequence[str] | None) -> PlaceAgent:
    both = {"path", "start"} & set(message)
    if both:
        raise MessageError(f'add_agent takes "at" and "goal" (a crowd agent) or "path", not '
                           f"both: drop {', '.join(sorted(both))}")
    if "at" not in message:
        raise MessageError('add_agent with "goal" needs "at", the point [x, z] it starts from')
    return PlaceAgent(_ground_point(message["at"], "at"), _goal(message.get("goal")),
                      parse_emotion(message, labels, "neutral", points_over),
                      _pace(message.get("pace", 1.0)))


def to_command(message: Mapping[str, Any], labels: Sequence[str],
               points_over: Sequence[str] | None = None) -> Command:
    """The simulation command of a parsed control message (any type but ``ping``).

    Emotions are coerced over the engine's ``labels``, a valence/arousal point blended over
    ``points_over`` (:func:`parse_emotion`).

    Raises:
        MessageError: an unknown type, an unknown field, or a missing or bad field.
    """
    kind = message["type"]
    if kind not in FIELDS or kind == "ping":
        known = ", ".join(k for k in FIELDS)
        raise MessageError(f"unknown message type {kind!r}; use one of {known}")
    unknown = set(message) - {"type", "ref", *FIELDS[kind]}
    if unknown:
        raise MessageError(f"{kind} has no field {', '.join(sorted(map(str, unknown)))}; its "
                           f"fields: {', '.join(FIELDS[kind]) or 'none'}")
    if kind == "add_agent" and ("at" in message or "goal" in message):
        return Command(kind, None, _place_agent(message, labels, points_over))
    if kind == "add_agent":
        return Command(kind, None, AddAgent(
            parse_path(message.get("path")), parse_emotion(message, labels, "neutral", points_over),
            _number(message.get("start", 0.0), "start"), _pace(message.get("pace", 1.0))))
    if kind in ("state", "start_recording", "scene"):
        return Command(kind)
    if kind == "add_obstacle":
        return Command(kind, None, _ring(message.get("polygon")))
    if kind == "stop_recording":
        rid = message.get("id")
        if rid is not None and (isinstance(rid, bool) or not isinstance(rid, int)):
            raise MessageError(f'"id" of stop_recording is a recording id, got {rid!r}')
        return Command(kind, None, rid)
    agent = agent_id(message)
    if kind == "set_emotion":
        return Command(kind, agent, parse_emotion(message, labels, points_over=points_over))
    if kind == "set_path":
        if "path" not in message:
            raise MessageError('set_path needs "path"')
        return Command(kind, agent, parse_path(message["path"]))
    if kind == "set_target":
        return Command(kind, agent, _target(message.get("target")))
    if kind == "set_pace":
        return Command(kind, agent, _pace(message.get("pace")))
    if kind == "set_goal":
        return Command(kind, agent, _goal(message.get("goal")))
    return Command(kind, agent)
