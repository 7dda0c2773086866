"""Joint roles of a humanoid rig from its hierarchy and rest pose alone (names ignored).

The fallback of :func:`emotive.core.roles.resolve_roles` for rigs whose names match no
family. A branch's size is the summed length of its bones; small branches (fingers, twist and
helper bones, eyes) are carried along and never required:

- the pelvis is the first joint below the root where three large branches meet; the two
  smaller ones are the legs, the largest (torso, arms and head) the spine;
- the chest is the first joint up the spine where three large branches meet: the two larger
  are the arms, the smallest the neck and head;
- along a limb (its longest path), the two longest bones are the upper and lower segment: hip
  (shoulder) and knee (elbow) are where they start, ankle (wrist) where the lower one ends,
  and the path's tip is the toe (hand tip);
- left is the side of ``up x forward``, up from the pelvis to the chest and forward from the
  ankles to the toes in the rest pose (+Z when the feet do not say), so telling left from
  right needs a rest pose that stands (T- or A-pose), not one folded along the bone axes.

The two legs (and the two arms) must be of about one length, and the arms clearly shorter
than the legs (a rig with four legs of one length is no humanoid). A rig that does not fit
raises :class:`~emotive.errors.RigError` saying it is not a humanoid and what is missing.
Points are indices into the ``(J + E)`` array of joint then end-site positions.
"""

from __future__ import annotations

import numpy as np

from emotive.core.skeleton import Skeleton
from emotive.errors import RigError

#: A child branch is large when its reach (longest path down, the bone to it included) is at
#: least this fraction of its farthest-reaching sibling's.
_LARGE = 0.1
#: The spine role is the joint nearest this fraction of the way (by bone length) from the
#: pelvis to the chest.
_SPINE_AT = 0.4
#: Arms (upper + lower segment) at least this fraction of the legs' make front legs, not arms.
_ARM_LEG_MAX = 0.85
#: The shorter of two legs (arms) is at least this fraction of the longer one.
_PAIR_MIN = 0.7
#: A leaf at the head's tip whose bone is over this fraction of the neck-and-head chain (and
#: whose end site is shorter than a quarter of it) is a head-top marker, not the head.
_HEAD_TOP = 0.55


class _Tree:
    """The rig as a tree of joints and end sites with rest positions and branch sizes."""

    def __init__(self, skeleton: Skeleton) -> None:
        sk = skeleton
        n, e = sk.num_joints, len(sk.end_site_parents)
        self.num_joints = n
        self.parents = np.concatenate((sk.parents, sk.end_site_parents)).astype(np.int64)
        offsets = np.concatenate((sk.offsets, sk.end_site_offsets))
        # Rest pose: identity rotations, so each joint sits at its ancestors' summed offsets.
        rest = np.zeros((n, 3))
        for j, p in enumerate(sk.parents):
            rest[j] = sk.offsets[j] + (rest[p] if p >= 0 else 0.0)
        ends = rest[sk.end_site_parents] + sk.end_site_offsets if e else np.zeros((0, 3))
        self.pos = np.concatenate((rest, ends))
        self.bone = np.linalg.norm(offsets, axis=1)
        self.bone[: n][sk.parents < 0] = 0.0
        self.kids: list[list[int]] = [[] for _ in range(n + e)]
        for k, p in enumerate(self.parents):
            if p >= 0:
                self.kids[p].append(k)
        # Summed bone length below each point, and the longest path down from it.
        self.size = np.zeros(n + e)
        self.reach = np.zeros(n + e)
        # Children come after their parents (end sites after every joint): sum bottom up.
        for k in range(n + e - 1, -1, -1):
            p = self.parents[k]
            if p >= 0:
                self.size[p] += self.bone[k] + self.size[k]
                self.reach[p] = max(self.reach[p], self.bone[k] + self.reach[k])

    def large(self, k: int) -> list[int]:
        """The children of ``k`` whose branch is large (see :data:`_LARGE`), largest first.

        Large by reach, ordered by size (summed bone length: the torso with its arms outweighs
        a leg, an arm its neck and head).
        """
        reach = {c: self.bone[c] + self.reach[c] for c in self.kids[k]}
        if not reach:
            return []
        top = max(reach.values())
        return sorted((c for c in reach if top > 0 and reach[c] >= _LARGE * top),
                      key=lambda c: -(self.bone[c] + self.size[c]))

    def longest_path(self, k: int) -> list[int]:
        """``k`` and the points down its longest path to a tip."""
        path = [k]
        while self.kids[path[-1]]:
            path.append(max(self.kids[path[-1]], key=lambda c: self.bone[c] + self.reach[c]))
        return path

    def hub(self, start: int) -> int | None:
        """The first point at or below ``start`` (breadth first) with three large branches."""
        queue = [start]
        while queue:
            k = queue.pop(0)
            if len(self.large(k)) >= 3:
                return k
            queue.extend(c for c in self.kids[k] if c < self.num_joints)
        return None


