"""The classifier reads identical joint motion alike on any rig that carries it.

Rig variants of held-out walks are built with the project's own code: renamed onto another
family's layout (:func:`emotive.core.rig_layouts.to_layout`), given other Euler channel orders,
re-expressed against a rotated rest pose (every joint frame turned by its own rotation, the
rotations and offsets rewritten so that every joint keeps its world position), given end sites
of random lengths (0-20 cm) and extra helper joints, then written to BVH in another unit
(:func:`emotive.io.bvh.write_bvh`) and read back (:func:`emotive.io.bvh.read_bvh`). The
calibrated probabilities must stay within 0.02 of the original rig's; the role joints the
classifier reads within 1e-4 of the leg length, and the affective features computed from them
within 1e-4 (radians for angles, relative for ratios).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from emotive.core.motion import Motion
from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.core.skeleton import ROTATION_CHANNELS, Skeleton
from emotive.eval.classifier import ROLE_POINTS, load_default_classifier, role_track
from emotive.features.affective import AFFECTIVE_FEATURE_KINDS, affective_features_np
from emotive.features.contacts import leg_length
from emotive.io.bvh import read_bvh, write_bvh
from emotive.transforms.fast_np import CONJUGATE, qapply, qmul
from layout_clips import synthetic_clip

#: Dataset-1 walks of the test split (never trained on).
HELD_OUT = ("dataset-1_walk_angry_002", "dataset-1_walk_happy_002", "dataset-1_walk-right_sad_001")
#: Frames kept of each clip (1.5 s at 30 fps: one judged window, quick to write and read).
FRAMES = 45
#: Variants drawn per held-out clip (3 x 70 = 210 in all).
EXAMPLES = 70
UNITS = ("m", "cm", "mm", "in")
ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
PROBABILITY_TOL = 0.02
POSITION_TOL = 1e-4
FEATURE_TOL = 1e-4


@pytest.fixture(scope="module")
def model():
    return load_default_classifier()


@pytest.fixture(scope="module")
def walks(bandai1_dir):
    out = {}
    for name in HELD_OUT:
        m = read_bvh(bandai1_dir / "data" / f"{name}.bvh")
        out[name] = m.replace(rotations=m.rotations[:FRAMES], positions=m.positions[:FRAMES])
    return out


def _quaternions(rng: np.random.Generator, n: int) -> np.ndarray:
    """``(n, 4)`` random unit quaternions ``w, x, y, z``."""
    xyzw = Rotation.random(n, random_state=rng).as_quat()
    return np.concatenate((xyzw[:, 3:], xyzw[:, :3]), axis=1)


def _reorder(skeleton: Skeleton, rng: np.random.Generator) -> Skeleton:
    """The rig with each rotated joint's Euler channels in a random order."""
    channels = []
    for chans in skeleton.channels:
        order = ORDERS[rng.integers(len(ORDERS))]
        rot = [c for c in chans if c in ROTATION_CHANNELS]
        pos = [c for c in chans if c not in ROTATION_CHANNELS]
        channels.append(tuple(pos) + (tuple(f"{a}rotation" for a in order) if rot else ()))
    return replace(skeleton, channels=tuple(channels))


def _rotate_rest(motion: Motion, rng: np.random.Generator) -> Motion:
    """The clip against a rest pose whose joint frames are turned by random rotations.

    Joint ``j``'s frame is turned by ``Q_j``: its world rotation becomes ``W_j Q_j``, so the
    local rotation is ``Q_p^-1 q_j Q_j`` and offsets (and animated translations) are read in
    the turned parent frame, ``Q_p^-1 t_j``; end sites in the turned joint frame. Every joint and
    end site keeps its world position.
    """
    sk = motion.skeleton
    q = _quaternions(rng, sk.num_joints)
    parents = sk.parents
    has_parent = parents >= 0
    q_parent_inv = np.where(has_parent[:, None], q[np.maximum(parents, 0)] * CONJUGATE,
                            [1.0, 0.0, 0.0, 0.0])
    rotations = qmul(qmul(np.broadcast_to(q_parent_inv, motion.rotations.shape),
                          motion.rotations), np.broadcast_to(q, motion.rotations.shape))
    positions = qapply(np.broadcast_to(q_parent_inv, (*motion.positions.shape[:2], 4)),
                       motion.positions)
    offsets = qapply(q_parent_inv, sk.offsets)
    ends = qapply(q[sk.end_site_parents] * CONJUGATE, sk.end_site_offsets)
    return motion.replace(skeleton=replace(sk, offsets=offsets, end_site_offsets=ends),
                          rotations=rotations, positions=positions)


def _end_sites(skeleton: Skeleton, rng: np.random.Generator) -> Skeleton:
    """The rig with every end site 0-20 cm long, in its own direction (random when zero)."""
    off = np.array(skeleton.end_site_offsets, dtype=np.float64)
    norm = np.linalg.norm(off, axis=1, keepdims=True)
    random_dir = rng.normal(size=off.shape)
    direction = np.where(norm > 1e-9, off / np.maximum(norm, 1e-12),
                         random_dir / np.linalg.norm(random_dir, axis=1, keepdims=True))
    return replace(skeleton, end_site_offsets=direction * rng.uniform(0, 0.2, (len(off), 1)))


