"""glTF 2.0 output: the skeleton as nodes, the clip as one animation, a skinned mannequin.

A file holds one scene: a node per joint (the joint's name, its translation and rotation in
the bind pose, metres, Y up, +Z forward as in the :class:`~emotive.core.Motion`), and a
``mannequin`` node with the procedural mesh of :mod:`emotive.io.mannequin`, rigidly skinned to
the joints. The bind pose is the clip's first frame (the rest pose of a clip without frames):
many rigs' rest poses do not stand (Bandai Namco's lies along X), and a file whose static
pose stands shows a character in every viewer, animated or not. The skin's inverse bind
matrices invert the world transforms of that pose.

The animation has one ``rotation`` channel per joint with rotation channels (quaternions
``x, y, z, w`` as glTF orders them; emotive stores ``w, x, y, z``), signs made continuous so
linear interpolation takes the short way, and one ``translation`` channel per joint whose
translation changes during the clip (the root's path); LINEAR sampling at the clip's frame
rate, key times ``0 .. (T - 1) / fps`` seconds.

``.glb`` files are binary; ``.gltf`` files are JSON with the buffer embedded as a base64 data
URI, so each output is one file, written atomically (:func:`emotive.io.atomic.atomic_output`).

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``V`` vertices, ``F`` triangles.
"""

from __future__ import annotations

import base64
import os
from pathlib import Path

import numpy as np
import pygltflib as gl

from emotive import __version__
from emotive.core.motion import Motion
from emotive.errors import OutputError
from emotive.io.atomic import atomic_output
from emotive.io.mannequin import Mesh, fit_mannequin
from emotive.transforms.kinematics import forward_kinematics_np
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_continuity,
    quaternion_normalize,
    quaternion_to_matrix,
)

#: Suffixes of glTF files: binary, and JSON with the buffer embedded.
GLTF_SUFFIXES = (".glb", ".gltf")

#: Name of the node that holds the skinned mesh.
MESH_NODE = "mannequin"

#: A translation that moves less than this (metres) over the clip gets no channel.
STILL = 1e-6

_XYZW = [1, 2, 3, 0]


class _Buffer:
    """The one binary buffer of a document: each array gets a buffer view and an accessor."""

    def __init__(self, doc: gl.GLTF2) -> None:
        self.doc = doc
        self.chunks: list[bytes] = []
        self.size = 0

    def add(self, array: np.ndarray, kind: str, component: int, target: int | None = None,
            bounds: bool = False) -> int:
        """Append ``array`` (``(N, ...)``) as one accessor; returns its index.

        Args:
            array: the values, already of the component type's dtype.
            kind: the accessor type (``"SCALAR"``, ``"VEC3"``, ``"MAT4"``, ...).
            component: the glTF component type (``gl.FLOAT``, ...).
            target: the buffer view target for vertex data and indices.
            bounds: store per-component ``min``/``max`` (required for positions and times).
        """
        data = np.ascontiguousarray(array).tobytes()
        self.doc.bufferViews.append(gl.BufferView(buffer=0, byteOffset=self.size,
                                                  byteLength=len(data), target=target))
        flat = array.reshape(len(array), -1)
        accessor = gl.Accessor(bufferView=len(self.doc.bufferViews) - 1, componentType=component,
                               count=len(array), type=kind)
        if bounds:
            accessor.min = flat.min(0).tolist()
            accessor.max = flat.max(0).tolist()
        self.doc.accessors.append(accessor)
        data += b"\0" * (-len(data) % 4)
        self.chunks.append(data)
        self.size += len(data)
        return len(self.doc.accessors) - 1

    def blob(self) -> bytes:
        """The whole buffer."""
        return b"".join(self.chunks)


