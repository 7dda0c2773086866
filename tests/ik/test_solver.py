"""The DLS solver on a synthetic two-link chain."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from ik_helpers import solve_inputs, two_link

from emotive.errors import EmotiveError
from emotive.ik import IKError, solve_chain
from emotive.ik.solver import _ChainKernel
from emotive.transforms.np_rotations import (
    quaternion_apply,
    quaternion_multiply,
    quaternion_to_axis_angle,
)


def _ankle(rotations: np.ndarray) -> np.ndarray:
    """World ankle positions ``(T, 3)`` of two-link solutions ``(T, 2, 4)``, rebuilt from the
    rotations so the check does not trust the solver's own forward kinematics."""
    shin = np.array([0.0, -0.5, 0.0])
    thigh = quaternion_apply(rotations[:, 0], np.broadcast_to(shin, (len(rotations), 3)))
    both = quaternion_multiply(rotations[:, 0], rotations[:, 1])
    return thigh + quaternion_apply(both, np.broadcast_to(shin, (len(rotations), 3)))


def _solve(chain, targets, **kw):
    return solve_chain(chain, *solve_inputs(chain, targets), targets, chain.neutral, **kw)


def test_kernel_matches_forward_kinematics(rng):
    chain, _ = two_link()
    kern = _ChainKernel(chain)
    theta = torch.as_tensor(rng.uniform(-1, 1, (5, 2, 3)))
    targets = rng.normal(0, 0.3, (5, 1, 3))
    base_rot, base_pos, local_pos, offsets = solve_inputs(chain, targets)
    base_rot = quaternion_multiply(base_rot, np.array([np.cos(0.3), np.sin(0.3), 0, 0]))
    nodes = torch.as_tensor(np.concatenate((base_pos[:, None], local_pos, offsets), 1))
    fast = kern.points(theta, torch.as_tensor(base_rot), nodes)
    ref = kern.points_reference(theta, torch.as_tensor(base_rot), nodes)
    for a, b in zip(fast, ref, strict=True):
        torch.testing.assert_close(a, b)


def test_reachable_targets_are_hit_within_limits(rng):
    chain, _ = two_link()
    direction = rng.normal(size=(40, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    direction[:, 1] = -np.abs(direction[:, 1]) - 0.5  # below the hip, inside the hip's range
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    targets = (direction * rng.uniform(0.3, 0.95, (40, 1)))[:, None]
    sol = _solve(chain, targets, warm_start=False, max_iter=40)
    assert sol.residual.max() < 1e-3
    assert len(sol.unreachable) == 0
    np.testing.assert_allclose(_ankle(sol.rotations), targets[:, 0], atol=1e-3)
    assert np.all(sol.theta >= chain.lower - 1e-9) and np.all(sol.theta <= chain.upper + 1e-9)
    knee = quaternion_to_axis_angle(sol.rotations[:, 1])
    flex = knee @ chain.axes[1][:, 0]
    np.testing.assert_allclose(np.linalg.norm(knee, axis=-1), np.abs(flex), atol=1e-9)
    assert flex.min() >= -1e-9 and flex.max() <= np.radians(150) + 1e-9


def test_limits_hold_when_target_needs_more():
    chain, _ = two_link(hip_swing=10.0)
    targets = np.array([[[0.8, -0.2, 0.0]]])  # far to the side: needs ~75 degrees of hip swing
    sol = _solve(chain, targets, warm_start=False, max_iter=60)
    assert np.all(sol.theta >= chain.lower - 1e-9) and np.all(sol.theta <= chain.upper + 1e-9)
    assert np.isclose(np.abs(sol.theta[0, 0, 1:]).max(), np.radians(10.0), atol=1e-6)
    assert sol.residual[0] > 0.1  # the limit, not the target, won


def test_unreachable_target_is_clamped_and_reported():
    chain, _ = two_link()
    targets = np.array([[[0.0, -0.6, 0.0]], [[0.3, -1.2, 0.9]], [[0.0, -0.7, 0.1]]])
    sol = _solve(chain, targets, max_iter=60)
    assert list(sol.unreachable.frames) == [1]
    assert sol.unreachable.targets == ("l_ankle",)
    excess = np.linalg.norm(targets[1, 0]) - 1.0
    np.testing.assert_allclose(sol.unreachable.distances, [excess], rtol=1e-9)
    ankle = _ankle(sol.rotations)[1]
    np.testing.assert_allclose(ankle, targets[1, 0] / np.linalg.norm(targets[1, 0]), atol=5e-3)
    assert sol.residual[1] < 5e-3  # measured to the clamped target


def test_nan_targets_raise_typed_error_naming_chain_and_frames():
    chain, _ = two_link()
    targets = np.full((10, 1, 3), [0.0, -0.7, 0.1])
    targets[3, 0, 1] = np.nan
    targets[7, 0, 0] = np.inf
    with pytest.raises(IKError, match=r"test_leg.*\[3, 7\]") as info:
        _solve(chain, targets)
    assert isinstance(info.value, EmotiveError)


def test_warm_start_gives_continuous_solution_on_smooth_path():
    chain, _ = two_link()
    t = np.linspace(0, 2 * np.pi, 200)
    targets = np.stack((0.4 * np.cos(t), -0.6 + 0.1 * np.sin(2 * t), 0.4 * np.sin(t)), -1)[:, None]
    sol = _solve(chain, targets, segment=50, burn_in=10)
    assert sol.residual.max() < 1e-3
    q = sol.rotations
    # Angle between consecutive frames' local rotations: no sign flips or branch jumps.
    dots = np.abs(np.sum(q[1:] * q[:-1], axis=-1)).clip(max=1.0)
    step = np.degrees(2 * np.arccos(dots))
    path_step = np.degrees(t[1] - t[0])
    assert step.max() < 3 * path_step
    assert np.all(np.sum(q[1:] * q[:-1], axis=-1) > 0)


def test_frames_the_first_pass_leaves_off_target_are_retried():
    chain, _ = two_link()
    # Far from the neutral pose: one iteration per frame cannot get there.
    targets = np.tile([[[0.5, -0.4, 0.45]]], (6, 1, 1))
    once = _solve(chain, targets, warm_start=False, max_iter=1, retry_above=np.inf)
    assert once.residual.min() > 0.01
    np.testing.assert_array_equal(once.off_target, np.arange(6))
    retried = _solve(chain, targets, warm_start=False, max_iter=1)
    assert retried.residual.max() < 1e-3
    assert len(retried.off_target) == 0
    assert retried.iterations.min() > once.iterations.max()


def test_frames_held_back_by_a_joint_limit_are_reported_off_target():
    chain, _ = two_link(hip_swing=10.0)
    targets = np.array([[[0.0, -0.99, 0.0]], [[0.8, -0.2, 0.0]], [[0.02, -0.985, 0.0]]])
    sol = _solve(chain, targets, max_iter=60)
    np.testing.assert_array_equal(sol.off_target, [1])  # the limit, not the solver, lost
    assert sol.residual[1] > 0.1 and sol.residual[[0, 2]].max() < 1e-3
    loose = _solve(chain, targets, max_iter=60, off_target=1.0)
    assert len(loose.off_target) == 0
