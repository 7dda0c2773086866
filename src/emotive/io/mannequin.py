"""A procedural mannequin fitted to any humanoid skeleton, rigidly skinned to its joints.

The body is read from the skeleton's geometry in one pose (the bind pose, world space,
metres, Y up), not from joint names, so any rig gets one:

- the *pelvis* is the first joint from which at least two subtrees hang down (the legs) and
  one rises (the spine); the bones above it (a placement root such as Bandai Namco's
  ``joint_Root`` with its metres-long offset, or Unreal's ground ``root`` and its IK helpers)
  get no geometry;
- the *spine chain* climbs from the pelvis towards the highest joint, and stops at the head
  (the top, or a joint whose children are two or more leaves: eyes, a jaw); the chain joint
  whose side branches hold the most joints is the *shoulder joint*, and those branches are the
  arms;
- along each leg and arm the long bones are counted from the body outwards: the first is the
  thigh or upper arm, the second the shin or forearm, the rest foot or hand (fingers and toes
  included); a short bone beside a long one (a twist or helper bone) and what hangs from it
  get no geometry of their own.

Each bone becomes a tapered capsule (an elliptical cross-section for the torso, feet and
hands) whose radii scale with the figure's size (:data:`FIGURE_PER_LEG` times the pelvis's
height above the lowest foot joint), and the head an ellipsoid above the neck; a hand or foot
that ends in a zero-length end site is extended along its last bone. Zero-length bones and
bones longer than :data:`MAX_BONE` figure sizes are skipped. Every vertex follows exactly one
joint (weight 1), the joint at the bone's start.

Legend: ``J`` joints, ``E`` end sites, ``V`` vertices, ``F`` triangles.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from emotive.core.skeleton import Skeleton

#: Linear RGBA base colour of the mannequin (a light clay).
COLOR = (0.72, 0.52, 0.38, 1.0)

#: Joint height (lowest foot joint to the head joint) per height of the pelvis above the
#: lowest foot joint, as on the Bandai Namco actors; every size below is in joint heights.
FIGURE_PER_LEG = 1.53

#: Bones longer than this many figure sizes get no geometry (placement offsets).
MAX_BONE = 0.6

#: Bones shorter than this many figure sizes get no geometry.
MIN_BONE = 0.01

#: Long-bone thresholds in figure sizes: legs, arms.
LONG_LEG = 0.18
LONG_ARM = 0.12

#: Vertices around each capsule and rings on each rounded end.
SEGMENTS = 12
CAP_RINGS = 3

#: Each body part: radius at the bone's start and end (figure sizes), the axial extent of
#: the rounded ends (in radii), and the cross-section's lateral and depth factors.
PARTS: dict[str, tuple[float, float, float, float, float, float]] = {
    "torso": (0.066, 0.076, 0.9, 0.9, 1.3, 1.0),
    "upper_chest": (0.076, 0.055, 0.9, 0.6, 1.3, 1.0),
    "pelvis": (0.06, 0.06, 1.0, 1.0, 1.0, 1.0),
    "neck": (0.03, 0.03, 1.0, 1.0, 1.0, 1.0),
    "head": (0.075, 0.075, 1.0, 1.15, 0.85, 0.95),
    "clavicle": (0.035, 0.033, 1.0, 1.0, 1.0, 1.0),
    "upper_arm": (0.033, 0.027, 1.0, 1.0, 1.0, 1.0),
    "forearm": (0.027, 0.02, 1.0, 1.0, 1.0, 1.0),
    "hand": (0.022, 0.02, 1.0, 1.0, 0.7, 1.2),
    "thigh": (0.05, 0.037, 1.0, 1.0, 1.0, 1.0),
    "shin": (0.037, 0.026, 1.0, 1.0, 1.0, 1.0),
    "foot": (0.028, 0.026, 1.0, 1.0, 1.3, 0.85),
    "other": (0.02, 0.02, 1.0, 1.0, 1.0, 1.0),
}

#: Parts whose radius is at most this fraction of the bone's length (fingers, small helpers).
THIN_PARTS = {"hand": 0.4, "other": 0.25}

#: Length of a hand or toe added past a zero-length end, in figure sizes (at most the
#: length of the bone before it).
EXTENSION = {"hand": 0.07, "foot": 0.035}

#: A bone from the head's joint (or to a leaf at the top of the spine) at least this many head
#: radii long reaches the top of the skull: the head ellipsoid spans it.
SKULL_TOP = 1.2

_UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Mesh:
    """A triangle mesh rigidly skinned to a skeleton's joints.

    Attributes:
        positions: ``(V, 3)`` vertex positions in the bind pose, world space, metres.
        normals: ``(V, 3)`` unit outward normals.
        joints: ``(V,)`` index of the joint each vertex follows with weight 1.
        triangles: ``(F, 3)`` vertex indices, counter-clockwise seen from outside.
        color: linear RGBA base colour.
    """

    positions: np.ndarray
    normals: np.ndarray
    joints: np.ndarray
    triangles: np.ndarray
    color: tuple[float, float, float, float] = COLOR


@dataclass(frozen=True)
class _Part:
    """One capsule: ``start + axis * length`` is its end; radii in metres."""

    joint: int
    start: np.ndarray
    axis: np.ndarray
    length: float
    kind: str
    radii: tuple[float, float]


class _Body:
    """The skeleton's points (joints then end sites) in the bind pose, and its anatomy."""

    def __init__(self, skeleton: Skeleton, points: np.ndarray) -> None:
        self.n = skeleton.num_joints
        self.points = points
        self.parent = np.concatenate((skeleton.parents, skeleton.end_site_parents))
        self.kids: list[list[int]] = [[] for _ in range(len(points))]
        for q, p in enumerate(self.parent):
            if p >= 0:
                self.kids[p].append(q)
        self.pelvis = self._pelvis()
        self.legs, self.spine = self._hips_children()
        self.size = self._size()
        self.chain = self._chain()
        self.shoulder = self._shoulder()
        self.lateral = self._lateral()

    def _size(self) -> float:
        """The figure's joint height (metres): from the pelvis height, else the joints' extent."""
        y = self.points[:, 1]
        feet = [q for leg in self.legs for q in self.subtree(leg) if q < self.n]
        size = FIGURE_PER_LEG * float(y[self.pelvis] - y[feet].min()) if feet else 0.0
        if size <= 1e-6:
            joints = [q for q in self.subtree(self.pelvis) if q < self.n]
            size = float(np.ptp(self.points[joints], axis=0).max()) if len(joints) > 1 else 0.0
        return size if size > 1e-6 else 1.0

    def joint_kids(self, q: int) -> list[int]:
        """Child joints (not end sites) of point ``q``."""
        return [k for k in self.kids[q] if k < self.n]

    def subtree(self, q: int) -> list[int]:
        """Point ``q`` and every point below it."""
        out, todo = [], [q]
        while todo:
            r = todo.pop()
            out.append(r)
            todo.extend(self.kids[r])
        return out

    def length(self, p: int, q: int) -> float:
        """Length of the bone from point ``p`` to point ``q``, metres."""
        return float(np.linalg.norm(self.points[q] - self.points[p]))

    def _below(self, j: int, k: int) -> bool:
        """Whether the subtree of ``k`` hangs below joint ``j`` (on average)."""
        return float(self.points[self.subtree(k), 1].mean()) < float(self.points[j, 1])

    def _pelvis(self) -> int:
        branching = [j for j in range(self.n) if len(self.joint_kids(j)) >= 2]
        for j in branching:
            down = [k for k in self.joint_kids(j) if self._below(j, k)]
            if len(down) >= 2 and len(down) < len(self.joint_kids(j)):
                return j
        return branching[0] if branching else 0

    def _hips_children(self) -> tuple[list[int], int | None]:
        kids = self.joint_kids(self.pelvis)
        legs = [k for k in kids if self._below(self.pelvis, k)]
        rest = [k for k in kids if k not in legs]
        spine = max(rest, key=lambda k: self.points[self.subtree(k), 1].max(), default=None)
        return legs, spine

    def _chain(self) -> list[int]:
        """Joints from the pelvis up the spine to the head.

        Each step goes to the child whose subtree holds the highest joint, and the climb stops
        at a joint whose children are two or more leaves (eyes, a jaw): the head.
        """
        chain = [self.pelvis]
        q = self.spine
        while q is not None:
            chain.append(q)
            kids = self.joint_kids(q)
            if len(kids) >= 2 and not any(self.joint_kids(k) for k in kids):
                break
            q = max(kids, key=lambda k: self.points[[r for r in self.subtree(k) if r < self.n],
                                                    1].max(), default=None)
        return chain

    def _shoulder(self) -> int | None:
        """The chain joint whose side branches hold the most joints (where the arms start)."""
        on_chain = set(self.chain)
        best, best_count = None, 0
        for j in self.chain[1:]:
            count = sum(len(self.subtree(k)) for k in self.joint_kids(j) if k not in on_chain)
            if count > best_count:
                best, best_count = j, count
        return best

    def arms(self) -> list[int]:
        """First joint of each arm (the shoulder joint's side branches)."""
        if self.shoulder is None:
            return []
        return [k for k in self.joint_kids(self.shoulder) if k not in set(self.chain)]

    def _lateral(self) -> np.ndarray:
        """Unit horizontal left-right direction, from the hip joints or else the shoulders."""
        for start, roots in ((self.pelvis, self.legs), (self.shoulder, self.arms())):
            if start is None or len(roots) < 2:
                continue
            ends = [self._first_away(start, k) for k in roots[:2]]
            side = self.points[ends[0]] - self.points[ends[1]]
            side = side - side @ _UP * _UP
            if np.linalg.norm(side) > 1e-3 * self.size:
                return side / np.linalg.norm(side)
        return np.array([1.0, 0.0, 0.0])

    def _first_away(self, start: int, q: int) -> int:
        """The first point down from ``q`` at a distance from ``start`` (past zero offsets)."""
        while self.length(start, q) < 0.02 * self.size and self.kids[q]:
            q = self.kids[q][0]
        return q