def _limb(tree: _Tree, start: int) -> tuple[int, int, int, int, float]:
    """Upper joint, middle joint, lower joint and tip of a limb, and its two segments' length."""
    path = tree.longest_path(start)
    if len(path) < 3:
        raise RigError("a limb has fewer than two bones")
    bones = [(tree.bone[path[i]], i) for i in range(1, len(path))]
    (_, a), (_, b) = sorted(sorted(bones, reverse=True)[:2], key=lambda x: x[1])
    # Bone i runs from path[i - 1] to path[i].
    upper, middle, lower = path[a - 1], path[b - 1], path[b]
    length = tree.bone[path[a]] + tree.bone[path[b]]
    tip = path[-1]
    if tip >= tree.num_joints and len(path) > b + 1 and tree.bone[tip] < 0.25 * tree.bone[path[-2]]:
        tip = path[-2]  # an end marker joint (LeftToe_End) whose end site adds next to nothing
    return upper, middle, lower, tip, length


def _head(tree: _Tree, start: int) -> tuple[int, int]:
    """Neck and head joints of the chain from the chest's smallest large branch."""
    chain = [k for k in tree.longest_path(start) if k < tree.num_joints]
    # The head is where the jaw and eyes branch off, when they do.
    hub = next((i for i, k in enumerate(chain[1:], 1)
                if sum(c < tree.num_joints for c in tree.kids[k]) >= 2), None)
    if hub is not None:
        return chain[0], chain[hub]
    neck, head = chain[0], chain[-1]
    total = sum(tree.bone[k] for k in chain[1:])
    ends = [c for c in tree.kids[head] if c >= tree.num_joints]
    end_len = max((tree.bone[c] for c in ends), default=0.0)
    if (len(chain) >= 3 and not any(c < tree.num_joints for c in tree.kids[head])
            and tree.bone[head] > _HEAD_TOP * total and end_len < 0.25 * tree.bone[head]):
        head = chain[-2]
    return neck, head


def _sides(tree: _Tree, pelvis: int, chest: int, feet: list[tuple]) -> np.ndarray:
    """``(3,)`` unit vector towards the character's left in the rest pose."""
    up = tree.pos[chest] - tree.pos[pelvis]
    up = up / max(float(np.linalg.norm(up)), 1e-9)
    forward = sum(tree.pos[f[3]] - tree.pos[f[2]] for f in feet)
    forward = forward - up * float(forward @ up)
    if np.linalg.norm(forward) < 1e-3 * max(float(tree.reach[pelvis]), 1e-9):
        forward = np.array([0.0, 0.0, 1.0]) - up * up[2]
    left = np.cross(up, forward)
    return left / max(float(np.linalg.norm(left)), 1e-9)


