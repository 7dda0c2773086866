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
when the keys are evenly spaced, else 30 fps (:data:`DEFAULT_FPS`). LINEAR channels
interpolate (rotations by slerp), STEP channels hold, CUBICSPLINE channels interpolate their
values linearly (their tangents are not used). A file without animation reads as one frame
of its static pose (a rig to retarget onto).

glTF is in metres, Y up, by the format's definition; quaternions are stored ``x, y, z, w``
and converted to emotive's ``w, x, y, z``. Buffers may be the GLB's binary chunk, base64 data
URIs or ``.bin`` files beside a ``.gltf``.

Legend: ``T`` frames, ``J`` joints, ``N`` nodes, ``K`` keys.
"""

from __future__ import annotations

import base64
import os
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pygltflib as gl

from emotive.core.motion import Motion
from emotive.core.skeleton import POSITION_CHANNELS, Skeleton
from emotive.errors import EmotiveError, MotionFileError
from emotive.io.bvh_limits import UNITS, size_problem, standing_height
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

#: Frame rate of a clip whose keys are not evenly spaced, frames per second.
DEFAULT_FPS = 30.0

#: Key spacings within this fraction of their mean count as evenly spaced.
EVEN_KEYS = 1e-3

#: A joint whose translation moves less than this (metres) over the clip gets no channel.
STILL = 1e-6

#: Extensions that change how buffers or animations are stored, which this reader cannot read.
UNSUPPORTED_EXTENSIONS = ("EXT_meshopt_compression", "KHR_animation_pointer")

_COMPONENT_DTYPES = {gl.BYTE: np.int8, gl.UNSIGNED_BYTE: np.uint8, gl.SHORT: np.int16,
                     gl.UNSIGNED_SHORT: np.uint16, gl.UNSIGNED_INT: np.uint32,
                     gl.FLOAT: np.float32}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
_PATH_WIDTHS = {"translation": 3, "rotation": 4, "scale": 3}
_WXYZ = [3, 0, 1, 2]


class _File:
    """A loaded document, its buffers' bytes and the path errors name."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.doc = _load(path)
        self.buffers: dict[int, bytes] = {}

    def fail(self, problem: str) -> MotionFileError:
        return MotionFileError(self.path, problem)

    def buffer(self, index: int) -> bytes:
        if index not in self.buffers:
            self.buffers[index] = self._read_buffer(index)
        return self.buffers[index]

    def _read_buffer(self, index: int) -> bytes:
        if not 0 <= index < len(self.doc.buffers):
            raise self.fail(f"refers to buffer {index}, which is not there; the file is corrupt")
        uri = self.doc.buffers[index].uri
        if uri is None:
            blob = self.doc.binary_blob() if index == 0 else None
            if blob is None:
                raise self.fail(f"buffer {index} has no data (no uri and no GLB binary chunk); "
                                "the file is corrupt")
            return bytes(blob)
        if uri.startswith("data:"):
            head, _, data = uri.partition(",")
            if not head.endswith(";base64"):
                raise self.fail(f"buffer {index} is a data URI that is not base64; re-export "
                                "the file as .glb")
            try:
                return base64.b64decode(data, validate=True)
            except ValueError:
                raise self.fail(f"buffer {index} holds invalid base64; the file is corrupt") \
                    from None
        target = self.path.parent / unquote(uri)
        try:
            return target.read_bytes()
        except OSError as exc:
            raise self.fail(f"cannot read its buffer file {target} ({exc.strerror or exc}); "
                            "keep the .bin beside the .gltf, or export a .glb") from None

    def accessor(self, index: int, what: str) -> np.ndarray:
        """``(count, width)`` float64 values of an accessor (normalized integers scaled)."""
        doc = self.doc
        if not 0 <= index < len(doc.accessors):
            raise self.fail(f"{what} refers to accessor {index}, which is not there; the file "
                            "is corrupt")
        acc = doc.accessors[index]
        dtype = _COMPONENT_DTYPES.get(acc.componentType)
        width = _WIDTHS.get(acc.type)
        if dtype is None or width is None:
            raise self.fail(f"{what} uses an accessor of type {acc.type} with component type "
                            f"{acc.componentType}, which animations do not use; re-export it")
        if acc.sparse is not None:
            raise self.fail(f"{what} uses a sparse accessor, which emotive does not read; "
                            "re-export the file without sparse accessors (e.g. from Blender)")
        count = int(acc.count or 0)
        if acc.bufferView is None:
            values = np.zeros((count, width), dtype=dtype)
        else:
            values = self._view(acc, dtype, width, count, what)
        values = values.astype(np.float64)
        if dtype is not np.float32:
            if not acc.normalized:
                raise self.fail(f"{what} stores integers that are not normalized, which glTF "
                                "does not allow for animation data; re-export it")
            info = np.iinfo(dtype)
            values = np.maximum(values / info.max, -1.0)
        if not np.all(np.isfinite(values)):
            raise self.fail(f"{what} holds values that are not finite numbers; the file is "
                            "corrupt")
        return values

    def _view(self, acc: gl.Accessor, dtype: type, width: int, count: int,
              what: str) -> np.ndarray:
        doc = self.doc
        if not 0 <= acc.bufferView < len(doc.bufferViews):
            raise self.fail(f"{what} refers to buffer view {acc.bufferView}, which is not "
                            "there; the file is corrupt")
        view = doc.bufferViews[acc.bufferView]
        data = self.buffer(view.buffer)
        item = np.dtype(dtype).itemsize
        stride = view.byteStride or item * width
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        end_view = (view.byteOffset or 0) + view.byteLength
        needed = start + (stride * (count - 1) + item * width if count else 0)
        if needed > min(end_view, len(data)) or start < 0:
            raise self.fail(f"{what} reads past the end of its buffer; the file is truncated "
                            "or corrupt")
        if count == 0:
            return np.zeros((0, width), dtype=dtype)
        return np.ndarray((count, width), dtype=np.dtype(dtype).newbyteorder("<"),
                          buffer=data, offset=start, strides=(stride, item)).copy()