def _limb(body: _Body, first: int, names: tuple[str, str, str, str], long: float) -> list:
    """``(p, q, kind)`` of every bone of a limb, from its base joint to its tips.

    Args:
        body: the analysed skeleton.
        first: the limb's first joint (a child of the pelvis or of the shoulder joint).
        names: parts for a short bone before the first long bone, then for the first, second
            and later long bones.
        long: threshold of a long bone, in figure sizes.
    """
    bones, todo = [], [(first, 0)]
    while todo:
        p, k = todo.pop()
        outgoing = [q for q in body.kids[p] if body.length(p, q) >= MIN_BONE * body.size]
        main = max(outgoing, key=lambda q: body.length(p, q), default=None)
        main_long = main is not None and body.length(p, main) >= long * body.size
        for q in body.kids[p]:
            is_long = body.length(p, q) >= long * body.size
            if main_long and not is_long and q in outgoing:
                continue  # a twist or helper bone inside the long one
            if q in outgoing:
                bones.append((p, q, names[min(k + 1, 3)] if is_long or k else names[0]))
            if q < body.n:
                todo.append((q, k + int(is_long)))
        if not outgoing and not body.joint_kids(p) and k >= 2:
            bones.append((p, None, names[3]))
    return bones


def _bones(body: _Body) -> list[tuple[int, int | None, str]]:
    """``(p, q, kind)`` of every bone that gets geometry; ``q`` is ``None`` for an extension."""
    bones = [(body.pelvis, k, "pelvis") for k in body.legs]
    for leg in body.legs:
        bones += _limb(body, leg, ("pelvis", "thigh", "shin", "foot"), LONG_LEG)
    shoulder = body.shoulder
    for arm in body.arms():
        bones.append((shoulder, arm, "clavicle"))
        bones += _limb(body, arm, ("clavicle", "upper_arm", "forearm", "hand"), LONG_ARM)
    chain = body.chain
    above = chain.index(shoulder) if shoulder is not None else len(chain) - 3
    for i, (p, q) in enumerate(pairwise(chain)):
        bones.append((p, q, "torso" if i < above else "upper_chest" if i == above else "neck"))
    sides = set(body.legs) | set(body.arms()) | set(chain)
    for j in chain[:-1]:
        for q in body.kids[j]:
            if q not in sides and q < body.n:
                bones += [(a, b, "other") for a in body.subtree(q) for b in body.kids[a]]
                bones.append((j, q, "other"))
    return bones


