"""Mirror images of rigs: left/right joint pairing and the local reflection of every joint.

:func:`emotive.core.ops.mirror` applies these maps to a clip.

Legend: ``J`` joints, ``E`` end sites.

Mirroring rule
--------------
:func:`mirror` reflects the world across the ``X = 0`` plane (``M = diag(-1, 1, 1)``) and swaps
left and right joints (``sigma``). Reflecting a joint's world frame ``R`` gives ``M R``, which
is not a rotation; each joint ``j`` therefore gets a local reflection ``D_j`` with
``det(D_j) = -1``, chosen from ``-I`` (point reflection) and the three axis-plane reflections
``diag(-1, 1, 1)``, ``diag(1, -1, 1)``, ``diag(1, 1, -1)``, and the mirrored world frame is
``M R_sigma(j) D_j``. Forward kinematics then forces:

* local rotations ``q'_j = conj(d_p) * q_sigma(j) * d_j``, where ``d`` is the unit quaternion of
  the rotation part of ``-D`` (``1``, ``i``, ``j`` or ``k``) and ``p`` the parent (the world's
  ``d`` is ``i``, the quaternion of ``-M``);
* local translations, rest offsets and end-site offsets ``t'_j = D_p t_sigma(j)`` (for roots,
  ``M t``).

With these, mirrored world positions equal the reflected original positions exactly, for any
choice of ``D_j``. The choice only decides whether the mirrored rig keeps the original rest
offsets and whether mirrored local rotations look like the rig's own: ``D_j`` is the candidate
that maps the mirrored children's offsets onto the joint's own children's offsets (within 5% of
the bone length); ties go to the parent's ``D``, then to ``-I``. On a rig at rest in a T-pose
with identity rotations (CMU style) every joint gets ``diag(-1, 1, 1)``, the familiar
``(w, x, y, z) -> (w, x, -y, -z)``. On the Bandai Namco rig (bones along local X, right-side
offsets negated) the limbs get ``-I`` (their local rotations are copied across unchanged), the
hips ``diag(1, -1, 1)`` and spine, chest, neck and head ``diag(1, 1, -1)``, and the mirrored rig
has the original offsets up to the rig's own asymmetry (below half a millimetre).

Because the maps are signed permutations, mirroring twice gives back rotations, translations and
offsets bit for bit, except that a joint whose ``D`` differs in kind from its parent's (point
versus plane reflection, e.g. Bandai's shoulders and upper legs) comes back as ``-q``: the same
rotation, as ``q`` and ``-q`` always are.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

__all__ = [
    "REFLECTION_QUATS",
    "REFLECTION_SIGNS",
    "MirrorMap",
    "mirror_map",
    "mirror_skeleton",
    "parent_reflections",
]

# Sided name patterns: (regex, replacement for left, replacement for right). "Strong" patterns
# make a joint without a counterpart an error; the bare one-letter prefix is too easily part of
# a word ("Root") and only pairs joints when the counterpart exists.
_STRONG_SIDES: tuple[tuple[str, str, str], ...] = (
    (r"(?<=[_.\-])([LR])$", "L", "R"),
    (r"(?<=[_.\-])([lr])$", "l", "r"),
    (r"(Left|Right)", "Left", "Right"),
    (r"(left|right)", "left", "right"),
    (r"(LEFT|RIGHT)", "LEFT", "RIGHT"),
    (r"^([LR])(?=[_.\-])", "L", "R"),
    (r"^([lr])(?=[_.\-])", "l", "r"),
)
_WEAK_SIDES: tuple[tuple[str, str, str], ...] = ((r"^([LR])(?=[A-Z0-9])", "L", "R"),)

# Candidate reflections D: sign vectors (D = diag(s)) and the unit quaternion d of -D.
_REFLECTION_NAMES = ("-I", "x", "y", "z")
REFLECTION_SIGNS = np.array(
    [[-1.0, -1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, -1.0, 1.0], [1.0, 1.0, -1.0]]
)
REFLECTION_QUATS = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)
_WORLD = 1  # the world mirror M = diag(-1, 1, 1)
_TIE = 0.05  # relative offset error under which two reflections count as equally good


def _swap_side(name: str, patterns: tuple[tuple[str, str, str], ...]) -> list[str]:
    out = []
    for pattern, left, right in patterns:
        swapped = re.sub(
            pattern,
            lambda m, left=left, right=right: right if m.group(1) == left else left,
            name,
        )
        if swapped != name:
            out.append(swapped)
    return out


def _pair_joints(skeleton: Skeleton, pairs: Mapping[str, str] | None) -> np.ndarray:
    names = skeleton.names
    where = {n: i for i, n in enumerate(names)}
    sigma = np.arange(len(names))
    if pairs is not None:
        for a, b in pairs.items():
            for x in (a, b):
                if x not in where:
                    raise RigError(
                        f"mirror pair {a!r} <-> {b!r} names {x!r}, which is not in the rig"
                    )
            sigma[where[a]], sigma[where[b]] = where[b], where[a]
    else:
        unpaired = []
        for j, name in enumerate(names):
            strong = _swap_side(name, _STRONG_SIDES)
            found = [c for c in strong + _swap_side(name, _WEAK_SIDES) if c in where]
            if found:
                sigma[j] = where[found[0]]
            elif strong:
                unpaired.append(f"{name} (no {strong[0]})")
        if unpaired:
            raise RigError(
                f"cannot mirror: sided joints without a counterpart: {', '.join(unpaired)}; "
                "pass pairs={'LeftName': 'RightName', ...} to mirror()"
            )
    bad = [names[j] for j in range(len(names)) if sigma[sigma[j]] != j]
    if bad:
        raise RigError(
            f"cannot mirror: left/right pairing is not one-to-one at {bad}; "
            "pass explicit pairs={'LeftName': 'RightName', ...}"
        )
    parents = skeleton.parents
    mapped = np.where(parents >= 0, sigma[np.maximum(parents, 0)], -1)
    bad = [names[j] for j in range(len(names)) if parents[sigma[j]] != mapped[j]]
    if bad:
        raise RigError(
            f"cannot mirror: joints {bad} and their mirror counterparts hang from joints that "
            "are not mirror images of each other; fix the pairs or the hierarchy"
        )
    return sigma


def _pair_end_sites(skeleton: Skeleton, sigma: np.ndarray) -> np.ndarray:
    esp = skeleton.end_site_parents
    # The k-th end site of joint j pairs with the k-th end site of sigma(j).
    rank = np.zeros(len(esp), dtype=np.int64)
    slot: dict[tuple[int, int], int] = {}
    for e, p in enumerate(esp):
        rank[e] = sum(1 for q in esp[:e] if q == p)
        slot[(int(p), int(rank[e]))] = e
    out = np.empty(len(esp), dtype=np.int64)
    for e, p in enumerate(esp):
        key = (int(sigma[p]), int(rank[e]))
        if key not in slot:
            raise RigError(
                f"cannot mirror: joint {skeleton.names[p]!r} has more end sites than "
                f"{skeleton.names[sigma[p]]!r}; give mirror images the same end sites"
            )
        out[e] = slot[key]
    return out


@dataclass(frozen=True)
class MirrorMap:
    """How a rig maps onto its mirror image (see the module docstring for the math).

    Attributes:
        pairs: ``(J,)`` index of each joint's mirror counterpart (itself on the midline).
        end_site_pairs: ``(E,)`` the same for end sites.
        reflections: ``(J,)`` index into ``("-I", "x", "y", "z")``: the local reflection ``D_j``
            (point reflection, or the plane normal to that local axis).
    """

    pairs: np.ndarray
    end_site_pairs: np.ndarray
    reflections: np.ndarray

    @property
    def reflection_names(self) -> tuple[str, ...]:
        """``(J,)`` reflection of every joint as ``"-I"``, ``"x"``, ``"y"`` or ``"z"``."""
        return tuple(_REFLECTION_NAMES[r] for r in self.reflections)


def mirror_map(skeleton: Skeleton, pairs: Mapping[str, str] | None = None) -> MirrorMap:
    """Pair left and right joints and pick each joint's local reflection.

    Joints pair by name: ``_L``/``_R`` (also ``.L``, ``-L``, lower case), ``Left``/``Right``
    anywhere in the name (also ``left``, ``LEFT``), and ``L``/``R`` prefixes (``L_Hip``,
    ``LThigh``). The reflection rule is the module docstring's.

    Args:
        skeleton: the rig, ``J`` joints and ``E`` end sites.
        pairs: explicit ``{left name: right name}`` pairs instead of the name patterns;
            joints not named are on the midline.

    Raises:
        RigError: a sided joint has no counterpart, the pairing is not one-to-one, or mirror
            images hang from joints that are not mirror images.
    """
    sigma = _pair_joints(skeleton, pairs)
    end_sigma = _pair_end_sites(skeleton, sigma)
    n = skeleton.num_joints
    # Children of every joint as (own offset, counterpart's offset) pairs, end sites included.
    kids: list[list[tuple[np.ndarray, np.ndarray]]] = [[] for _ in range(n)]
    for j in range(n):
        p = skeleton.parents[j]
        if p >= 0:
            kids[p].append((skeleton.offsets[j], skeleton.offsets[sigma[j]]))
    for e, p in enumerate(skeleton.end_site_parents):
        kids[p].append((skeleton.end_site_offsets[e], skeleton.end_site_offsets[end_sigma[e]]))
    reflections = np.empty(n, dtype=np.int64)
    for j in range(n):
        p = skeleton.parents[j]
        inherited = _WORLD if p < 0 else int(reflections[p])
        if not skeleton.rotation_order(j) or not kids[j]:
            # No rotation channel to absorb a change of frame, or nothing to tell frames apart.
            reflections[j] = inherited
            continue
        own = np.stack([k[0] for k in kids[j]])
        other = np.stack([k[1] for k in kids[j]])
        scale = np.maximum(np.linalg.norm(own, axis=-1), np.linalg.norm(other, axis=-1))
        err = np.linalg.norm(REFLECTION_SIGNS[:, None] * other - own, axis=-1)
        err = np.where(scale > 0, err / np.where(scale > 0, scale, 1.0), 0.0).max(axis=1)
        tied = np.flatnonzero(err <= err.min() + _TIE)
        reflections[j] = inherited if inherited in tied else (0 if 0 in tied else tied[0])
    return MirrorMap(sigma, end_sigma, reflections)


def parent_reflections(skeleton: Skeleton, mm: MirrorMap) -> np.ndarray:
    """``(J,)`` reflection index of each joint's parent, the world mirror for roots."""
    parents = skeleton.parents
    return np.where(parents >= 0, mm.reflections[np.maximum(parents, 0)], _WORLD)


def mirror_skeleton(skeleton: Skeleton, mm: MirrorMap | None = None) -> Skeleton:
    """The rig whose rest offsets are the mirror images of ``skeleton``'s.

    Offsets become ``D_parent * offsets[pair]`` (module docstring). On a left/right symmetric
    rig this is the same rig.

    Args:
        skeleton: the rig, offsets ``(J, 3)`` and end-site offsets ``(E, 3)``.
        mm: its :func:`mirror_map` (computed when ``None``).
    """
    mm = mirror_map(skeleton) if mm is None else mm
    signs = REFLECTION_SIGNS[parent_reflections(skeleton, mm)]
    end_signs = REFLECTION_SIGNS[mm.reflections[skeleton.end_site_parents]]
    return Skeleton(
        skeleton.names,
        skeleton.parents,
        signs * skeleton.offsets[mm.pairs],
        skeleton.channels,
        skeleton.end_site_parents,
        end_signs * skeleton.end_site_offsets[mm.end_site_pairs],
    )
