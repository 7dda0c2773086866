"""glTF files written by emotive, read back with pygltflib and checked against the motion."""

from __future__ import annotations

import numpy as np
import pygltflib as gl
import pytest

from disk_faults import fill_disk
from emotive.core import Motion, Skeleton
from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.errors import OutputError
from emotive.io.bvh import read_bvh
from emotive.io.gltf import MESH_NODE, write_gltf
from emotive.io.mannequin import fit_mannequin
from emotive.io.motion_files import MOTION_SUFFIXES, write_motion
from emotive.models.api import Generated
from emotive.render.outputs import OUT_SUFFIXES, write_generated
from emotive.transforms.np_rotations import euler_to_quaternion, quaternion_to_matrix
from rigs import RIG

_COMPONENTS = {gl.FLOAT: np.float32, gl.UNSIGNED_BYTE: np.uint8, gl.UNSIGNED_SHORT: np.uint16,
               gl.UNSIGNED_INT: np.uint32}
_WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class Read:
    """A glTF file read back: the document, accessor arrays and FK of its own nodes."""

    def __init__(self, path):
        self.doc = gl.GLTF2().load(str(path))
        uri = self.doc.buffers[0].uri
        self.blob = self.doc.binary_blob() if uri is None else \
            self.doc.get_data_from_buffer_uri(uri)

    def array(self, index: int) -> np.ndarray:
        acc = self.doc.accessors[index]
        view = self.doc.bufferViews[acc.bufferView]
        start = (view.byteOffset or 0) + (acc.byteOffset or 0)
        values = np.frombuffer(self.blob, dtype=_COMPONENTS[acc.componentType],
                               count=acc.count * _WIDTH[acc.type], offset=start)
        return values.reshape(acc.count, -1)

    @property
    def joints(self) -> list:
        return [n for n in self.doc.nodes if n.name != MESH_NODE]

    def channel_values(self, path: str) -> dict[int, np.ndarray]:
        anim = self.doc.animations[0]
        return {c.target.node: self.array(anim.samplers[c.sampler].output)
                for c in anim.channels if c.target.path == path}

    def world(self, frame: int) -> np.ndarray:
        """``(J, 4, 4)`` world matrices of the joint nodes at ``frame`` of the animation."""
        rot = self.channel_values("rotation")
        pos = self.channel_values("translation")
        parent = {k: i for i, n in enumerate(self.doc.nodes) for k in (n.children or [])}
        out = np.zeros((len(self.joints), 4, 4))
        for j, node in enumerate(self.joints):
            q = rot[j][frame] if j in rot else np.array(node.rotation)
            t = pos[j][frame] if j in pos else np.array(node.translation)
            local = np.eye(4)
            local[:3, :3] = quaternion_to_matrix(np.asarray(q, dtype=np.float64)[[3, 0, 1, 2]])
            local[:3, 3] = t
            out[j] = out[parent[j]] @ local if j in parent else local
        return out

    def skinned(self, frame: int) -> np.ndarray:
        """``(V, 3)`` mesh vertices skinned at ``frame`` (linear blend, as a viewer does)."""
        prim = self.doc.meshes[0].primitives[0]
        verts = self.array(prim.attributes.POSITION).astype(np.float64)
        joints = self.array(prim.attributes.JOINTS_0).astype(np.int64)
        weights = self.array(prim.attributes.WEIGHTS_0).astype(np.float64)
        ibm = self.ibm()
        skin = self.world(frame) @ ibm
        homo = np.concatenate((verts, np.ones((len(verts), 1))), 1)
        per = np.einsum("vkab,vb->vka", skin[joints], homo)[..., :3]
        return (weights[..., None] * per).sum(1)

    def ibm(self) -> np.ndarray:
        m = self.array(self.doc.skins[0].inverseBindMatrices).astype(np.float64)
        return np.swapaxes(m.reshape(-1, 4, 4), 1, 2)


def standing_clip(frames: int = 15, seed: int = 0, still_toe: bool = True) -> Motion:
    """The small rig of :data:`rigs.RIG`, standing in its rest pose at frame 0, then moving;
    with ``still_toe`` the last joint has no rotation channels."""
    rng = np.random.default_rng(seed)
    ends = [(j, r[3]) for j, r in enumerate(RIG) if r[3] is not None]
    channels = [("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")]
    channels += [("Zrotation", "Xrotation", "Yrotation")] * (len(RIG) - 1 - still_toe)
    channels += [()] * still_toe
    sk = Skeleton(tuple(r[0] for r in RIG), np.array([r[1] for r in RIG]),
                  np.array([r[2] for r in RIG], dtype=float), tuple(channels),
                  end_site_parents=[j for j, _ in ends], end_site_offsets=[o for _, o in ends])
    euler = rng.uniform(-0.6, 0.6, (frames, len(RIG), 3))
    euler[0] = 0.0
    if still_toe:
        euler[:, -1] = 0.0
    rotations = euler_to_quaternion(euler, "ZXY")
    # Negated quaternions on some frames: the file must still interpolate the short way.
    rotations[1::3] *= -1
    positions = np.broadcast_to(sk.offsets, (frames, len(RIG), 3)).copy()
    positions[:, 0, 2] += np.linspace(0.0, 1.2, frames)
    return Motion(sk, rotations, positions, 25.0, {"name": "standing"})


