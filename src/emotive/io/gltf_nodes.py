"""A glTF document's node tree and the joints read from it, in time linear in its size.

:func:`node_tree` checks every node's ``children`` once (each child has one parent, none is
its own ancestor) and orders the nodes parents first with an explicit stack, refusing more
than ``MAX_NODES`` nodes or nesting deeper than ``MAX_DEPTH``. :func:`skeleton_plan` picks the
joints (the first skin's, else the animated nodes' chains, see
:mod:`emotive.io.gltf_read`), each joint's parent joint and the nodes whose transforms reach
the joints (the joints and their ancestors), each in one pass over that order: no node's
ancestors are ever listed, so a chain of ``N`` nodes costs ``O(N)``, not ``O(N^2)``.
:func:`rest_transforms` reads nodes' rest ``translation``/``rotation``/``scale`` or
``matrix``: finite numbers, a non-zero quaternion, an affine matrix without a mirror.

Legend: ``N`` nodes, ``J`` joints.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.io import input_limits
from emotive.io.gltf_document import CORRUPT, Document
from emotive.transforms.np_rotations import matrix_to_quaternion, quaternion_normalize

_WXYZ = [3, 0, 1, 2]
_IDENTITY = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]


@dataclass(frozen=True)
class NodeTree:
    """The node hierarchy.

    Attributes:
        nodes: the ``N`` node objects.
        parents: ``(N,)`` each node's parent node, ``-1`` for roots.
        order: ``(N,)`` every node, parents before children (depth first, children in file
            order).
    """

    nodes: list
    parents: np.ndarray
    order: np.ndarray


@dataclass(frozen=True)
class SkeletonPlan:
    """The joints of a node tree and the nodes that place them.

    Attributes:
        joints: ``(J,)`` the joints' nodes, parents first.
        joint_parents: ``(J,)`` each joint's parent joint (its nearest ancestor among the
            joints), ``-1`` for roots.
        needed: ``(N,)`` whether a node is a joint or an ancestor of one.
        children: ``(N,)`` each node's children that are ``needed``.
    """

    joints: np.ndarray
    joint_parents: np.ndarray
    needed: np.ndarray
    children: np.ndarray


def node_tree(doc: Document) -> NodeTree:
    """The document's node hierarchy, checked (see the module docstring).

    Raises:
        MotionFileError: more than ``MAX_NODES`` nodes, a child listed twice, missing, its
            own ancestor (a cycle) or nested deeper than ``MAX_DEPTH``.
    """
    nodes = doc.array("nodes")
    n_nodes = len(nodes)
    parents = [-1] * n_nodes
    kids: list[list[int]] = []
    for n, node in enumerate(nodes):
        where = f"nodes[{n}]"
        listed = doc.indices(doc.obj(node, where), "children", where)
        mine = []
        for k, child in enumerate(listed):
            c = doc.index(child, f"{where}.children[{k}]", n_nodes, "nodes")
            if parents[c] >= 0 or c == n:
                other = "itself" if c == n else f"nodes[{parents[c]}]"
                raise doc.fail(f"{where}.children[{k}]", f"lists node {c}, which is already "
                               f"a child of {other}; {CORRUPT}")
            parents[c] = n
            mine.append(c)
        kids.append(mine)
    order: list[int] = []
    depth = [1] * n_nodes
    stack = [n for n in range(n_nodes - 1, -1, -1) if parents[n] < 0]
    most = input_limits.MAX_DEPTH
    while stack:
        n = stack.pop()
        order.append(n)
        below = kids[n]
        if below:
            if depth[n] >= most:
                raise doc.fail(f"nodes[{below[0]}]", f"is nested {depth[n] + 1:,} nodes deep: "
                               f"at most {most:,} levels are read; apply the helper nodes' "
                               "transforms or simplify the hierarchy")
            for c in below:
                depth[c] = depth[n] + 1
            stack.extend(reversed(below))
    if len(order) != n_nodes:
        seen = set(order)
        first = next(n for n in range(n_nodes) if n not in seen)
        raise doc.fail(f"nodes[{first}]", "is in a cycle of the node hierarchy (it is its own "
                       f"ancestor); {CORRUPT}")
    return NodeTree(nodes, np.array(parents, dtype=np.int64), np.array(order, dtype=np.int64))


def _skin_joints(doc: Document, tree: NodeTree) -> np.ndarray:
    """``(N,)`` mask of the first skin's joints."""
    where, skin = doc.entry("skins", 0, "skins[0]")
    listed = doc.indices(skin, "joints", where)
    if len(listed) > input_limits.MAX_JOINTS:
        raise doc.fail(f"{where}.joints", f"lists {len(listed):,} joints: at most "
                       f"{input_limits.MAX_JOINTS:,} are read; split or simplify the rig")
    if not listed:
        raise doc.fail(f"{where}.joints", f"is empty; {CORRUPT}")
    mask = np.zeros(len(tree.nodes), dtype=bool)
    for k, n in enumerate(listed):
        mask[doc.index(n, f"{where}.joints[{k}]", len(tree.nodes), "nodes")] = True
    return mask


def _animated_joints(doc: Document, tree: NodeTree, animated: np.ndarray) -> np.ndarray:
    """``(N,)`` mask of the joints of a file without skin.

    Each animated node and the nodes from it up to the top animated node of its tree, then
    their plain child nodes (no mesh, camera or skin).
    """
    parents, order = tree.parents, tree.order
    has_parent = parents >= 0
    # Whether a node or one of its ancestors is animated (parents first) ...
    under = animated.copy()
    for n in order:
        if has_parent[n] and under[parents[n]]:
            under[n] = True
    # ... and whether a node or one of its descendants is (children first).
    above = animated.copy()
    for n in order[::-1]:
        if above[n] and has_parent[n]:
            above[parents[n]] = True
    joints = under & above
    for n in order:
        node = tree.nodes[n]
        if (has_parent[n] and joints[parents[n]] and node.get("mesh") is None
                and node.get("camera") is None and node.get("skin") is None):
            joints[n] = True
    return joints


