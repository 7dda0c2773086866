"""The skeleton: joint names, parents in topological order, rest offsets and channel layout."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from emotive.errors import RigError

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")


@dataclass(frozen=True, eq=False)
class Skeleton:
    """An articulated rig.

    Attributes:
        names: ``J`` unique joint names.
        parents: ``(J,)`` parent index of each joint, ``-1`` for roots; ``parents[j] < j``.
        offsets: ``(J, 3)`` rest translation of each joint relative to its parent, in metres.
        channels: per joint, the channel names in file order (BVH style, e.g.
            ``("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")``).
            Joints without rotation channels are fixed at the identity.
        end_site_parents: ``(E,)`` joint index that each end site hangs from.
        end_site_offsets: ``(E, 3)`` end-site offsets relative to their parent joint, in metres.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...] = ()
    end_site_parents: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    end_site_offsets: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        names = tuple(self.names)
        parents = np.asarray(self.parents, dtype=np.int64)
        offsets = np.asarray(self.offsets, dtype=np.float64)
        n = len(names)
        if n == 0:
            raise RigError("a skeleton needs at least one joint")
        if len(set(names)) != n:
            dup = sorted({x for x in names if names.count(x) > 1})
            raise RigError(f"duplicate joint names {dup}: every joint needs a unique name")
        if parents.shape != (n,) or offsets.shape != (n, 3):
            raise RigError(
                f"expected parents ({n},) and offsets ({n}, 3), "
                f"got {parents.shape} and {offsets.shape}"
            )
        if np.any(parents >= np.arange(n)) or np.any(parents < -1):
            raise RigError("parents must be in topological order: parents[j] < j, roots -1")
        channels = tuple(tuple(c) for c in self.channels) or tuple(
            ((*POSITION_CHANNELS, "Zrotation", "Xrotation", "Yrotation") if p < 0 else
             ("Zrotation", "Xrotation", "Yrotation"))
            for p in parents
        )
        if len(channels) != n:
            raise RigError(f"expected channels for {n} joints, got {len(channels)}")
        esp = np.asarray(self.end_site_parents, dtype=np.int64).reshape(-1)
        eso = np.asarray(self.end_site_offsets, dtype=np.float64).reshape(-1, 3)
        if len(esp) != len(eso) or np.any((esp < 0) | (esp >= n)):
            raise RigError("end sites need one valid parent joint index and one offset each")
        for name, value in (
            ("names", names), ("parents", parents), ("offsets", offsets), ("channels", channels),
            ("end_site_parents", esp), ("end_site_offsets", eso),
        ):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def num_joints(self) -> int:
        """Number of joints ``J`` (end sites excluded)."""
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the joint called ``name``; raises :class:`RigError` if there is none."""
        try:
            return self.names.index(name)
        except ValueError:
            raise RigError(
                f"joint {name!r} is not in the rig (joints: {', '.join(self.names)})"
            ) from None

    def rotation_order(self, joint: int) -> str:
        """Euler order of a joint's rotation channels, e.g. ``"ZXY"`` (``""`` if it has none)."""
        return "".join(c[0].upper() for c in self.channels[joint] if c in ROTATION_CHANNELS)

    @property
    def animated_translation(self) -> np.ndarray:
        """``(J,)`` bool: which joints carry position channels."""
        return np.array([any(c in POSITION_CHANNELS for c in ch) for ch in self.channels])

    @property
    def children(self) -> list[list[int]]:
        """Child joint indices of every joint."""
        kids: list[list[int]] = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                kids[p].append(j)
        return kids

    def between(self, top: int, joint: int) -> list[int] | None:
        """The joints strictly between ``top`` and its descendant ``joint``, top first.

        Returns:
            The indices (empty when ``joint`` is a child of ``top``), or ``None`` when
            ``joint`` does not hang below ``top``.
        """
        path, node = [], int(self.parents[joint])
        while node >= 0 and node != top:
            path.append(node)
            node = int(self.parents[node])
        return path[::-1] if node == top else None

    def scaled(self, factor: float) -> Skeleton:
        """The same rig with every length multiplied by ``factor``."""
        return Skeleton(
            self.names, self.parents, self.offsets * factor, self.channels,
            self.end_site_parents, self.end_site_offsets * factor,
        )

    def same_as(self, other: Skeleton, atol: float = 1e-6) -> bool:
        """Whether two rigs have the same names, hierarchy and offsets (within ``atol``)."""
        return (
            self.names == other.names
            and np.array_equal(self.parents, other.parents)
            and np.allclose(self.offsets, other.offsets, atol=atol)
        )


def skeleton_to_dict(skeleton: Skeleton) -> dict:
    """Plain lists of a rig (for ``weights_only`` checkpoints); see :func:`skeleton_from_dict`."""
    return {
        "names": list(skeleton.names), "parents": skeleton.parents.tolist(),
        "offsets": skeleton.offsets.tolist(), "channels": [list(c) for c in skeleton.channels],
        "end_site_parents": skeleton.end_site_parents.tolist(),
        "end_site_offsets": skeleton.end_site_offsets.tolist(),
    }


def skeleton_from_dict(values: dict) -> Skeleton:
    """The rig saved by :func:`skeleton_to_dict`.

    Raises:
        KeyError: a missing entry.
        ValueError: a rig that is not valid (parents out of order, mismatched lengths, ...),
            its reason prefixed by ``skeleton:``, so that the caller reading a saved file
            names the file in its own error.
    """
    try:
        return Skeleton(
            tuple(values["names"]), np.array(values["parents"]), np.array(values["offsets"]),
            tuple(tuple(c) for c in values["channels"]), np.array(values["end_site_parents"]),
            np.array(values["end_site_offsets"]).reshape(-1, 3),
        )
    except RigError as exc:
        raise ValueError(f"skeleton: {exc}") from None
