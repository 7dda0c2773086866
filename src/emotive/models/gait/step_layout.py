"""The per-agent state vector of the exported gait step, field by field.

The whole-step graph (:mod:`emotive.models.gait.step_graph`) keeps everything an agent
carries from frame to frame, except the GRU state, in one float row per agent: an engine feeds
back what it got and never needs to read it, while the Python host and the tests read fields
by name. ``J`` is the rig's joint count; everything is float (the planted flags are 0 or 1).

=======================  ===============  ==============================================
field                    shape            meaning
=======================  ===============  ==============================================
``rotations``            ``(J, 4)``       current heading-canonical local rotations
``root``                 ``(3,)``         current root features ``[h, s, delta]``
``affective``            ``(18,)``        affective features of that pose (ratios in log space)
``theta``                ``()``           stepping phase, radians
``speed_lowpass``        ``()``           low-passed target speed, metres per frame
``delta``                ``()``           low-passed facing offset into turns, radians
``kappa``                ``()``           curvature input ``s^2 |k|``
``curvature``            ``()``           path curvature under the agent, 1/m (signed)
``x``, ``z``             ``()``           ground position, metres
``heading``              ``()``           world yaw, radians (0 faces +Z)
``lock_previous``        ``(2, 2, 3)``    unlocked heel and toe positions of the last frame
``lock_planted``         ``(2, 2)``       planted heels and toes (0 or 1)
``lock_anchor``          ``(2, 2)``       where each foot's planted point is held ``(x, z)``
``lock_correction``      ``(2, 2)``       each foot's horizontal correction, metres
``lock_yaw_anchor``      ``(2,)``         world yaw each foot in contact is held at
``lock_yaw_correction``  ``(2,)``         each foot's yaw correction, radians
``lock_released``        ``(2,)``         frames since each foot's contact ended
=======================  ===============  ==============================================
"""

from __future__ import annotations

import math

import torch

from emotive.features.affective import AFFECTIVE_FEATURE_NAMES

#: The lock fields, in order, as named in :class:`~emotive.ik.foot_lock_kernel.LockTensors`.
LOCK_FIELDS: tuple[str, ...] = ("previous", "planted", "anchor", "correction", "yaw_anchor",
                                "yaw_correction", "released")


def field_shapes(joints: int) -> dict[str, tuple[int, ...]]:
    """Field name -> shape of one agent's row, in row order (the module docstring's table)."""
    shapes: dict[str, tuple[int, ...]] = {
        "rotations": (joints, 4), "root": (3,), "affective": (len(AFFECTIVE_FEATURE_NAMES),),
    }
    for name in ("theta", "speed_lowpass", "delta", "kappa", "curvature", "x", "z", "heading"):
        shapes[name] = ()
    lock = {"previous": (2, 2, 3), "planted": (2, 2), "anchor": (2, 2),
            "correction": (2, 2), "yaw_anchor": (2,), "yaw_correction": (2,),
            "released": (2,)}
    shapes.update({f"lock_{k}": lock[k] for k in LOCK_FIELDS})
    return shapes


class AgentLayout:
    """Where each field lies in the row, and packing between rows and named tensors.

    Args:
        joints: ``J``.
    """

    def __init__(self, joints: int) -> None:
        self.shapes = field_shapes(joints)
        self.slices: dict[str, slice] = {}
        at = 0
        for name, shape in self.shapes.items():
            size = math.prod(shape)
            self.slices[name] = slice(at, at + size)
            at += size
        self.size = at

    def field(self, rows: torch.Tensor, name: str) -> torch.Tensor:
        """``(B, *shape)`` the field ``name`` of ``(B, S)`` rows (a view)."""
        return rows[:, self.slices[name]].reshape(-1, *self.shapes[name])

    def unpack(self, rows: torch.Tensor) -> dict[str, torch.Tensor]:
        """Every field of ``(B, S)`` rows, by name (views, from one split)."""
        sizes = [s.stop - s.start for s in self.slices.values()]
        parts = torch.split(rows, sizes, 1)
        return {name: part.reshape(-1, *shape)
                for (name, shape), part in zip(self.shapes.items(), parts, strict=True)}

    def pack(self, fields: dict[str, torch.Tensor]) -> torch.Tensor:
        """``(B, S)`` rows from every field, each ``(B, *shape)``."""
        parts = [fields[name].reshape(-1, math.prod(shape)) for name, shape in self.shapes.items()]
        return torch.cat(parts, 1)

    def to_json(self) -> list[dict]:
        """The layout as the graph's metadata states it: ``[{name, offset, shape}]``."""
        return [{"name": n, "offset": s.start, "shape": list(self.shapes[n])}
                for n, s in self.slices.items()]
