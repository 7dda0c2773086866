"""The crowd scene of ``emotive export web --scene``: what the page needs, computed at export.

The page runs the scene with recast-navigation's Detour crowd (``crowd.js``): it builds a
navigation mesh from a flat ground mesh of the walkable area, spawns each group's agents on
its spawn places, sends them to their goals and sets each navigation agent's parameters from
its emotion. Everything that needs geometry or the emotion parser is done here, once, in
Python, with the crowd's own functions, and written as ``scene.json`` beside the page:

=================  ===========================================================================
``scene``          the scene as its file says it (:meth:`~emotive.crowd.scene.Scene.to_dict`)
``mesh``           the walkable area (the area less its obstacles) as triangles: ``vertices``
                   ``(V, 2)`` and ``triangles`` ``(T, 3)`` indices, each triangle clockwise
                   in the ``(x, y)`` plane, so that its normal in the bodies' world (``y`` is
                   the world ``z``, Y up) points up, as Recast wants walkable triangles
``groups``         per group: its spawn ``sites`` (:func:`~emotive.crowd.validation.spawn_sites`,
                   the places ``emotive crowd`` uses), ``count``, ``flow``, ``pace``, the
                   ``emotion`` resolved to weights over the model's labels (below) and the
                   ``goal`` with, for an exit, the ``targets`` a walker heads for: triangles
                   of the exit polygon shrunk by a body's half width, within the route area
                   (``emotive crowd`` draws its destination in the exit within the route area)
``roam``           triangles of the route area (the walkable area shrunk by the routes'
                   clearance): where wanderers draw their next point
``navigation``     the emotion-to-navigation table of ``emotive crowd``
                   (:data:`~emotive.crowd.emotion_table.TABLE`: radius, time gap, yielding per
                   emotion of the main paper) that the page blends per agent
``constants``      the crowd's spawn spacing, arrival radius and body clearance
=================  ===========================================================================

A group's emotion becomes ``{"weights": (C,)}`` for a text (a label, a blend or a
valence/arousal point, parsed as ``emotive crowd`` parses it; a schedule gives its first
keyframe), ``{"choices": [(C,), ...], "p": [...]}`` for a choice, or ``{"valence": [lo, hi],
"arousal": [lo, hi]}`` for a box, which the page turns into weights with the same kernel
(``emotion.js``).

Legend: ``C`` emotion labels, ``V`` vertices, ``T`` triangles.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from emotive.crowd.emotion_table import COLUMNS, TABLE
from emotive.crowd.errors import SceneError
from emotive.crowd.scene import EmotionSpec, Scene
from emotive.data.circumplex import DEFAULT_LABELS
from emotive.errors import ConfigError, EmotionError

#: ``format`` of ``scene.json``.
SCENE_FORMAT = "emotive-web-scene/1"
#: Its file name, beside the page.
SCENE_FILE = "scene.json"
#: Decimals kept of coordinates (0.1 mm).
_DECIMALS = 4


def crowd_geometry() -> Any:
    """The crowd's geometry modules (shapely), or a one-line error naming the extra."""
    try:
        import shapely  # noqa: PLC0415 (an optional extra, only with --scene)

        from emotive.crowd import goals, validation  # noqa: PLC0415 (they import shapely)
    except ImportError as exc:
        raise ConfigError(f"--scene needs shapely ({exc.name} is not installed); install "
                          "the crowd extra: pip install 'emotive[crowd]'") from None
    return shapely, validation, goals


def triangles(shape: Any) -> tuple[np.ndarray, np.ndarray]:
    """A polygon with holes (or several) as a triangle mesh.

    Args:
        shape: a shapely ``Polygon`` or ``MultiPolygon`` (metres).

    Returns:
        ``vertices`` ``(V, 2)`` and ``triangles`` ``(T, 3)`` (indices), each triangle
        clockwise in the ``(x, y)`` plane (its normal points up in the bodies' world, where
        ``y`` is ``z``), from shapely's constrained Delaunay triangulation, which keeps the
        boundary and the holes' edges.
    """
    shapely = crowd_geometry()[0]
    tris = [np.asarray(t.exterior.coords)[:3]
            for t in shapely.constrained_delaunay_triangles(shape).geoms if t.area > 1e-12]
    if not tris:
        return np.zeros((0, 2)), np.zeros((0, 3), dtype=np.int64)
    corners = np.round(np.asarray(tris), _DECIMALS)
    vertices, index = np.unique(corners.reshape(-1, 2), axis=0, return_inverse=True)
    index = index.reshape(-1, 3)
    a = vertices[index[:, 1]] - vertices[index[:, 0]]
    b = vertices[index[:, 2]] - vertices[index[:, 0]]
    # Recast's walkable test reads the normal (v1 - v0) x (v2 - v0) with (x, 0, y): its up
    # component is -(a x b) of the plane, so a counter-clockwise triangle faces down.
    ccw = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0
    index[ccw] = index[ccw][:, [0, 2, 1]]
    return vertices, index