@pytest.fixture(params=[".glb", ".gltf"])
def synthetic(tmp_path, request):
    motion = standing_clip()
    path = write_gltf(motion, tmp_path / f"walk{request.param}")
    return Read(path), motion, path


@pytest.fixture(scope="module")
def bandai(bandai1_dir, tmp_path_factory):
    motion = read_bvh(bandai1_dir / "data" / "dataset-1_walk_happy_001.bvh")
    motion = motion.replace(rotations=motion.rotations[:60], positions=motion.positions[:60])
    return Read(write_gltf(motion, tmp_path_factory.mktemp("gltf") / "walk.glb")), motion


def check_against_motion(read: Read, motion: Motion) -> None:
    sk = motion.skeleton
    doc = read.doc
    assert [n.name for n in read.joints] == list(sk.names)
    assert doc.nodes[-1].name == MESH_NODE and doc.nodes[-1].skin == 0
    assert doc.scenes[doc.scene].nodes == [0, len(doc.nodes) - 1]
    assert doc.skins[0].joints == list(range(sk.num_joints))
    # Key times: 0 .. (T - 1) / fps, one per frame.
    anim = doc.animations[0]
    times = read.array(anim.samplers[0].input)[:, 0]
    np.testing.assert_allclose(times, np.arange(motion.num_frames) / motion.fps, atol=1e-6)
    assert doc.accessors[anim.samplers[0].input].max[0] == pytest.approx(
        (motion.num_frames - 1) / motion.fps)
    assert {s.interpolation for s in anim.samplers} == {"LINEAR"}
    # A rotation channel per rotated joint; x, y, z, w of the motion's quaternions.
    rot = read.channel_values("rotation")
    assert sorted(rot) == [j for j in range(sk.num_joints) if sk.rotation_order(j)]
    for j, values in rot.items():
        assert values.shape == (motion.num_frames, 4)
        assert (np.sum(values[1:] * values[:-1], -1) >= 0).all()  # continuous signs
        for frame in (0, motion.num_frames // 2, motion.num_frames - 1):
            want = motion.rotations[frame, j, [1, 2, 3, 0]]
            got = values[frame] * np.sign(values[frame] @ want)
            np.testing.assert_allclose(got, want, atol=1e-6)
    # World transforms from the file's own nodes and channels match emotive's FK.
    for frame in (0, motion.num_frames // 2, motion.num_frames - 1):
        np.testing.assert_allclose(read.world(frame)[:, :3, 3], motion.global_positions()[frame],
                                   atol=1e-5)
    # Inverse bind matrices invert the world transforms of the bind pose (the first frame).
    np.testing.assert_allclose(read.world(0) @ read.ibm(), np.broadcast_to(np.eye(4), (
        sk.num_joints, 4, 4)), atol=1e-5)


def check_mesh(read: Read, motion: Motion) -> None:
    prim = read.doc.meshes[0].primitives[0]
    attrs = prim.attributes
    count = read.doc.accessors[attrs.POSITION].count
    for index in (attrs.NORMAL, attrs.JOINTS_0, attrs.WEIGHTS_0):
        assert read.doc.accessors[index].count == count
    triangles = read.array(prim.indices).reshape(-1, 3)
    assert 500 < len(triangles) < 12_000 and triangles.max() < count
    np.testing.assert_allclose(read.array(attrs.WEIGHTS_0).sum(1), 1.0)
    assert read.array(attrs.JOINTS_0).max() < motion.skeleton.num_joints
    np.testing.assert_allclose(np.linalg.norm(read.array(attrs.NORMAL), axis=1), 1.0, atol=1e-5)
    # Rigid skinning: every vertex keeps its place relative to its joint in every frame.
    verts = read.array(attrs.POSITION).astype(np.float64)
    joint = read.array(attrs.JOINTS_0)[:, 0].astype(np.int64)
    world0 = read.world(0)
    for frame in (motion.num_frames // 2, motion.num_frames - 1):
        grot, gpos = (a[frame] for a in motion.global_transforms())
        r = quaternion_to_matrix(grot)[joint] @ np.swapaxes(world0[joint, :3, :3], 1, 2)
        want = np.einsum("vab,vb->va", r, verts - world0[joint, :3, 3]) + gpos[joint]
        np.testing.assert_allclose(read.skinned(frame), want, atol=1e-4)


class TestSyntheticRig:
    def test_nodes_channels_and_bind_matrices_match_the_motion(self, synthetic):
        read, motion, _ = synthetic
        check_against_motion(read, motion)
        # The root's path is the one translation channel; the still toe has no rotation one.
        pos = read.channel_values("translation")
        assert sorted(pos) == [0]
        np.testing.assert_allclose(pos[0], motion.positions[:, 0], atol=1e-6)
        assert len(read.joints) - 1 not in read.channel_values("rotation")

    def test_the_mesh_is_skinned_rigidly_and_stands_as_tall_as_the_rig(self, synthetic):
        read, motion, _ = synthetic
        check_mesh(read, motion)
        ends = motion.positions_with_end_sites()[0]
        positions = read.doc.accessors[read.doc.meshes[0].primitives[0].attributes.POSITION]
        box = np.array(positions.max) - np.array(positions.min)
        # The rig stands 1.75 m from the toes' ends to the head's; the mesh adds some skull.
        assert np.ptp(ends[:, 1]) <= box[1] <= np.ptp(ends[:, 1]) + 0.2

    def test_the_material_and_the_buffer_are_inside_the_one_file(self, synthetic, tmp_path):
        read, _, path = synthetic
        assert read.doc.materials[0].pbrMetallicRoughness.baseColorFactor[3] == 1.0
        binary = path.suffix == ".glb"
        assert (read.doc.buffers[0].uri is None) == binary
        assert binary or read.doc.buffers[0].uri.startswith("data:application/octet-stream;")
        assert list(tmp_path.iterdir()) == [path]

    def test_without_a_mesh_the_file_holds_the_skeleton_and_its_animation(self, tmp_path):
        motion = standing_clip()
        read = Read(write_gltf(motion, tmp_path / "bones.glb", mesh=False))
        assert not read.doc.meshes and not read.doc.skins
        assert [n.name for n in read.doc.nodes] == list(motion.skeleton.names)
        np.testing.assert_allclose(read.world(5)[:, :3, 3], motion.global_positions()[5],
                                   atol=1e-5)


def test_a_clip_without_frames_is_its_rest_pose_without_an_animation(tmp_path):
    motion = standing_clip()
    empty = motion.replace(rotations=motion.rotations[:0], positions=motion.positions[:0])
    read = Read(write_gltf(empty, tmp_path / "rest.glb"))
    assert not read.doc.animations and read.doc.skins
    np.testing.assert_allclose([n.translation for n in read.joints], motion.skeleton.offsets,
                               atol=1e-6)
    np.testing.assert_allclose([n.rotation for n in read.joints],
                               np.tile([0.0, 0, 0, 1], (len(RIG), 1)))


class TestBandaiClip:
    def test_nodes_channels_and_bind_matrices_match_the_motion(self, bandai):
        read, motion = bandai
        check_against_motion(read, motion)
        # Only the hips move: Bandai's other position channels hold their offsets.
        assert sorted(read.channel_values("translation")) == [motion.skeleton.index("Hips")]

    def test_the_mannequin_is_a_person_sized_figure_on_the_ground(self, bandai):
        read, motion = bandai
        check_mesh(read, motion)
        for frame in (0, 30, 59):
            verts = read.skinned(frame)
            feet = motion.global_positions()[frame][:, 1].min()
            # Head to feet about an adult's height; no limb from the placement root (the
            # joint_Root to Hips offset is metres long) and no stray vertex.
            assert 1.45 < np.ptp(verts[:, 1]) < 1.8
            assert feet - 0.06 < verts[:, 1].min() < feet + 0.02
            hips = motion.global_positions()[frame, motion.skeleton.index("Hips")]
            assert np.linalg.norm(verts - hips, axis=1).max() < 1.0


class TestMannequin:
    def test_triangles_face_outwards_along_the_normals(self):
        motion = standing_clip()
        ends = motion.positions_with_end_sites()[0]
        mesh = fit_mannequin(motion.skeleton, ends[:len(RIG)], ends[len(RIG):])
        a, b, c = (mesh.positions[mesh.triangles[:, k]].astype(np.float64) for k in range(3))
        face = np.cross(b - a, c - a)
        big = np.linalg.norm(face, axis=1) > 1e-8
        mean_normal = mesh.normals[mesh.triangles].sum(1)
        assert big.mean() > 0.99
        assert ((face * mean_normal).sum(1)[big] > 0).all()

    def test_a_long_placement_offset_gets_no_geometry(self):
        motion = standing_clip()
        sk = motion.skeleton
        # A placement root 4 m away from the hips, as on the Bandai rig.
        rig = Skeleton(("Placement", *sk.names), np.array([-1, *(sk.parents + 1)]),
                       np.concatenate(([[0.0, 0, 0]], sk.offsets)),
                       end_site_parents=sk.end_site_parents + 1,
                       end_site_offsets=sk.end_site_offsets)
        points = motion.positions_with_end_sites()[0]
        far = np.concatenate(([[0.0, 0.0, -4.0]], points))
        mesh = fit_mannequin(rig, far[:rig.num_joints], far[rig.num_joints:])
        assert 0 not in set(mesh.joints.tolist())
        assert np.ptp(mesh.positions[:, 2]) < 0.6


def mannequin_of(motion: Motion):
    points = motion.positions_with_end_sites()[0]
    n = motion.skeleton.num_joints
    return fit_mannequin(motion.skeleton, points[:n], points[n:])


@pytest.mark.parametrize("layout", LAYOUTS)
def test_every_rig_family_gets_the_same_figure(layout):
    motion = standing_clip(still_toe=False)
    ours = mannequin_of(motion)
    other = to_layout(motion, layout)
    mesh = mannequin_of(other)
    # Same height and width (twist, finger and helper bones change little; Mixamo's toe end
    # joints make longer feet), a few thousand triangles, and nothing far from the body.
    size, want = np.ptp(mesh.positions, 0), np.ptp(ours.positions, 0)
    assert (np.abs(size / want - 1) < (0.03, 0.03, 0.2)).all(), (size, want)
    assert len(mesh.triangles) < 12_000
    hips = other.global_positions()[0, 1 if layout.startswith("unreal") else 0]
    assert np.linalg.norm(mesh.positions - hips, axis=1).max() < 1.1
    head = [j for j, name in enumerate(other.skeleton.names) if name.lower().endswith("head")]
    assert np.isin(head, mesh.joints).all()


def test_a_rig_with_no_bone_to_dress_gets_no_mesh(tmp_path):
    sk = Skeleton(("Root",), np.array([-1]), np.zeros((1, 3)))
    motion = Motion(sk, np.tile([1.0, 0, 0, 0], (4, 1, 1)), np.zeros((4, 1, 3)), 30.0)
    assert len(mannequin_of(motion).triangles) == 0
    read = Read(write_gltf(motion, tmp_path / "point.glb"))
    assert not read.doc.meshes and not read.doc.skins and len(read.doc.nodes) == 1


class TestMotionFiles:
    def test_the_suffix_chooses_the_format(self, tmp_path):
        motion = standing_clip(still_toe=False)
        assert MOTION_SUFFIXES == (".bvh", ".glb", ".gltf")
        bvh = read_bvh(write_motion(motion, tmp_path / "w.BVH", unit="m"))
        assert bvh.metadata["file_unit"] == "m" and bvh.num_frames == motion.num_frames
        assert (tmp_path / "w.glb").exists() is False
        write_motion(motion, tmp_path / "w.glb")
        assert (tmp_path / "w.glb").read_bytes()[:4] == b"glTF"
        with pytest.raises(OutputError, match=r"w\.fbx.*\.bvh or \.glb or \.gltf"):
            write_motion(motion, tmp_path / "w.fbx")
        with pytest.raises(OutputError, match=r"must end in \.glb or \.gltf.*w\.glb"):
            write_gltf(motion, tmp_path / "w.bvh")

    def test_a_failed_write_leaves_no_file(self, tmp_path, monkeypatch):
        motion = standing_clip()
        with pytest.raises(OutputError, match="missing"):
            write_motion(motion, tmp_path / "missing" / "w.glb")
        fill_disk(monkeypatch)
        with pytest.raises(OutputError, match="disk is full"):
            write_gltf(motion, tmp_path / "w.glb")
        assert list(tmp_path.iterdir()) == []

    def test_generated_motions_are_written_as_gltf(self, tmp_path):
        motion = standing_clip()
        assert {".glb", ".gltf"} < set(OUT_SUFFIXES)
        generated = Generated(motion, np.ones((motion.num_frames, 1)), ("happy",))
        written = write_generated(generated, tmp_path / "walk.gltf", npz=tmp_path / "walk.npz")
        assert written == [tmp_path / "walk.gltf", tmp_path / "walk.npz"]
        check_against_motion(Read(written[0]), motion)
