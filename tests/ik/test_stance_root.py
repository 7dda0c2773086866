"""The root path rebuilt from the stance foot (emotive.ik.stance_root)."""

from __future__ import annotations

import numpy as np
import pytest
from ik_helpers import make_humanoid

from emotive.core.roles import resolve_roles
from emotive.features.contacts import foot_positions
from emotive.ik import root_from_stance
from emotive.transforms.np_rotations import axis_angle_to_quaternion, quaternion_multiply


def _frozen_glide(frames: int = 90, speed: float = 1.0):
    """The humanoid holding its first pose while its root glides forward at ``speed`` m/s."""
    walk = make_humanoid(frames, speed=speed)
    rotations = np.repeat(walk.rotations[:1], frames, axis=0)
    return walk.replace(rotations=rotations)


def _root_speed(motion) -> np.ndarray:
    """``(T - 1,)`` horizontal speed of the root role's joint, m/s."""
    root = resolve_roles(motion.skeleton).index["root"]
    path = motion.global_positions()[:, root]
    return np.linalg.norm(np.diff(path[:, [0, 2]], axis=0), axis=1) * motion.fps


def _root_jerk(motion) -> float:
    """99th percentile of the root role's jerk, m/s^3."""
    root = resolve_roles(motion.skeleton).index["root"]
    path = motion.global_positions()[:, root]
    return float(np.percentile(np.linalg.norm(np.diff(path, 3, axis=0), axis=1), 99)
                 * motion.fps**3)


def test_a_root_gliding_over_still_legs_stops():
    glide = _frozen_glide()
    assert _root_speed(glide).min() > 0.99
    fixed = root_from_stance(glide)
    assert _root_speed(fixed).max() < 1e-9
    np.testing.assert_allclose(fixed.positions[:, 0, 1], glide.positions[:, 0, 1])
    np.testing.assert_array_equal(fixed.rotations, glide.rotations)


def test_in_the_air_the_root_keeps_its_own_velocity():
    glide = _frozen_glide()
    positions = glide.positions.copy()
    positions[40:50, 0, 1] += 0.3  # a jump: every foot point far above its ground
    exact = _root_speed(root_from_stance(glide.replace(positions=positions), smooth_seconds=0))
    np.testing.assert_allclose(exact[40:49], 1.0, atol=1e-9)
    assert exact[:38].max() < 1e-9 and exact[51:].max() < 1e-9
    smooth = _root_speed(root_from_stance(glide.replace(positions=positions)))
    assert smooth[44] > 0.99 and smooth[:30].max() < 1e-3 and smooth[60:].max() < 1e-3
    assert abs(smooth.sum() - exact.sum()) < 1e-6  # the smoothing moves the shift, keeps it


def test_the_stance_point_stays_still_while_the_body_turns_and_the_legs_swing():
    walk = make_humanoid(120, speed=0.3)
    yaw = axis_angle_to_quaternion(np.outer(np.linspace(0.0, 1.2, 120), [0.0, 1.0, 0.0]))
    rotations = walk.rotations.copy()
    rotations[:, 0] = quaternion_multiply(yaw, rotations[:, 0])
    fixed = root_from_stance(walk.replace(rotations=rotations), smooth_seconds=0)
    roles = resolve_roles(fixed.skeleton)
    feet = foot_positions(fixed.positions_with_end_sites(), roles).reshape(120, 4, 3)
    heights = feet[..., 1] - np.percentile(feet[..., 1], 5.0, axis=0)
    stance = (0.5 * (heights[1:] + heights[:-1])).argmin(axis=1)
    steps = np.arange(119)
    moved = feet[steps + 1, stance][:, [0, 2]] - feet[steps, stance][:, [0, 2]]
    assert np.abs(moved).max() < 1e-9
    assert np.ptp(fixed.positions[:, 0, [0, 2]], axis=0).max() > 0.01  # the swing moves it


def test_one_frame_is_returned_unchanged():
    one = make_humanoid(1)
    assert root_from_stance(one) is one


@pytest.mark.data
def test_real_walks_keep_most_of_their_root_speed(bandai1_dir):
    from emotive.data.clips import load_clips

    ratios, jerks = [], []
    for clip in load_clips("bandai-namco-1", contents=("walk",)):
        if clip.motion.duration < 2.0:
            continue
        fixed = root_from_stance(clip.motion)
        ratios.append(_root_speed(fixed).mean() / _root_speed(clip.motion).mean())
        jerks.append(_root_jerk(fixed) / _root_jerk(clip.motion))
    # Locking rolling heels and toes loses a little of each step (module doc: 0.94 median).
    assert 0.88 < np.median(ratios) < 1.02
    assert min(ratios) > 0.75
    # The smoothing keeps the root as smooth as recorded (unsmoothed: about 6x).
    assert np.median(jerks) < 1.2