def _head(body: _Body, bones: list) -> _Part:
    """The head ellipsoid, above the highest chain joint or spanning a skull-top bone.

    A skull-top bone ending at the chain's top joint (Mixamo's ``HeadTop_End``) is removed
    from ``bones``: the head covers it.
    """
    r = PARTS["head"][0] * body.size
    top = body.chain[-1]
    below = body.parent[top] if top != body.pelvis else -1
    ends = [q for q in body.kids[top] if body.length(top, q) > SKULL_TOP * r]
    if ends:
        joint, center = top, (body.points[top] + body.points[ends[0]]) / 2
        axis = body.points[ends[0]] - body.points[top]
    elif below >= 0 and body.length(below, top) > SKULL_TOP * r:
        joint, center = below, (body.points[below] + body.points[top]) / 2
        axis = body.points[top] - body.points[below]
        bones[:] = [b for b in bones if b[:2] != (below, top)]
    else:
        axis = body.points[top] - body.points[below] if below >= 0 else _UP
        axis = axis if np.linalg.norm(axis) > 1e-9 else _UP
        joint = top
        center = body.points[top] + 0.8 * r * axis / np.linalg.norm(axis)
    axis = axis / np.linalg.norm(axis)
    return _Part(joint, center, axis, 0.0, "head", (r, r))