def _order(tree: _Tree, pair: list[tuple], origin: int, left: np.ndarray, what: str) -> list:
    """The two limbs of ``pair`` ordered left, right."""
    side = [float((tree.pos[limb[0]] - tree.pos[origin]) @ left) for limb in pair]
    scale = max(float(tree.reach[origin]), 1e-9)
    if abs(side[0] - side[1]) < 1e-3 * scale:
        raise RigError(f"cannot tell the left {what} from the right in the rest pose")
    return pair if side[0] > side[1] else pair[::-1]


def _pelvis(tree: _Tree) -> tuple[int, list[int]]:
    """The pelvis and its three large branches, largest first."""
    k = 0
    while True:
        large = tree.large(k)
        if len(large) == 1:
            k = large[0]
            continue
        if len(large) == 3:
            return k, large
        if len(large) < 3:
            raise RigError("it has no joint where two legs and a spine meet")
        raise RigError(f"{len(large)} limbs meet at one joint where a humanoid has two legs "
                       "and a spine")


def topology_roles(skeleton: Skeleton) -> dict[str, int]:
    """Every role of :data:`emotive.core.roles.ROLES` from the rig's shape alone.

    Args:
        skeleton: the rig; its rest pose (offsets, ``(J, 3)`` metres) should stand (T- or
            A-pose) for left and right to be told apart.

    Returns:
        role -> index into the ``(J + E)`` array of joint then end-site positions.

    Raises:
        RigError: "the rig is not a humanoid: ..." naming what is missing or wrong.
    """
    try:
        return _topology_roles(_Tree(skeleton))
    except RigError as exc:
        raise RigError(f"the rig is not a humanoid by its shape: {exc}") from None


def _topology_roles(tree: _Tree) -> dict[str, int]:
    pelvis, (spine_root, *legs) = _pelvis(tree)
    chest = tree.hub(spine_root)
    if chest is None:
        raise RigError("it has no chest where two arms and a neck meet")
    *arms, neck_root = tree.large(chest)[:3]
    legs_ = [_limb(tree, k) for k in legs]
    arms_ = [_limb(tree, k) for k in arms]
    for pair, what in ((legs_, "legs"), (arms_, "arms")):
        short, long_ = sorted(limb[4] for limb in pair)
        if short < _PAIR_MIN * long_:
            raise RigError(f"its two {what} differ in length ({short:.3g} and {long_:.3g})")
    leg_len = min(leg[4] for leg in legs_)
    if max(arm[4] for arm in arms_) >= _ARM_LEG_MAX * leg_len:
        raise RigError("its front limbs are as long as its legs (four legs and no arms)")
    left = _sides(tree, pelvis, chest, legs_)
    (l_leg, r_leg) = _order(tree, legs_, pelvis, left, "leg")
    (l_arm, r_arm) = _order(tree, arms_, chest, left, "arm")
    spine = _spine(tree, _path_between(tree, pelvis, chest))
    neck, head = _head(tree, neck_root)
    roles = {"root": pelvis, "spine": spine, "chest": chest, "neck": neck, "head": head}
    for s, leg, arm in (("l", l_leg, l_arm), ("r", r_leg, r_arm)):
        roles.update({f"{s}_hip": leg[0], f"{s}_knee": leg[1], f"{s}_ankle": leg[2],
                      f"{s}_toe": leg[3], f"{s}_shoulder": arm[0], f"{s}_elbow": arm[1],
                      f"{s}_wrist": arm[2], f"{s}_handtip": arm[3]})
    return roles


def _spine(tree: _Tree, path: list[int]) -> int:
    """The joint between pelvis and chest nearest :data:`_SPINE_AT` of the way up the path."""
    if len(path) < 3:
        return path[-1]
    along = np.cumsum([tree.bone[k] for k in path[1:]])
    share = along[:-1] / max(float(along[-1]), 1e-12)
    return path[1 + int(np.argmin(np.abs(share - _SPINE_AT)))]


def _path_between(tree: _Tree, top: int, bottom: int) -> list[int]:
    """``top``, the joints between, and ``bottom`` (a descendant of ``top``)."""
    path = [bottom]
    while path[-1] != top:
        path.append(int(tree.parents[path[-1]]))
    return path[::-1]