def _load(path: Path) -> gl.GLTF2:
    if not path.is_file():
        raise MotionFileError(path, "no such file; check the path")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            doc = gl.GLTF2().load(str(path))
    except Exception as exc:  # pygltflib raises whatever its parsers raise on bad bytes
        raise MotionFileError(path, f"not a readable glTF file ({type(exc).__name__}: {exc}); "
                              "export it again as .glb or .gltf") from None
    if doc is None or not isinstance(doc.nodes, list):
        raise MotionFileError(path, "not a readable glTF file; export it again as .glb")
    required = [e for e in (doc.extensionsRequired or []) if e in UNSUPPORTED_EXTENSIONS]
    if required:
        raise MotionFileError(path, f"needs the glTF extension {required[0]}, which emotive "
                              "does not read; re-export the file without compression")
    return doc


def _parents(file: _File) -> np.ndarray:
    """``(N,)`` each node's parent node, ``-1`` for roots."""
    nodes = file.doc.nodes
    parents = np.full(len(nodes), -1, dtype=np.int64)
    for n, node in enumerate(nodes):
        for c in node.children or []:
            if not 0 <= c < len(nodes) or parents[c] >= 0 or c == n:
                raise file.fail(f"node {n} lists child {c}, which is missing or has another "
                                "parent; the file is corrupt")
            parents[c] = n
    return parents


def _preorder(file: _File, parents: np.ndarray) -> list[int]:
    """Every node, parents before children (depth first, children in file order)."""
    nodes, order = file.doc.nodes, []
    stack = [n for n in range(len(nodes)) if parents[n] < 0][::-1]
    while stack:
        n = stack.pop()
        order.append(n)
        stack.extend(reversed(nodes[n].children or []))
    if len(order) != len(nodes):
        raise file.fail("its node hierarchy has a cycle; the file is corrupt")
    return order


