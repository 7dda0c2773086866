"""glTF 2.0 input: a skeleton and its animation from a ``.glb`` or ``.gltf`` file.

The joints are the first skin's (every node of a file without skins that an animation channel
moves, with the nodes between them and their plain child nodes, when no skin is there),
ordered parents first. A joint's parent is its nearest ancestor among the joints; nodes
between joints or above the top joint (an armature node, a scene's axis or unit conversion)
are folded into the joints' transforms. Each frame's world transform of every joint is
composed from the nodes' rest ``translation``/``rotation``/``scale`` (or ``matrix``) and the
first animation's ``translation``, ``rotation`` and ``scale`` channels, then split into the
:class:`~emotive.core.Motion`'s local rotations and translations: world joint positions are
kept exactly, scale is baked into the lengths (a non-uniform scale is kept only in the
positions it moves).

The animation is resampled at a fixed rate, key times ``t0 + k / fps``: its own keyframe rate
when the keys are evenly spaced at 1-1000 fps, else 30 fps (:data:`DEFAULT_FPS`). LINEAR
channels interpolate (rotations by slerp), STEP channels hold, CUBICSPLINE channels
interpolate their values linearly (their tangents are not used). A file without animation
reads as one frame of its static pose (a rig to retarget onto).

glTF is in metres, Y up, by the format's definition; quaternions are stored ``x, y, z, w``
and converted to emotive's ``w, x, y, z``. Buffers may be the GLB's binary chunk, base64 data
URIs or files beside a ``.gltf``.

The file is read within the input contract of :mod:`emotive.io.input_limits`: the container
and fields by :mod:`emotive.io.gltf_document`, buffers and accessors by
:mod:`emotive.io.gltf_buffers` (references only inside the file's folder, sizes checked
before any array is made), the node tree by :mod:`emotive.io.gltf_nodes` (linear in its
size); the clip's frames, joints and values, the lengths (``MAX_LENGTH_M``) and the frame rate
are held to the limits BVH files are. The transforms are composed a block of frames at a
time, so the memory they take does not grow with the clip.

Legend: ``T`` frames, ``J`` joints, ``N`` nodes, ``D`` moving nodes, ``K`` keys.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pygltflib as gl

from emotive.core.motion import Motion
from emotive.core.skeleton import POSITION_CHANNELS, Skeleton
from emotive.errors import EmotiveError, MotionFileError
from emotive.io import input_limits
from emotive.io.bvh_limits import UNITS, standing_height
from emotive.io.gltf_buffers import Buffers
from emotive.io.gltf_document import CORRUPT, Document, open_document
from emotive.io.gltf_nodes import (
    NodeTree,
    SkeletonPlan,
    joint_names,
    node_tree,
    rest_transforms,
    skeleton_plan,
)
from emotive.io.input_limits import fps_problem, length_problem, size_problem
from emotive.transforms.np_rotations import (
    matrix_to_quaternion,
    quaternion_apply,
    quaternion_invert,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_slerp,
    quaternion_to_matrix,
)

#: Suffixes of the glTF files :func:`read_gltf` reads.
GLTF_READ_SUFFIXES = (".glb", ".gltf")

#: Frame rate of a clip whose keys are not evenly spaced at 1-1000 fps, frames per second.
DEFAULT_FPS = 30.0

#: Key spacings within this fraction of their mean count as evenly spaced.
EVEN_KEYS = 1e-3

#: A joint whose translation moves less than this (metres) over the clip gets no channel.
STILL = 1e-6

#: Node-frames whose transforms are composed at once (the block's arrays take about 200
#: bytes each: some 50 MB).
BLOCK_NODE_FRAMES = 1 << 18

_PATH_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
_PATHS = ("translation", "rotation", "scale")
_WXYZ = [3, 0, 1, 2]

#: ``{(node, path): (times (K,), values (K, C), interpolation)}`` of the first animation.
Tracks = dict[tuple[int, str], tuple[np.ndarray, np.ndarray, str]]


def _targets(doc: Document) -> list[tuple[int, str, int, str]]:
    """``(node, path, sampler, channel element)`` of the first animation's node channels.

    Morph weights and pointer targets move no node and are left out.
    """
    animations = doc.array("animations")
    if not animations:
        return []
    anim = doc.obj(animations[0], "animations[0]")
    channels = doc.indices(anim, "channels", "animations[0]")
    if len(channels) > input_limits.MAX_NODES:
        raise doc.fail("animations[0].channels", f"holds {len(channels):,} channels: at most "
                       f"{input_limits.MAX_NODES:,} are read; simplify the animation")
    n_nodes = len(doc.array("nodes"))
    out = []
    for c, channel in enumerate(channels):
        where = f"animations[0].channels[{c}]"
        channel = doc.obj(channel, where)
        target = doc.obj(channel.get("target"), f"{where}.target")
        path = doc.string(target, "path", f"{where}.target")
        if target.get("node") is None or path not in _PATH_WIDTHS:
            continue
        node = doc.index(target["node"], f"{where}.target.node", n_nodes, "nodes")
        out.append((node, path, channel.get("sampler"), where))
    return out


def _tracks(doc: Document, buffers: Buffers, targets: list, wanted: np.ndarray) -> Tracks:
    """The tracks of the channels whose node is ``wanted`` (``(N,)`` mask)."""
    if not targets:
        return {}
    samplers = doc.indices(doc.obj(doc.array("animations")[0], "animations[0]"), "samplers",
                           "animations[0]")
    tracks: Tracks = {}
    for node, path, sampler, where in targets:
        if not wanted[node]:
            continue
        s = doc.index(sampler, f"{where}.sampler", len(samplers), "animations[0].samplers")
        swhere = f"animations[0].samplers[{s}]"
        spec = doc.obj(samplers[s], swhere)
        times = buffers.accessor(spec.get("input"), f"{swhere}.input")
        values = buffers.accessor(spec.get("output"), f"{swhere}.output")
        interpolation = doc.string(spec, "interpolation", swhere, gl.ANIM_LINEAR)
        width, keys = _PATH_WIDTHS[path], len(times)
        what = f"{swhere} ({path} of nodes[{node}], {where})"
        if interpolation == gl.ANIM_CUBICSPLINE:
            if len(values) != 3 * keys:
                raise doc.fail(what, f"has {len(values)} values for {keys} cubic keys (needs "
                               f"{3 * keys}); {CORRUPT}")
            values = values.reshape(keys, 3, -1)[:, 1]
        elif interpolation not in (gl.ANIM_LINEAR, gl.ANIM_STEP):
            raise doc.fail(f"{swhere}.interpolation", f"is {interpolation[:40]!r}; glTF allows "
                           "LINEAR, STEP and CUBICSPLINE")
        if times.shape[1] != 1 or values.shape != (keys, width):
            raise doc.fail(what, f"has {keys} key times and values of shape {values.shape}; "
                           f"{CORRUPT}")
        times = times[:, 0]
        if np.any(np.diff(times) < 0):
            raise doc.fail(f"{swhere}.input", f"has key times that go backwards; {CORRUPT}")
        if path == "rotation":
            if not np.all(np.linalg.norm(values, axis=1) > 1e-9):
                raise doc.fail(f"{swhere}.output", "holds a zero quaternion, not a rotation; "
                               f"{CORRUPT}")
            values = quaternion_normalize(values[:, _WXYZ])
        tracks[(node, path)] = (times, values, interpolation)
    return tracks


def _frame_rate(doc: Document, tracks: Tracks, fps: float | None) -> tuple[float, float, int]:
    """``(fps, first key time, frames)`` of the resampled clip."""
    times = np.unique(np.concatenate([t for t, _, _ in tracks.values()]))
    start, end = float(times[0]), float(times[-1])
    if fps is None:
        fps = DEFAULT_FPS
        steps = np.diff(times)
        if len(steps) and steps.mean() > 0 and np.ptp(steps) <= EVEN_KEYS * steps.mean():
            own = 1.0 / steps.mean()
            if abs(own - round(own)) < EVEN_KEYS * own:
                own = float(round(own))
            if fps_problem(own) is None:
                fps = own
    frames = (end - start) * fps
    if not frames < input_limits.MAX_FRAMES:
        raise doc.fail("animations[0]", f"runs {end - start:.4g} s, {frames + 1:.4g} frames at "
                       f"{fps:g} fps: at most {input_limits.MAX_FRAMES:,} frames are read; "
                       "split the clip")
    return fps, start, round(frames) + 1


def _sample(times: np.ndarray, values: np.ndarray, interpolation: str, at: np.ndarray,
            rotation: bool) -> np.ndarray:
    """Values ``(T, C)`` of one track at times ``at`` ``(T,)``, held beyond its ends."""
    if len(times) == 1:
        return np.broadcast_to(values[0], (len(at), values.shape[1])).copy()
    key = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 1)
    if interpolation == gl.ANIM_STEP:
        return values[key]
    lo = np.minimum(key, len(times) - 2)
    span = times[lo + 1] - times[lo]
    u = np.clip((at - times[lo]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    u = np.where(span > 0, u, 1.0)
    a, b = values[lo], values[lo + 1]
    if rotation:
        return quaternion_slerp(a, b, u)
    return a + (b - a) * u[:, None]


def _local_matrices(t: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """``(..., 4, 4)`` node matrices from translations ``(..., 3)``, rotations and scales."""
    m = np.zeros((*t.shape[:-1], 4, 4))
    m[..., :3, :3] = quaternion_to_matrix(r) * s[..., None, :]
    m[..., :3, 3] = t
    m[..., 3, 3] = 1.0
    return m


class _Pose:
    """The joints' world matrices, composed a block of frames at a time.

    Args:
        doc: the document.
        tree: its node tree.
        plan: its joints and the nodes that place them.
    """

    def __init__(self, doc: Document, tree: NodeTree, plan: SkeletonPlan) -> None:
        self.doc, self.tree, self.plan = doc, tree, plan
        #: The nodes that place the joints, parents first, and each one's row in the arrays.
        self.nodes = tree.order[plan.needed[tree.order]]
        self.row = np.full(len(tree.nodes), -1, dtype=np.int64)
        self.row[self.nodes] = np.arange(len(self.nodes))
        self.rest = rest_transforms(doc, self.nodes)
        local = _local_matrices(*self.rest)
        #: ``(M, 4, 4)`` world matrices of the rest pose.
        self.world = local.copy()
        parents = tree.parents
        for i, n in enumerate(self.nodes):
            p = parents[n]
            if p >= 0:
                self.world[i] = self.world[self.row[p]] @ local[i]

    def rest_pose(self) -> np.ndarray:
        """``(1, J, 4, 4)`` world matrices of the joints at rest."""
        return self.world[self.row[self.plan.joints]][None]

    def frames(self, tracks: Tracks, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local rotations ``(T, J, 4)`` and translations ``(T, J, 3)`` at times ``at``.

        Raises:
            MotionFileError: more than ``MAX_MOVING_NODES`` moving nodes, more node-frames
                than ``MAX_VALUES``, or a zero or mirroring scale.
        """
        parents, plan = self.tree.parents, self.plan
        moving = np.zeros(len(self.tree.nodes), dtype=bool)
        moving[[n for n, _ in tracks]] = True
        for n in self.nodes:
            if parents[n] >= 0 and moving[parents[n]]:
                moving[n] = True
        dynamic = self.nodes[moving[self.nodes]]
        _check_moving(self.doc, len(dynamic), len(at))
        sampled = {key: _sample(*track, at, rotation=key[1] == "rotation")
                   for key, track in tracks.items() if moving[key[0]]}
        joints = plan.joints
        column = np.full(len(self.tree.nodes), -1, dtype=np.int64)
        column[joints] = np.arange(len(joints))
        rotations = np.empty((len(at), len(joints), 4))
        positions = np.empty((len(at), len(joints), 3))
        block = max(1, BLOCK_NODE_FRAMES // max(len(dynamic), len(joints), 1))
        rows = self.row[dynamic]
        for start in range(0, len(at), block):
            frames = slice(start, start + block)
            size = len(at[frames])
            trs = [np.broadcast_to(part[rows], (size, *part[rows].shape)).copy()
                   for part in self.rest]
            for d, n in enumerate(dynamic):
                for k, path in enumerate(_PATHS):
                    if (n, path) in sampled:
                        trs[k][:, d] = sampled[(n, path)][frames]
            local = _local_matrices(*trs)
            mats = np.broadcast_to(self.world[self.row[joints]], (size, len(joints), 4, 4)).copy()
            live: dict[int, np.ndarray] = {}
            left = plan.children.copy()
            for d, n in enumerate(dynamic):
                p = parents[n]
                if p < 0:
                    world = local[:, d]
                elif moving[p]:
                    world = live[p] @ local[:, d]
                    left[p] -= 1
                    if left[p] == 0:
                        del live[p]
                else:
                    world = self.world[self.row[p]] @ local[:, d]
                if column[n] >= 0:
                    mats[:, column[n]] = world
                if plan.children[n]:
                    live[n] = world
            rotations[frames], positions[frames] = _split(self.doc, joints, plan.joint_parents,
                                                          mats)
        return rotations, positions


def _check_moving(doc: Document, moving: int, frames: int) -> None:
    """Refuse more moving nodes than ``MAX_MOVING_NODES``, or too many of their values.

    They count 6 values a node and frame against ``MAX_VALUES``, as the joints do: their
    samples are held for the whole clip.
    """
    if moving > input_limits.MAX_MOVING_NODES:
        raise doc.fail("animations[0]", f"moves {moving:,} nodes that place the joints: at "
                       f"most {input_limits.MAX_MOVING_NODES:,} are read; bake the animation "
                       "onto the skeleton")
    if 6 * moving * frames > input_limits.MAX_VALUES:
        raise doc.fail("animations[0]", f"{frames:,} frames x {moving:,} moving nodes x 6 = "
                       f"{6 * moving * frames:,} values: at most {input_limits.MAX_VALUES:,} "
                       "are read; split the clip")


def _split(doc: Document, joints: np.ndarray, joint_parents: np.ndarray,
           mats: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``(T, J, 4)`` and translations ``(T, J, 3)`` of world matrices.

    Args:
        doc: the document (for messages).
        joints: ``(J,)`` the joints' nodes.
        joint_parents: ``(J,)`` each joint's parent joint, ``-1`` for roots.
        mats: ``(T, J, 4, 4)`` the joints' world matrices.
    """
    if not np.all(np.isfinite(mats)):
        bad = joints[int(np.argwhere(~np.isfinite(mats).all((-1, -2)))[0, 1])]
        raise doc.fail(f"nodes[{bad}]", "is placed by transforms that overflow (not finite); "
                       f"{CORRUPT}")
    linear = mats[..., :3, :3]
    scale = np.linalg.norm(linear, axis=-2)
    det = np.linalg.det(linear)
    if np.any(scale < 1e-12) or np.any(det < 0):
        bad = joints[int(np.argwhere((scale < 1e-12).any(-1) | (det < 0))[0, 1])]
        raise doc.fail(f"nodes[{bad}]", "has a zero or mirroring scale; apply the transforms "
                       "before exporting")
    grot = quaternion_normalize(matrix_to_quaternion(linear / scale[..., None, :]))
    gpos = mats[..., :3, 3]
    rotations, positions = grot.copy(), gpos.copy()
    child = np.flatnonzero(joint_parents >= 0)
    p = joint_parents[child]
    inv = quaternion_invert(grot[:, p])
    rotations[:, child] = quaternion_multiply(inv, grot[:, child])
    positions[:, child] = quaternion_apply(inv, gpos[:, child] - gpos[:, p])
    return quaternion_normalize(rotations), positions


def _check_lengths(doc: Document, joints: np.ndarray, lengths: np.ndarray, what: str) -> None:
    """Refuse lengths ``(T, J, 3)`` in metres beyond ``MAX_LENGTH_M`` or not finite.

    The message names the node of the joint that holds the largest.
    """
    problem = length_problem(lengths, what)
    if problem:
        worst = np.nan_to_num(np.abs(lengths), nan=np.inf).max(axis=(0, 2))
        raise doc.fail(f"nodes[{joints[int(np.argmax(worst))]}]", problem)


def read_gltf(path: str | os.PathLike, unit: str = "auto", fps: float | None = None) -> Motion:
    """Read the skeleton and first animation of a glTF 2.0 file into a :class:`Motion`.

    Args:
        path: a ``.glb`` or ``.gltf`` file.
        unit: the file's length unit; ``"auto"`` and ``"m"`` take glTF's metres, another key of
            :data:`emotive.io.bvh_limits.UNITS` rescales a file exported in that unit.
        fps: frame rate to resample at (1-1000); ``None`` keeps evenly spaced keys' own rate,
            else 30.

    Returns:
        The motion (metres, Y up), ``metadata`` holding ``name``, ``source``, ``file_unit``
        and ``height_m``.

    Raises:
        MotionFileError: the file is missing, not a regular file, corrupt, beyond the limits
            of :mod:`emotive.io.input_limits`, refers to a file outside its folder, has no
            skin and no animation, uses a sparse or non-float accessor, a compression
            extension or a mirroring scale. The message names the element and the fix.
    """
    path = Path(path)
    if unit != "auto" and unit not in UNITS:
        raise MotionFileError(path, f"unknown --unit {unit!r}; use auto or one of "
                              f"{', '.join(UNITS)}")
    if fps is not None and fps_problem(fps):
        raise MotionFileError(path, fps_problem(fps))
    with open_document(path) as doc, Buffers(doc) as buffers:
        try:
            return _read(doc, buffers, unit, fps)
        except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
            # A shape no check above foresaw: still one typed line, never a traceback.
            raise MotionFileError(path, f"holds a malformed field ({type(exc).__name__}: "
                                  f"{str(exc)[:120]}); the file is corrupt, export it "
                                  "again") from None


def _read(doc: Document, buffers: Buffers, unit: str, fps: float | None) -> Motion:
    """The body of :func:`read_gltf`."""
    path = doc.path
    tree = node_tree(doc)
    targets = _targets(doc)
    animated = np.zeros(len(tree.nodes), dtype=bool)
    animated[[n for n, _, _, _ in targets]] = True
    plan = skeleton_plan(doc, tree, animated)
    joints = plan.joints
    tracks = _tracks(doc, buffers, targets, plan.needed)
    pose = _Pose(doc, tree, plan)
    is_joint = np.zeros(len(tree.nodes), dtype=bool)
    is_joint[joints] = True
    if any(is_joint[n] for n, _ in tracks):
        fps, start, frames = _frame_rate(doc, {k: v for k, v in tracks.items()
                                               if is_joint[k[0]]}, fps)
        problem = size_problem(frames, 6 * len(joints), len(joints))
        if problem:
            raise doc.fail("animations[0]", problem)
        rotations, positions = pose.frames(tracks, start + np.arange(frames) / fps)
    else:
        fps = fps or DEFAULT_FPS
        rotations, positions = _split(doc, joints, plan.joint_parents, pose.rest_pose())
    scale = UNITS["m" if unit == "auto" else unit]
    _, rest_pos = _split(doc, joints, plan.joint_parents, pose.rest_pose())
    _check_lengths(doc, joints, rest_pos * scale, "joint offsets")
    _check_lengths(doc, joints, positions * scale, "joint translations")
    # A joint whose translation leaves its rest offset (a track, a scaled or moving parent
    # node) keeps position channels, so a BVH written from the clip keeps it too.
    moving = np.abs(positions - rest_pos[0]).max(axis=(0, 2)) * scale > STILL
    rotating = ("Zrotation", "Xrotation", "Yrotation")
    channels = tuple((*POSITION_CHANNELS, *rotating) if plan.joint_parents[j] < 0 or moving[j]
                     else rotating for j in range(len(joints)))
    try:
        skeleton = Skeleton(joint_names(doc, joints), plan.joint_parents, rest_pos[0] * scale,
                            channels)
        motion = Motion(skeleton, rotations, positions * scale, fps)
    except EmotiveError as exc:
        raise MotionFileError(path, f"its skeleton cannot be read: {exc}") from None
    return motion.replace(metadata={
        "name": path.stem, "source": str(path), "file_unit": "m" if unit == "auto" else unit,
        "height_m": standing_height(skeleton)})