def skeleton_plan(doc: Document, tree: NodeTree, animated: np.ndarray) -> SkeletonPlan:
    """The joints of a node tree and the nodes that place them (see :class:`SkeletonPlan`).

    Args:
        doc: the document.
        tree: its node tree.
        animated: ``(N,)`` whether the first animation moves a node.

    Raises:
        MotionFileError: no skin and no animation, an empty first skin or one naming missing
            nodes, or more than ``MAX_JOINTS`` joints.
    """
    if doc.array("skins"):
        is_joint = _skin_joints(doc, tree)
    elif animated.any():
        is_joint = _animated_joints(doc, tree, animated)
    else:
        raise doc.fail("skins", "there is no skin and no animation, so the file holds no "
                       "skeleton to read; export the character with its armature (skinning "
                       "on)")
    joints = tree.order[is_joint[tree.order]]
    if len(joints) > input_limits.MAX_JOINTS:
        raise doc.fail("nodes", f"{len(joints):,} joints: at most {input_limits.MAX_JOINTS:,} "
                       "are read; split or simplify the rig")
    position = np.full(len(tree.nodes), -1, dtype=np.int64)
    position[joints] = np.arange(len(joints))
    # The nearest joint at or above each node, parents first.
    nearest = np.full(len(tree.nodes), -1, dtype=np.int64)
    for n in tree.order:
        p = tree.parents[n]
        nearest[n] = position[n] if is_joint[n] else (nearest[p] if p >= 0 else -1)
    joint_parents = np.array([nearest[tree.parents[n]] if tree.parents[n] >= 0 else -1
                              for n in joints], dtype=np.int64)
    needed = is_joint.copy()
    children = np.zeros(len(tree.nodes), dtype=np.int64)
    for n in tree.order[::-1]:
        p = tree.parents[n]
        if needed[n] and p >= 0:
            needed[p] = True
            children[p] += 1
    return SkeletonPlan(joints, joint_parents, needed, children)


def rest_transforms(doc: Document, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                             np.ndarray]:
    """Rest translations ``(M, 3)``, rotations ``(M, 4)`` (``w, x, y, z``) and scales ``(M, 3)``.

    Of ``M`` nodes, from their ``translation``/``rotation``/``scale`` or ``matrix``.

    Args:
        doc: the document.
        nodes: ``(M,)`` node indices.

    Raises:
        MotionFileError: a field that is not a list of finite numbers of its length, a zero
            quaternion, or a matrix that is not affine, is degenerate or mirrors.
    """
    all_nodes = doc.array("nodes")
    t, r, s = np.zeros((len(nodes), 3)), np.zeros((len(nodes), 4)), np.ones((len(nodes), 3))
    r[:, 0] = 1.0
    turns: list[int] = []
    linears: list[np.ndarray] = []
    for i, n in enumerate(nodes):
        where = f"nodes[{n}]"
        node = all_nodes[n]
        matrix = doc.numbers(node, "matrix", where, 16)
        if matrix is not None and matrix != _IDENTITY:
            m = np.array(matrix).reshape(4, 4).T
            if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
                raise doc.fail(f"{where}.matrix", "is not an affine transform (its last row is "
                               f"not 0 0 0 1); {CORRUPT}")
            scale = np.linalg.norm(m[:3, :3], axis=0)
            if not np.all(scale > 1e-12) or np.linalg.det(m[:3, :3]) < 0:
                raise doc.fail(f"{where}.matrix", "is degenerate or mirrors; apply the "
                               "transform before exporting")
            t[i], s[i] = m[:3, 3], scale
            turns.append(i)
            linears.append(m[:3, :3] / scale)
            continue
        for out, key, width in ((t, "translation", 3), (s, "scale", 3)):
            value = doc.numbers(node, key, where, width)
            if value is not None:
                out[i] = value
        rotation = doc.numbers(node, "rotation", where, 4)
        if rotation is not None:
            if not sum(v * v for v in rotation) > 1e-18:
                raise doc.fail(f"{where}.rotation", "is a zero quaternion, not a rotation; "
                               f"{CORRUPT}")
            r[i] = [rotation[k] for k in _WXYZ]
    if turns:
        r[turns] = matrix_to_quaternion(np.stack(linears))
    return t, quaternion_normalize(r), s


def joint_names(doc: Document, joints: np.ndarray) -> tuple[str, ...]:
    """Joint names: the nodes' own, made unique (``name.2``), ``node<N>`` for unnamed nodes.

    Raises:
        MotionFileError: a name that is not text or is longer than ``MAX_NAME_CHARS``.
    """
    nodes = doc.array("nodes")
    names: list[str] = []
    seen: set[str] = set()
    next_suffix: dict[str, int] = {}
    for n in joints:
        where = f"nodes[{n}]"
        base = doc.string(nodes[n], "name", where) or f"node{n}"
        if len(base) > input_limits.MAX_NAME_CHARS:
            raise doc.fail(f"{where}.name", f"is {len(base):,} characters long: at most "
                           f"{input_limits.MAX_NAME_CHARS} are read; rename the node")
        name, k = base, next_suffix.get(base, 1)
        while name in seen:
            k += 1
            name = f"{base}.{k}"
        next_suffix[base] = k
        seen.add(name)
        names.append(name)
    return tuple(names)