def bind_pose(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``(J, 4)`` (``w, x, y, z``) and translations ``(J, 3)`` of the bind pose.

    The first frame, or the rest pose (identity rotations, rest offsets) of a clip without
    frames.
    """
    if motion.num_frames:
        return motion.rotations[0], motion.positions[0]
    sk = motion.skeleton
    rotations = np.zeros((sk.num_joints, 4))
    rotations[:, 0] = 1.0
    return rotations, np.array(sk.offsets)


def _bind_world(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World rotations ``(J, 4)``, joint positions ``(J, 3)`` and end sites ``(E, 3)``."""
    sk = motion.skeleton
    rotations, positions = bind_pose(motion)
    grot, gpos = forward_kinematics_np(rotations[None], positions[None], sk.parents)
    p = sk.end_site_parents
    ends = quaternion_apply(grot[0, p], sk.end_site_offsets) + gpos[0, p]
    return grot[0], gpos[0], ends.reshape(-1, 3)


def inverse_bind_matrices(world_rotations: np.ndarray, world_positions: np.ndarray) -> np.ndarray:
    """``(J, 4, 4)`` inverses of the joints' world transforms (row-major, column vectors).

    Args:
        world_rotations: ``(J, 4)`` world rotations ``w, x, y, z``.
        world_positions: ``(J, 3)`` world positions, metres.
    """
    rt = np.swapaxes(quaternion_to_matrix(world_rotations), -1, -2)
    out = np.zeros((len(rt), 4, 4))
    out[:, :3, :3] = rt
    out[:, :3, 3] = -np.einsum("jab,jb->ja", rt, world_positions)
    out[:, 3, 3] = 1.0
    return out


def _nodes(motion: Motion) -> list[gl.Node]:
    sk = motion.skeleton
    rotations, positions = bind_pose(motion)
    rotations = quaternion_normalize(rotations)[:, _XYZW]
    kids = sk.children
    return [gl.Node(name=name, translation=positions[j].tolist(),
                    rotation=rotations[j].tolist(), children=kids[j] or None)
            for j, name in enumerate(sk.names)]


def _animation(motion: Motion, buf: _Buffer) -> gl.Animation | None:
    """One animation over every rotated joint and every moving translation, or ``None``."""
    sk = motion.skeleton
    if motion.num_frames == 0:
        return None
    times = (np.arange(motion.num_frames) / motion.fps).astype(np.float32)
    key_times = buf.add(times, "SCALAR", gl.FLOAT, bounds=True)
    rotations = quaternion_continuity(quaternion_normalize(motion.rotations), dim=0)[..., _XYZW]
    anim = gl.Animation(name=motion.metadata.get("name", "motion"))
    tracks = [(j, "rotation", rotations[:, j], "VEC4") for j in range(sk.num_joints)
              if sk.rotation_order(j)]
    moving = np.ptp(motion.positions, axis=0).max(-1) > STILL
    tracks += [(j, "translation", motion.positions[:, j], "VEC3")
               for j in np.flatnonzero(moving)]
    for joint, target, values, kind in tracks:
        output = buf.add(values.astype(np.float32), kind, gl.FLOAT)
        anim.samplers.append(gl.AnimationSampler(input=key_times, output=output,
                                                 interpolation=gl.ANIM_LINEAR))
        anim.channels.append(gl.AnimationChannel(
            sampler=len(anim.samplers) - 1,
            target=gl.AnimationChannelTarget(node=int(joint), path=target)))
    return anim if anim.channels else None


def _skinned_mesh(mesh: Mesh, num_joints: int, buf: _Buffer) -> gl.Mesh:
    """The mannequin's one primitive (vertices, normals, joints, weights, triangles)."""
    joint_type, joint_dtype = ((gl.UNSIGNED_BYTE, np.uint8) if num_joints <= 256 else
                               (gl.UNSIGNED_SHORT, np.uint16))
    joints = np.zeros((len(mesh.joints), 4), dtype=joint_dtype)
    joints[:, 0] = mesh.joints
    weights = np.zeros((len(mesh.joints), 4), dtype=np.float32)
    weights[:, 0] = 1.0
    index_type, index_dtype = ((gl.UNSIGNED_SHORT, np.uint16) if len(mesh.positions) < 65535
                               else (gl.UNSIGNED_INT, np.uint32))
    attributes = gl.Attributes(
        POSITION=buf.add(mesh.positions.astype(np.float32), "VEC3", gl.FLOAT,
                         gl.ARRAY_BUFFER, bounds=True),
        NORMAL=buf.add(mesh.normals.astype(np.float32), "VEC3", gl.FLOAT, gl.ARRAY_BUFFER),
        JOINTS_0=buf.add(joints, "VEC4", joint_type, gl.ARRAY_BUFFER),
        WEIGHTS_0=buf.add(weights, "VEC4", gl.FLOAT, gl.ARRAY_BUFFER),
    )
    indices = buf.add(mesh.triangles.reshape(-1).astype(index_dtype), "SCALAR", index_type,
                      gl.ELEMENT_ARRAY_BUFFER)
    return gl.Mesh(name=MESH_NODE, primitives=[gl.Primitive(
        attributes=attributes, indices=indices, material=0, mode=gl.TRIANGLES)])


def gltf_document(motion: Motion, mesh: bool = True) -> tuple[gl.GLTF2, bytes]:
    """The glTF document of a motion (see the module docstring) and its binary buffer.

    Args:
        motion: the clip, any rig.
        mesh: add the skinned mannequin (without it, or for a rig with no bone to dress, the
            file holds the skeleton's nodes and the animation only).

    Returns:
        The document, whose one buffer has no ``uri`` yet, and the buffer's bytes.
    """
    sk = motion.skeleton
    doc = gl.GLTF2(asset=gl.Asset(version="2.0", generator=f"emotive {__version__}"))
    buf = _Buffer(doc)
    doc.nodes = _nodes(motion)
    roots = [int(j) for j in np.flatnonzero(sk.parents < 0)]
    doc.scenes = [gl.Scene(nodes=roots)]
    doc.scene = 0
    anim = _animation(motion, buf)
    if anim is not None:
        doc.animations = [anim]
    grot, gpos, ends = _bind_world(motion)
    body = fit_mannequin(sk, gpos, ends) if mesh else None
    if body is not None and len(body.triangles):
        ibm = inverse_bind_matrices(grot, gpos)
        # glTF matrices are column-major: the transpose of a row-major matrix, flattened.
        matrices = np.swapaxes(ibm, 1, 2).reshape(-1, 16).astype(np.float32)
        skin = gl.Skin(name="skeleton", joints=list(range(sk.num_joints)),
                       inverseBindMatrices=buf.add(matrices.reshape(-1, 4, 4), "MAT4",
                                                   gl.FLOAT))
        if len(roots) == 1:
            skin.skeleton = roots[0]
        doc.skins = [skin]
        doc.materials = [gl.Material(name="clay", pbrMetallicRoughness=gl.PbrMetallicRoughness(
            baseColorFactor=list(body.color), metallicFactor=0.0, roughnessFactor=0.8))]
        doc.meshes = [_skinned_mesh(body, sk.num_joints, buf)]
        doc.nodes.append(gl.Node(name=MESH_NODE, mesh=0, skin=0))
        doc.scenes[0].nodes.append(len(doc.nodes) - 1)
    blob = buf.blob()
    doc.buffers = [gl.Buffer(byteLength=len(blob))]
    return doc, blob


def encode_gltf(doc: gl.GLTF2, blob: bytes, binary: bool) -> bytes:
    """The bytes of a ``.glb`` file (``binary``) or of a ``.gltf`` with an embedded buffer."""
    if binary:
        doc.set_binary_blob(blob)
        return b"".join(doc.save_to_bytes())
    doc.buffers[0].uri = ("data:application/octet-stream;base64,"
                          + base64.b64encode(blob).decode("ascii"))
    return doc.gltf_to_json().encode("utf-8")


def write_gltf(motion: Motion, path: str | os.PathLike, mesh: bool = True) -> Path:
    """Write a motion as a glTF 2.0 file, atomically.

    Args:
        motion: the clip, any rig (metres, Y up).
        path: a ``.glb`` (binary) or ``.gltf`` (JSON, buffer embedded) file.
        mesh: add the skinned mannequin.

    Returns:
        ``path``.

    Raises:
        OutputError: ``path`` does not end in ``.glb`` or ``.gltf``, or could not be written
            whole (then it is left as it was).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in GLTF_SUFFIXES:
        raise OutputError(f"{path}: a glTF file must end in .glb or .gltf; rename it, e.g. "
                          f"{path.with_suffix('.glb').name}")
    doc, blob = gltf_document(motion, mesh=mesh)
    data = encode_gltf(doc, blob, binary=suffix == ".glb")
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return path
