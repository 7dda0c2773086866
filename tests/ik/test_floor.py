"""Feet kept above the floor: sunk feet lifted straight up, smoothly, the hips kept."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from ik_helpers import make_humanoid

from emotive.core import Motion, Skeleton
from emotive.core.roles import resolve_roles
from emotive.features.contacts import FOOT_ROLES
from emotive.ik.floor import (
    FLOOR_ALLOWANCE,
    clip_floor,
    depth_below_floor,
    keep_above_floor,
    lift_feet,
    spread_lifts,
    standing_floor,
)

FRAMES = 60


def _sunk(motion: Motion, depth: np.ndarray) -> Motion:
    """The clip with its hips (and so both feet) lowered by ``depth`` ``(T,)`` metres."""
    positions = motion.positions.copy()
    positions[:, 0, 1] -= depth
    return motion.replace(positions=positions)


def _bump(frames: int, centre: int, width: float, height: float) -> np.ndarray:
    t = np.arange(frames)
    return height * np.exp(-0.5 * ((t - centre) / width) ** 2)


def _feet(motion: Motion) -> np.ndarray:
    """``(T, 4, 3)`` heel and toe positions."""
    roles = resolve_roles(motion.skeleton)
    return motion.positions_with_end_sites()[:, roles.indices(FOOT_ROLES)]


@pytest.fixture
def walker() -> Motion:
    return make_humanoid(FRAMES)


def test_sunk_feet_are_lifted_straight_up_to_the_floor_and_the_hips_stay(walker):
    roles = resolve_roles(walker.skeleton)
    floor = clip_floor(walker.positions_with_end_sites(), roles)
    sunk = _sunk(walker, _bump(FRAMES, 30, 5.0, 0.03))
    before = depth_below_floor(sunk.positions_with_end_sites(), roles, floor)
    assert before.max() > 0.025

    fixed = keep_above_floor(sunk, floor)
    after = depth_below_floor(fixed.positions_with_end_sites(), roles, floor)
    assert after.max() <= FLOOR_ALLOWANCE + 1e-9
    # Straight up: heels and toes keep their ground position; the hips do not move.
    np.testing.assert_allclose(_feet(fixed)[..., [0, 2]], _feet(sunk)[..., [0, 2]], atol=1e-9)
    np.testing.assert_array_equal(fixed.positions, sunk.positions)
    hips = roles.index["root"]
    np.testing.assert_array_equal(fixed.rotations[:, hips], sunk.rotations[:, hips])
    # Frames far from the dip are the input's own.
    np.testing.assert_array_equal(fixed.rotations[:10], sunk.rotations[:10])
    np.testing.assert_array_equal(fixed.rotations[-10:], sunk.rotations[-10:])


def test_a_one_frame_dip_is_lifted_over_neighbouring_frames(walker):
    roles = resolve_roles(walker.skeleton)
    floor = clip_floor(walker.positions_with_end_sites(), roles)
    dip = np.zeros(FRAMES)
    dip[30] = 0.03
    sunk = _sunk(walker, dip)
    fixed = keep_above_floor(sunk, floor)
    assert depth_below_floor(fixed.positions_with_end_sites(), roles, floor).max() <= (
        FLOOR_ALLOWANCE + 1e-9)
    lift = _feet(fixed)[:, :, 1].max(1) - _feet(sunk)[:, :, 1].max(1)
    # The lift starts before the dip and ends after it, rising and falling step by step.
    assert lift[28] > 1e-3 and lift[32] > 1e-3
    assert np.abs(np.diff(lift)).max() < 0.6 * lift.max()


def test_dips_within_the_allowance_are_left_alone(walker):
    roles = resolve_roles(walker.skeleton)
    floor = clip_floor(walker.positions_with_end_sites(), roles)
    sunk = _sunk(walker, _bump(FRAMES, 30, 5.0, 0.5 * FLOOR_ALLOWANCE))
    assert depth_below_floor(sunk.positions_with_end_sites(), roles, floor).max() > 0
    assert keep_above_floor(sunk, floor) is sunk


def test_the_standing_floor_is_the_standing_feet_heights(walker):
    roles = resolve_roles(walker.skeleton)
    standing = walker.positions_with_end_sites()[0]
    floor = standing_floor(standing, roles)
    assert floor.shape == (2, 2)
    np.testing.assert_allclose(floor.ravel(), standing[roles.indices(FOOT_ROLES), 1])
    assert depth_below_floor(standing[None], roles, floor).max() == 0.0


def _twisted_legs(frames: int) -> Motion:
    """A humanoid with a twist joint between each knee and ankle (no two-bone solve)."""
    names = ["Hips", "Spine", "Chest", "Neck", "Head"]
    parents = [-1, 0, 1, 2, 3]
    offsets = [[0, 0.9, 0], [0, 0.1, 0], [0, 0.15, 0], [0, 0.2, 0], [0, 0.1, 0]]
    for side, sign in (("L", 1.0), ("R", -1.0)):
        base = len(names)
        names += [f"UpperArm_{side}", f"LowerArm_{side}", f"Hand_{side}"]
        parents += [2, base, base + 1]
        offsets += [[sign * 0.15, 0.18, 0], [sign * 0.28, 0, 0], [sign * 0.25, 0, 0]]
        leg = len(names)
        names += [f"UpperLeg_{side}", f"LowerLeg_{side}", f"LowerLegTwist_{side}",
                  f"Foot_{side}", f"Toes_{side}"]
        parents += [0, leg, leg + 1, leg + 2, leg + 3]
        offsets += [[sign * 0.1, -0.05, 0], [0, -0.42, 0], [0, -0.2, 0], [0, -0.22, 0],
                    [0, -0.05, 0.12]]
    ends = [names.index("Head"), names.index("Hand_L"), names.index("Hand_R"),
            names.index("Toes_L"), names.index("Toes_R")]
    end_offsets = [[0, 0.1, 0], [0.08, 0, 0], [-0.08, 0, 0], [0, 0, 0.05], [0, 0, 0.05]]
    sk = Skeleton(tuple(names), parents, offsets, (), ends, end_offsets)
    rotations = np.zeros((frames, len(names), 4))
    rotations[..., 0] = 1.0
    positions = np.broadcast_to(np.asarray(offsets, dtype=np.float64),
                                (frames, len(names), 3)).copy()
    positions[:, 0, 2] += 0.02 * np.arange(frames)
    return Motion(sk, rotations, positions, 30.0)


def test_a_rig_without_a_two_bone_leg_is_lifted_through_its_root():
    clip = _twisted_legs(40)
    roles = resolve_roles(clip.skeleton)
    assert roles.names["l_ankle"] == "Foot_L"
    floor = clip_floor(clip.positions_with_end_sites(), roles)
    sunk = _sunk(clip, _bump(40, 20, 4.0, 0.03))
    fixed = keep_above_floor(sunk, floor)
    assert depth_below_floor(fixed.positions_with_end_sites(), roles, floor).max() <= (
        FLOOR_ALLOWANCE + 1e-9)
    np.testing.assert_array_equal(fixed.rotations, sunk.rotations)
    assert fixed.positions[20, 0, 1] > sunk.positions[20, 0, 1] + 0.02


def test_bad_shapes_are_refused(walker):
    with pytest.raises(ValueError, match=r"\(2, 2\)"):
        keep_above_floor(walker, np.zeros(4))
    with pytest.raises(ValueError, match=r"\(60, 2\)"):
        lift_feet(walker, np.zeros((FRAMES, 3)))


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(1, 40), st.just(2)),
              elements=st.floats(0.0, 0.1)), st.sampled_from([24.0, 30.0, 60.0, 120.0]))
def test_a_spread_lift_is_never_less_than_the_depth(depth, fps):
    lift = spread_lifts(depth, fps)
    assert lift.shape == depth.shape
    assert (lift >= depth).all()
    assert (lift <= depth.max() + 1e-12).all()
