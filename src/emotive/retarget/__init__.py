"""Retargeting: any humanoid clip played on any humanoid rig (issue 23).

* :mod:`~emotive.retarget.retarget`: :func:`retarget`, rest poses aligned per bone, the
  target's bone lengths, root motion scaled by leg length, planted feet kept by a two-bone
  leg solve.
* :mod:`~emotive.retarget.rest`: rest poses described by role bones.
* :mod:`~emotive.retarget.feet`: the ground under a clip and how much its feet slide.
* :mod:`~emotive.retarget.templates`: any rig rebuilt standing in a T- or A-pose, with other
  proportions and rotation orders (target rigs for tests and demos).

The layer sits between :mod:`emotive.ik` and :mod:`emotive.models`: it uses ``core``, ``io``,
``features`` and ``ik``, and the models and commands use it.
"""

from emotive.retarget.feet import foot_skate, lowest_ankle_height, plant_feet
from emotive.retarget.retarget import Pairing, leg_scale, pair_rigs, resolve_rig, retarget
from emotive.retarget.templates import PARTS, POSES, rest_clip, rest_template

__all__ = [
    "PARTS",
    "POSES",
    "Pairing",
    "foot_skate",
    "leg_scale",
    "lowest_ankle_height",
    "pair_rigs",
    "plant_feet",
    "resolve_rig",
    "rest_clip",
    "rest_template",
    "retarget",
]
