"""Crowds: gait bodies walking a scene together, each with a JuPedSim navigation agent.

Modules, by concept: :mod:`~emotive.crowd.scene` (the scene file as a plain value),
:mod:`~emotive.crowd.validation` (its geometry checks, spawn places),
:mod:`~emotive.crowd.emotion_table` (emotion to navigation parameters),
:mod:`~emotive.crowd.navigation` (JuPedSim, tied back to the bodies),
:mod:`~emotive.crowd.goals` (exits, waypoints, wandering), :mod:`~emotive.crowd.crowd` (the
:class:`~emotive.crowd.crowd.Crowd` beside the gait generator),
:mod:`~emotive.crowd.trajectories` (recording, PedPy's trajectory format) and
:mod:`~emotive.crowd.measure` (measures of a written run). See ``docs/crowd.md``.

Nothing heavy is imported here: ``Crowd``, ``Scene`` and ``load_scene`` load their modules
when first used, and JuPedSim only when a navigation is built.
"""

from __future__ import annotations

from typing import Any

__all__ = ["Crowd", "Scene", "load_scene"]

_WHERE = {"Crowd": "emotive.crowd.crowd", "Scene": "emotive.crowd.scene",
          "load_scene": "emotive.crowd.scene"}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib  # noqa: PLC0415 (lazy exports)

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'emotive.crowd' has no attribute {name!r}")