def _part(body: _Body, p: int, q: int | None, kind: str) -> _Part | None:
    """The capsule of bone ``p -> q`` (``q=None``: extend ``p``'s incoming bone)."""
    start = body.points[p]
    if q is None:
        incoming = start - body.points[body.parent[p]]
        length = min(EXTENSION[kind] * body.size, float(np.linalg.norm(incoming)))
        if length < MIN_BONE * body.size:
            return None
        axis = incoming / np.linalg.norm(incoming)
    else:
        axis = body.points[q] - start
        length = float(np.linalg.norm(axis))
        if not MIN_BONE * body.size <= length <= MAX_BONE * body.size:
            return None
        axis = axis / length
    r0, r1 = (PARTS[kind][0] * body.size, PARTS[kind][1] * body.size)
    if kind in THIN_PARTS:
        r0, r1 = min(r0, THIN_PARTS[kind] * length), min(r1, THIN_PARTS[kind] * length)
    return _Part(p, start, axis, length, kind, (r0, r1))


def _profile(part: _Part) -> tuple[np.ndarray, np.ndarray]:
    """Rings of a capsule: ``(R, 2)`` (axial, radial) positions and ``(R, 2)`` normals."""
    cap0, cap1 = (PARTS[part.kind][2] * part.radii[0], PARTS[part.kind][3] * part.radii[1])
    theta = np.linspace(-np.pi / 2, 0, CAP_RINGS + 1)[1:]
    start = np.stack((cap0 * np.sin(theta), part.radii[0] * np.cos(theta)), 1)
    start_n = np.stack((np.sin(theta) / max(cap0, 1e-12), np.cos(theta) / part.radii[0]), 1)
    theta = np.linspace(0, np.pi / 2, CAP_RINGS + 1)[:-1]
    if part.length <= 0:
        theta = theta[1:]
    end = np.stack((part.length + cap1 * np.sin(theta), part.radii[1] * np.cos(theta)), 1)
    end_n = np.stack((np.sin(theta) / max(cap1, 1e-12), np.cos(theta) / part.radii[1]), 1)
    rings = np.concatenate((start, end))
    normals = np.concatenate((start_n, end_n))
    poles = np.array([[-cap0, 0.0], [part.length + cap1, 0.0]])
    return np.concatenate((poles[:1], rings, poles[1:])), np.concatenate(
        ([[-1.0, 0.0]], normals / np.linalg.norm(normals, axis=1, keepdims=True), [[1.0, 0.0]]))