def _joint_nodes(file: _File, parents: np.ndarray, order: list[int],
                 animated: set[int]) -> list[int]:
    """The nodes read as joints, parents first (see the module docstring)."""
    doc = file.doc
    if doc.skins:
        joints = set(doc.skins[0].joints or [])
        if not joints or not joints <= set(range(len(doc.nodes))):
            raise file.fail("its first skin has no joints or names missing nodes; the file is "
                            "corrupt")
    elif animated:
        # The nodes from the top animated node of each tree down to every animated node.
        tops = {n for n in animated if not _ancestors(n, parents) & animated}
        joints = set()
        for n in animated:
            chain = [n, *_ancestor_list(n, parents)]
            top = next(i for i, a in enumerate(chain) if a in tops)
            joints.update(chain[:top + 1])
        for n in order:
            node = doc.nodes[n]
            if (parents[n] in joints and node.mesh is None and node.camera is None
                    and node.skin is None):
                joints.add(n)
    else:
        raise file.fail("has no skin and no animation, so it holds no skeleton to read; "
                        "export the character with its armature (skinning on)")
    return [n for n in order if n in joints]


def _ancestor_list(node: int, parents: np.ndarray) -> list[int]:
    out, p = [], int(parents[node])
    while p >= 0:
        out.append(p)
        p = int(parents[p])
    return out


def _ancestors(node: int, parents: np.ndarray) -> set[int]:
    return set(_ancestor_list(node, parents))


