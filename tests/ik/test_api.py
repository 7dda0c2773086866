"""Trajectories, reconstruction and foot pinning on whole clips."""

from __future__ import annotations

import numpy as np
import pytest
from ik_helpers import make_humanoid

from emotive.core.ops import canonicalize_facing
from emotive.ik import (
    extract_trajectories,
    integrate_pelvis,
    pin_feet,
    reconstruct,
    resolve_chains,
)
from emotive.io.bvh import read_bvh


def test_trajectories_are_invariant_to_world_placement_and_invert():
    motion = make_humanoid(frames=40)
    moved = canonicalize_facing(motion.replace(), frame=10)
    chains = resolve_chains(motion.skeleton, motion)
    a, b = extract_trajectories(motion, chains), extract_trajectories(moved, chains)
    for name in chains:
        np.testing.assert_allclose(a.targets[name], b.targets[name], atol=1e-9)
    np.testing.assert_allclose(a.pelvis.displacement, b.pelvis.displacement, atol=1e-9)
    np.testing.assert_allclose(a.pelvis.turn, b.pelvis.turn, atol=1e-9)
    pos, rot = integrate_pelvis(b.pelvis)
    np.testing.assert_allclose(pos, moved.global_positions()[:, 0], atol=1e-9)
    world = moved.global_transforms()[0][:, 0]
    np.testing.assert_allclose(np.abs(np.sum(rot * world, -1)), 1.0, atol=1e-9)


def _ground_speed(p: np.ndarray) -> np.ndarray:
    """Horizontal speed (m/s at 30 fps) over the contact frames 20..39."""
    return np.linalg.norm(np.diff(p[20:40, [0, 2]], axis=0), axis=-1) * 30.0


def test_pin_feet_stops_a_sliding_foot():
    motion = make_humanoid(frames=60, speed=0.3)
    contacts = np.zeros((60, 2), dtype=bool)
    contacts[20:40, 0] = True
    chains = resolve_chains(motion.skeleton, motion, names=("left_leg", "right_leg"))
    ankle = chains["left_leg"].targets[0]
    before = motion.positions_with_end_sites()[:, ankle]
    result = pin_feet(motion, contacts, chains)
    after = result.motion.positions_with_end_sites()[:, ankle]
    assert _ground_speed(before).min() > 0.2
    assert _ground_speed(after).max() < 0.01
    assert result.residuals["left_leg"].max() < 2e-3
    assert len(result.unreachable["left_leg"]) == 0
    # Far from the contact (and for the free right foot) the clip is untouched.
    np.testing.assert_allclose(after[:10], before[:10], atol=2e-3)


@pytest.mark.data
def test_reconstruct_real_walk(bandai1_dir):
    motion = read_bvh(bandai1_dir / "data" / "dataset-1_walk_normal_001.bvh")
    chains = resolve_chains(motion.skeleton, motion)
    result = reconstruct(motion, chains)
    a = motion.positions_with_end_sites()
    b = result.motion.positions_with_end_sites()
    report = {}
    for name, chain in chains.items():
        effector = np.linalg.norm(a[:, chain.targets] - b[:, chain.targets], axis=-1)
        joints = np.linalg.norm(a[:, chain.joints] - b[:, chain.joints], axis=-1)
        report[name] = (effector.max(), joints.mean())
        assert len(result.unreachable[name]) == 0
        assert result.residuals[name].max() < 2e-3, name
        assert effector.max() < 5e-3, name  # world end effectors and elbows within 5 mm
    print({n: (round(e * 1000, 2), round(j * 1000, 2)) for n, (e, j) in report.items()})
    # Torso and arms are fully determined by their targets; the legs keep a free knee swivel.
    assert max(report[n][1] for n in ("head_torso", "left_arm", "right_arm")) < 2e-3
    assert max(report[n][1] for n in ("left_leg", "right_leg")) < 6e-3
    assert np.linalg.norm(a - b, axis=-1).max() < 0.06