def _frame(axis: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit ``(side, depth)`` directions across ``axis``, ``side`` as close to ``lateral``."""
    side = lateral - lateral @ axis * axis
    if np.linalg.norm(side) < 0.1:
        other = _UP if abs(axis @ _UP) < 0.9 else np.array([0.0, 0.0, 1.0])
        side = np.cross(other, axis)
    side = side / np.linalg.norm(side)
    return side, np.cross(axis, side)


def _capsule(part: _Part, lateral: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices ``(V, 3)``, normals ``(V, 3)`` and triangles ``(F, 3)`` of one part."""
    profile, normal = _profile(part)
    _, _, _, _, wide, deep = PARTS[part.kind]
    side, depth = _frame(part.axis, lateral)
    phi = np.linspace(0, 2 * np.pi, SEGMENTS, endpoint=False)
    ring = np.stack((np.cos(phi), np.sin(phi)), 1)
    rings = profile[1:-1]
    cross = rings[:, None, 1:] * ring[None] * (wide, deep)
    verts = (rings[:, None, :1] * part.axis + cross[..., :1] * side + cross[..., 1:] * depth)
    ncross = normal[1:-1, None, 1:] * ring[None] / (wide, deep)
    norms = (normal[1:-1, None, :1] * part.axis + ncross[..., :1] * side
             + ncross[..., 1:] * depth)
    verts = np.concatenate((profile[:1, :1] * part.axis, verts.reshape(-1, 3),
                            profile[-1:, :1] * part.axis)) + part.start
    norms = np.concatenate((-part.axis[None], norms.reshape(-1, 3), part.axis[None]))
    norms = norms / np.linalg.norm(norms, axis=1, keepdims=True)
    return verts, norms, _triangles(len(rings))


def _triangles(rings: int) -> np.ndarray:
    """``(F, 3)`` triangles of a capsule: bottom pole, ``rings`` rings, top pole."""
    k = np.arange(SEGMENTS)
    nxt = (k + 1) % SEGMENTS
    top = 1 + rings * SEGMENTS
    tris = [np.stack((np.zeros_like(k), 1 + nxt, 1 + k), 1)]
    for i in range(rings - 1):
        a, b = 1 + i * SEGMENTS, 1 + (i + 1) * SEGMENTS
        tris.append(np.stack((a + k, a + nxt, b + k), 1))
        tris.append(np.stack((a + nxt, b + nxt, b + k), 1))
    last = 1 + (rings - 1) * SEGMENTS
    tris.append(np.stack((last + k, last + nxt, np.full_like(k, top)), 1))
    return np.concatenate(tris)


def fit_mannequin(skeleton: Skeleton, joint_positions: np.ndarray,
                  end_positions: np.ndarray) -> Mesh:
    """A mannequin fitted to a skeleton in one pose (see the module docstring).

    Args:
        skeleton: the rig.
        joint_positions: ``(J, 3)`` world joint positions of the bind pose, metres, Y up.
        end_positions: ``(E, 3)`` world end-site positions of the same pose.

    Returns:
        The mesh, in the same world space, each vertex bound to one joint; empty for a rig
        with no bone to dress (a single joint, zero-length bones only).
    """
    points = np.concatenate((np.asarray(joint_positions, dtype=np.float64),
                             np.asarray(end_positions, dtype=np.float64).reshape(-1, 3)))
    body = _Body(skeleton, points)
    bones = _bones(body)
    parts = [_head(body, bones)] if len(body.chain) > 1 else []
    parts += [p for p in (_part(body, *bone) for bone in bones) if p is not None]
    verts, norms, tris, joints, base = [np.zeros((0, 3))], [np.zeros((0, 3))], [], [], 0
    tris.append(np.zeros((0, 3), dtype=np.int64))
    joints.append(np.zeros(0, dtype=np.int64))
    for part in parts:
        v, n, t = _capsule(part, body.lateral)
        verts.append(v)
        norms.append(n)
        tris.append(t + base)
        joints.append(np.full(len(v), part.joint))
        base += len(v)
    return Mesh(np.concatenate(verts).astype(np.float32), np.concatenate(norms).astype(np.float32),
                np.concatenate(joints).astype(np.int64), np.concatenate(tris).astype(np.uint32))