def _rest_trs(file: _File, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's rest translation ``(3,)``, rotation ``(4,)`` (``w, x, y, z``) and scale."""
    node = file.doc.nodes[n]
    try:
        if node.matrix is not None and not np.allclose(node.matrix, np.eye(4).reshape(-1)):
            m = np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T
            scale = np.linalg.norm(m[:3, :3], axis=0)
            if np.any(scale <= 0) or np.linalg.det(m[:3, :3]) < 0:
                raise file.fail(f"node {n} ({node.name}) has a degenerate or mirroring matrix; "
                                "apply the transform before exporting")
            return m[:3, 3], matrix_to_quaternion(m[:3, :3] / scale), scale
        t = np.asarray(node.translation if node.translation is not None else [0, 0, 0], float)
        r = np.asarray(node.rotation if node.rotation is not None else [0, 0, 0, 1], float)
        s = np.asarray(node.scale if node.scale is not None else [1, 1, 1], float)
    except (TypeError, ValueError):
        raise file.fail(f"node {n} ({node.name}) has a malformed transform; the file is "
                        "corrupt") from None
    if t.shape != (3,) or r.shape != (4,) or s.shape != (3,) or not (
            np.all(np.isfinite(t)) and np.all(np.isfinite(r)) and np.all(np.isfinite(s))):
        raise file.fail(f"node {n} ({node.name}) has a malformed transform; the file is "
                        "corrupt")
    return t, quaternion_normalize(r[_WXYZ]), s


def _tracks(file: _File) -> dict[tuple[int, str], tuple[np.ndarray, np.ndarray, str]]:
    """``{(node, path): (times (K,), values (K, C), interpolation)}`` of the first animation."""
    doc = file.doc
    if not doc.animations:
        return {}
    anim = doc.animations[0]
    tracks = {}
    for c, channel in enumerate(anim.channels or []):
        target = channel.target
        if target is None or target.node is None or target.path not in _PATH_WIDTHS:
            continue  # morph weights and pointer targets move no joint
        if not 0 <= target.node < len(doc.nodes) or not 0 <= channel.sampler < len(
                anim.samplers or []):
            raise file.fail(f"animation channel {c} targets a missing node or sampler; the "
                            "file is corrupt")
        sampler = anim.samplers[channel.sampler]
        what = f"animation channel {c} ({target.path} of node {target.node})"
        times = file.accessor(sampler.input, what + " key times")
        values = file.accessor(sampler.output, what + " values")
        interpolation = sampler.interpolation or gl.ANIM_LINEAR
        width = _PATH_WIDTHS[target.path]
        keys = len(times)
        if interpolation == gl.ANIM_CUBICSPLINE:
            if len(values) != 3 * keys:
                raise file.fail(f"{what} has {len(values)} values for {keys} cubic keys "
                                f"(needs {3 * keys}); the file is corrupt")
            values = values.reshape(keys, 3, -1)[:, 1]
        elif interpolation not in (gl.ANIM_LINEAR, gl.ANIM_STEP):
            raise file.fail(f"{what} uses interpolation {interpolation!r}; glTF allows "
                            "LINEAR, STEP and CUBICSPLINE")
        if times.shape[1] != 1 or values.shape != (keys, width) or keys == 0:
            raise file.fail(f"{what} has {keys} key times and values of shape "
                            f"{values.shape}; the file is corrupt")
        times = times[:, 0]
        if np.any(np.diff(times) < 0):
            raise file.fail(f"{what} has key times that go backwards; the file is corrupt")
        if target.path == "rotation":
            values = quaternion_normalize(values[:, _WXYZ])
        tracks[(target.node, target.path)] = (times, values, interpolation)
    return tracks


def _frame_rate(tracks: dict, fps: float | None) -> tuple[float, float, int]:
    """``(fps, first key time, frames)`` of the resampled clip."""
    times = np.unique(np.concatenate([t for t, _, _ in tracks.values()]))
    start, end = float(times[0]), float(times[-1])
    if fps is None:
        fps = DEFAULT_FPS
        steps = np.diff(times)
        if len(steps) and steps.mean() > 0 and np.ptp(steps) <= EVEN_KEYS * steps.mean():
            fps = 1.0 / steps.mean()
            if abs(fps - round(fps)) < EVEN_KEYS * fps:
                fps = float(round(fps))
    return fps, start, round((end - start) * fps) + 1


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


def _local_matrices(trs: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """``(T, 4, 4)`` node matrices from translations ``(T, 3)``, rotations and scales."""
    t, r, s = trs
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = quaternion_to_matrix(r) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def _world_matrices(file: _File, nodes: list[int], parents: np.ndarray, order: list[int],
                    tracks: dict, at: np.ndarray | None) -> dict[int, np.ndarray]:
    """``{node: (T, 4, 4)}`` world matrices of ``nodes`` and their ancestors.

    Args:
        file: the document.
        nodes: the nodes wanted.
        parents: ``(N,)`` parent node of each node, ``-1`` for roots.
        order: every node, parents first (:func:`_preorder`).
        tracks: the animation's tracks (:func:`_tracks`).
        at: key times ``(T,)`` to sample the tracks at, or ``None`` for the rest pose (T = 1).
    """
    frames = 1 if at is None else len(at)
    needed = set(nodes)
    for n in nodes:
        needed.update(_ancestor_list(n, parents))
    world: dict[int, np.ndarray] = {}
    for n in (n for n in order if n in needed):
        trs = [np.broadcast_to(v, (frames, len(v))).copy() for v in _rest_trs(file, n)]
        if at is not None:
            for k, path in enumerate(("translation", "rotation", "scale")):
                if (n, path) in tracks:
                    trs[k] = _sample(*tracks[(n, path)], at, rotation=path == "rotation")
        local = _local_matrices(tuple(trs))
        p = int(parents[n])
        world[n] = local if p < 0 else world[p] @ local
    return world


def _split(file: _File, joints: list[int], joint_parents: np.ndarray,
           world: dict[int, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``(T, J, 4)`` and translations ``(T, J, 3)`` of the world matrices."""
    mats = np.stack([world[n] for n in joints], axis=1)
    linear = mats[..., :3, :3]
    scale = np.linalg.norm(linear, axis=-2)
    if np.any(scale < 1e-12) or np.any(np.linalg.det(linear) < 0):
        bad = joints[int(np.argwhere((scale < 1e-12).any(-1) | (np.linalg.det(linear) < 0))[0, 1])]
        raise file.fail(f"node {bad} ({file.doc.nodes[bad].name}) has a zero or mirroring "
                        "scale; apply the transforms before exporting")
    grot = quaternion_normalize(matrix_to_quaternion(linear / scale[..., None, :]))
    gpos = mats[..., :3, 3]
    rotations, positions = grot.copy(), gpos.copy()
    child = np.flatnonzero(joint_parents >= 0)
    p = joint_parents[child]
    inv = quaternion_invert(grot[:, p])
    rotations[:, child] = quaternion_multiply(inv, grot[:, child])
    positions[:, child] = quaternion_apply(inv, gpos[:, child] - gpos[:, p])
    return quaternion_normalize(rotations), positions


def _names(file: _File, joints: list[int]) -> tuple[str, ...]:
    """Joint names: the nodes' own, made unique, ``node<N>`` for unnamed nodes."""
    names, seen = [], set()
    for n in joints:
        base = file.doc.nodes[n].name or f"node{n}"
        name, k = base, 1
        while name in seen:
            k += 1
            name = f"{base}.{k}"
        seen.add(name)
        names.append(name)
    return tuple(names)


def read_gltf(path: str | os.PathLike, unit: str = "auto", fps: float | None = None) -> Motion:
    """Read the skeleton and first animation of a glTF 2.0 file into a :class:`Motion`.

    Args:
        path: a ``.glb`` or ``.gltf`` file.
        unit: the file's length unit; ``"auto"`` and ``"m"`` take glTF's metres, another key of
            :data:`emotive.io.bvh_limits.UNITS` rescales a file exported in that unit.
        fps: frame rate to resample at; ``None`` keeps evenly spaced keys' own rate, else 30.

    Returns:
        The motion (metres, Y up), ``metadata`` holding ``name``, ``source``, ``file_unit``
        and ``height_m``.

    Raises:
        MotionFileError: the file is missing, corrupt, has no skin and no animation, uses a
            sparse or non-float accessor, a compression extension or a mirroring scale.
    """
    path = Path(path)
    file = _File(path)
    if unit != "auto" and unit not in UNITS:
        raise MotionFileError(path, f"unknown --unit {unit!r}; use auto or one of "
                              f"{', '.join(UNITS)}")
    try:
        return _read(file, unit, fps)
    except (TypeError, ValueError, KeyError, IndexError, AttributeError) as exc:
        # A field of the wrong JSON type (a string for an index, a list for a number).
        raise file.fail(f"holds a malformed field ({type(exc).__name__}: {exc}); the file is "
                        "corrupt, export it again") from None


def _read(file: _File, unit: str, fps: float | None) -> Motion:
    """The body of :func:`read_gltf`."""
    path = file.path
    parents = _parents(file)
    order = _preorder(file, parents)
    tracks = _tracks(file)
    joints = _joint_nodes(file, parents, order, {n for n, _ in tracks})
    position = {n: i for i, n in enumerate(joints)}
    joint_parents = np.array([next((position[a] for a in _ancestor_list(n, parents)
                                    if a in position), -1) for n in joints], dtype=np.int64)
    if tracks and any(n in position for n, _ in tracks):
        fps, start, frames = _frame_rate({k: v for k, v in tracks.items() if k[0] in position},
                                         fps)
        problem = size_problem(frames, 6 * len(joints), len(joints))
        if problem:
            raise file.fail(problem)
        at = start + np.arange(frames) / fps
    else:
        fps, at = fps or DEFAULT_FPS, None
    scale = UNITS["m" if unit == "auto" else unit]
    _, rest_pos = _split(file, joints, joint_parents,
                                _world_matrices(file, joints, parents, order, tracks, None))
    rotations, positions = _split(file, joints, joint_parents,
                                  _world_matrices(file, joints, parents, order, tracks, at))
    # A joint whose translation leaves its rest offset (a track, a scaled or moving parent
    # node) keeps position channels, so a BVH written from the clip keeps it too.
    moving = np.abs(positions - rest_pos[0]).max(axis=(0, 2)) * scale > STILL
    rotating = ("Zrotation", "Xrotation", "Yrotation")
    channels = tuple((*POSITION_CHANNELS, *rotating) if joint_parents[j] < 0 or moving[j]
                     else rotating for j in range(len(joints)))
    try:
        skeleton = Skeleton(_names(file, joints), joint_parents, rest_pos[0] * scale, channels)
        motion = Motion(skeleton, rotations, positions * scale, fps)
    except EmotiveError as exc:
        raise file.fail(f"its skeleton cannot be read: {exc}") from None
    return motion.replace(metadata={
        "name": path.stem, "source": str(path), "file_unit": "m" if unit == "auto" else unit,
        "height_m": standing_height(skeleton)})