def _flat(shape: Any) -> list[float]:
    """Triangles of ``shape`` as ``[ax, ay, bx, by, cx, cy, ...]`` (for sampling points)."""
    vertices, index = triangles(shape)
    return np.round(vertices[index].reshape(-1), _DECIMALS).tolist()


def _weights(text: str, labels: Sequence[str], where: str) -> list[float]:
    from emotive.models.gait.agent_inputs import to_model_schedule  # noqa: PLC0415 (torch)

    try:
        weights = to_model_schedule(text, labels).at(0.0)
    except EmotionError as exc:
        raise SceneError(where, f"{exc}; give an emotion this model knows") from None
    return [round(float(w), 6) for w in np.asarray(weights).reshape(-1)]


def resolve_emotion(spec: EmotionSpec, labels: Sequence[str], where: str) -> dict[str, Any]:
    """A group's emotion as the page draws it (see the module docstring).

    Raises:
        SceneError: a text the emotion parser refuses, naming the group.
    """
    if spec.text:
        return {"weights": _weights(spec.text, labels, where)}
    if spec.choices:
        p = np.asarray(spec.weights, dtype=np.float64)
        return {"choices": [_weights(c, labels, where) for c in spec.choices],
                "p": (p / p.sum()).tolist()}
    return {"valence": list(spec.valence), "arousal": list(spec.arousal)}


def _goal(goal: Any, route: Any, clearance: float) -> dict[str, Any]:
    shapely = crowd_geometry()[0]
    if goal.kind == "exit":
        exit_shape = shapely.Polygon(goal.polygon)
        # A body's half width inside the exit, so that a walker standing where Detour lets it
        # arrive (within a few centimetres of its target) is in the exit, not on its edge.
        target = exit_shape.buffer(-clearance).intersection(route)
        if target.is_empty or target.area <= 1e-9:
            target = exit_shape.intersection(route)
        if target.is_empty or target.area <= 1e-9:
            target = exit_shape
        return {"kind": "exit", "polygon": [list(p) for p in goal.polygon],
                "targets": _flat(target)}
    if goal.kind == "waypoints":
        return {"kind": "waypoints", "points": [list(p) for p in goal.points]}
    return {"kind": "wander"}


def scene_document(scene: Scene, labels: Sequence[str]) -> dict[str, Any]:
    """The content of ``scene.json`` (see the module docstring).

    Args:
        scene: a checked scene (:func:`~emotive.crowd.scene.load_scene`).
        labels: the model's ``C`` emotion labels.

    Returns:
        A JSON-able dict.

    Raises:
        SceneError: a bad polygon or an emotion this model does not know.
        ConfigError: shapely (the crowd extra) is not installed.
    """
    _, validation, goals = crowd_geometry()
    where = scene.source or scene.name
    walkable = validation.validate_scene(scene)
    route = validation.route_area(walkable)
    vertices, index = triangles(walkable)
    groups = []
    for g in scene.groups:
        at = f"{where}: group {g.name!r}"
        sites = validation.spawn_sites(validation.polygon(g.spawn, f"{at} spawn"), walkable)
        groups.append({
            "name": g.name, "sites": np.round(sites, _DECIMALS).tolist(), "count": g.count,
            "flow": g.flow, "pace": list(g.pace),
            "emotion": resolve_emotion(g.emotion, labels, f"{at} emotion"),
            "goal": _goal(g.goal, route, validation.BODY_CLEARANCE)})
    return {
        "format": SCENE_FORMAT,
        "name": scene.name,
        "scene": scene.to_dict(),
        "mesh": {"vertices": np.round(vertices, _DECIMALS).tolist(),
                 "triangles": index.tolist()},
        "groups": groups,
        "roam": _flat(route),
        "navigation": {"columns": list(COLUMNS), "labels": list(DEFAULT_LABELS),
                       "table": {label: list(TABLE[label]) for label in DEFAULT_LABELS}},
        "constants": {"spawn_spacing": validation.SPAWN_SPACING,
                      "arrival_radius": goals.ARRIVAL_RADIUS,
                      "body_clearance": validation.BODY_CLEARANCE},
    }