def _with_helpers(motion: Motion, rng: np.random.Generator, count: int) -> Motion:
    """The clip with ``count`` helper joints (each with an end site) hung below random joints.

    Each helper carries the rig's shared name prefix (``mixamorig:``), a random offset up to
    15 cm and a random rotation that changes over time.
    """
    sk = motion.skeleton
    prefix = sk.names[0].rpartition(":")[0] + ":" if ":" in sk.names[0] else ""
    n, t = sk.num_joints, motion.num_frames
    parents = rng.integers(0, n, count)
    offsets = rng.uniform(-0.15, 0.15, (count, 3))
    start, end = _quaternions(rng, count), _quaternions(rng, count)
    w = np.linspace(0, 1, t)[:, None, None]
    end *= np.where((start * end).sum(-1, keepdims=True) < 0, -1.0, 1.0)
    spin = start[None] * (1 - w) + end[None] * w
    spin /= np.linalg.norm(spin, axis=-1, keepdims=True)
    skeleton = Skeleton(
        sk.names + tuple(f"{prefix}Helper{k}_twist" for k in range(count)),
        np.concatenate((sk.parents, parents)), np.concatenate((sk.offsets, offsets)),
        sk.channels + (("Zrotation", "Xrotation", "Yrotation"),) * count,
        np.concatenate((sk.end_site_parents, n + np.arange(count))),
        np.concatenate((sk.end_site_offsets, rng.uniform(-0.1, 0.1, (count, 3)))),
    )
    return motion.replace(
        skeleton=skeleton, rotations=np.concatenate((motion.rotations, spin), axis=1),
        positions=np.concatenate((motion.positions, np.broadcast_to(offsets, (t, count, 3))),
                                 axis=1))


def rig_variant(walk: Motion, layout: str, unit: str, seed: int, rest: bool, helpers: int,
                folder) -> Motion:
    """``walk`` on a random rig variant, written to BVH in ``unit`` and read back."""
    rng = np.random.default_rng(seed)
    motion = walk if layout == "bandai" else to_layout(walk, layout)
    motion = motion.replace(skeleton=_end_sites(_reorder(motion.skeleton, rng), rng))
    if rest:
        motion = _rotate_rest(motion, rng)
    if helpers:
        motion = _with_helpers(motion, rng, helpers)
    return read_bvh(write_bvh(motion, folder / f"{layout}-{seed}.bvh", unit=unit), unit=unit)


def _assert_reads_alike(model, walk: Motion, other: Motion) -> None:
    base, judged = model.judge(walk), model.judge(other)
    assert np.abs(judged.probabilities - base.probabilities).max() <= PROBABILITY_TOL
    a, b = role_track(walk), role_track(other)
    leg = leg_length(a, ROLE_POINTS)
    assert np.abs(a - b).max() <= POSITION_TOL * leg
    fa, fb = affective_features_np(a, ROLE_POINTS), affective_features_np(b, ROLE_POINTS)
    angles = np.array([k == "angle" for k in AFFECTIVE_FEATURE_KINDS])
    assert np.abs(fa - fb)[:, angles].max() <= FEATURE_TOL
    assert (np.abs(fa - fb) / np.abs(fa))[:, ~angles].max() <= FEATURE_TOL


_VARIANTS = dict(
    layout=st.sampled_from(("bandai", *LAYOUTS)), unit=st.sampled_from(UNITS),
    seed=st.integers(0, 2**32 - 1), rest=st.booleans(), helpers=st.integers(0, 4),
)


@pytest.mark.data
@pytest.mark.parametrize("clip", HELD_OUT)
@settings(max_examples=EXAMPLES, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(**_VARIANTS)
def test_rig_variants_read_alike(model, walks, clip, tmp_path, layout, unit, seed, rest,
                                 helpers):
    walk = walks[clip]
    other = rig_variant(walk, layout, unit, seed, rest, helpers, tmp_path)
    assert other.num_frames == walk.num_frames
    _assert_reads_alike(model, walk, other)


@settings(max_examples=30, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(**_VARIANTS)
def test_synthetic_rig_variants_read_alike(model, tmp_path, layout, unit, seed, rest, helpers):
    """Without the data: random poses of the small Bandai-named rig (:mod:`layout_clips`)."""
    walk = synthetic_clip(frames=30, seed=seed % 7)
    _assert_reads_alike(model, walk, rig_variant(walk, layout, unit, seed, rest, helpers,
                                                 tmp_path))


@pytest.mark.data
def test_mixamo_centimetres_long_end_sites_reads_neutral(model, bandai1_dir, tmp_path):
    """The reported rig: Mixamo names, centimetres, head end site 15 cm, hand ends 10 cm."""
    walk = read_bvh(bandai1_dir / "data" / "dataset-1_walk_normal_001.bvh")
    mixamo = to_layout(walk, "mixamo")
    sk = mixamo.skeleton
    off = np.array(sk.end_site_offsets)
    direction = off / np.linalg.norm(off, axis=1, keepdims=True)
    names = [sk.names[p] for p in sk.end_site_parents]
    length = np.array([0.15 if "Head" in n else 0.10 if "Hand" in n else 0.0 for n in names])
    assert (length == 0.15).sum() == 1 and (length == 0.10).sum() >= 2
    sk = replace(sk, end_site_offsets=np.where(length[:, None] > 0, direction * length[:, None],
                                               off))
    path = write_bvh(mixamo.replace(skeleton=sk), tmp_path / "mixamo.bvh", unit="cm")
    other = read_bvh(path)
    assert other.metadata["file_unit"] == "cm"
    base, judged = model.judge(walk), model.judge(other)
    assert np.abs(judged.probabilities - base.probabilities).max() <= PROBABILITY_TOL
    neutral = base.labels.index("neutral")
    assert judged.probabilities.mean(0).argmax() == neutral
    assert judged.probabilities[:, neutral].mean() >= 0.9
