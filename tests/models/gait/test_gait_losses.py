"""Tests of the gait losses: minimum at the truth, known values on hand-built poses, the
combined loss, the ablation switches and finite gradients."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from gait_helpers import NUM_JOINTS, random_inputs, random_pose

from emotive.core import Motion, Skeleton
from emotive.models.gait import (
    GaitConfig,
    GaitLoss,
    GaitNetwork,
    GaitOutputs,
    GaitRig,
    affective_loss,
    amplitude_loss,
    foot_contact_loss,
    motion_loss,
    pose_loss,
    rig_positions,
    root_loss,
)
from emotive.models.gait.affect import gait_affective_np
from emotive.transforms.np_rotations import euler_to_quaternion
from emotive.transforms.rotations import quaternion_multiply, yaw_quaternion

LOWER_ARM_L, TOES_L = 6, 14
#: Half turn about X: maps (0, y, z) to (0, -y, -z).
HALF_TURN_X = torch.tensor([0.0, 1.0, 0.0, 0.0], dtype=torch.float64)


def rest_pose(skeleton, frames: int = 2) -> tuple[torch.Tensor, torch.Tensor]:
    """Identity rotations and rest offsets, the root translated to (1, 0.95, 2)."""
    rotations = torch.zeros(frames, NUM_JOINTS, 4, dtype=torch.float64)
    rotations[..., 0] = 1.0
    positions = torch.from_numpy(np.broadcast_to(skeleton.offsets, (frames, NUM_JOINTS, 3))
                                 .copy())
    positions[:, 0] = torch.tensor([1.0, 0.95, 2.0], dtype=torch.float64)
    return rotations, positions


def with_joint(rotations: torch.Tensor, joint: int, q: torch.Tensor) -> torch.Tensor:
    out = rotations.clone()
    out[..., joint, :] = q
    return out


class TestMotionLoss:
    def test_zero_at_truth_and_for_the_opposite_quaternion(self, skeleton, rig):
        q, _, _ = random_pose(skeleton, (2, 3))
        assert float(motion_loss(q, q, rig.euler_orders)) == pytest.approx(0.0, abs=1e-20)
        assert float(motion_loss(-q, q, rig.euler_orders)) == pytest.approx(0.0, abs=1e-20)

    def test_unit_norm_penalty_on_raw_quaternions(self, skeleton, rig):
        q, _, _ = random_pose(skeleton, (4,))
        # Twice as long: same rotation, penalty lambda (2 - 1)^2 per joint and frame.
        got = motion_loss(2.0 * q, q, rig.euler_orders, versor_weight=0.5)
        assert float(got) == pytest.approx(0.5 * NUM_JOINTS)

    def test_known_euler_offset_in_each_joints_order(self, skeleton, rig):
        q, _, euler = random_pose(skeleton, (3,), seed=1)
        joint = 5
        order = skeleton.rotation_order(joint)
        assert order != skeleton.rotation_order(joint + 1)
        shifted = euler[:, joint] + np.array([0.3, -0.2, 0.1])
        pred = with_joint(q, joint, torch.from_numpy(euler_to_quaternion(shifted, order)))
        assert float(motion_loss(pred, q, rig.euler_orders)) == pytest.approx(0.14, rel=1e-9)
        # The wrong orders measure another difference: the loss must use the rig's own.
        wrong = motion_loss(pred, q, ("XYZ",) * NUM_JOINTS)
        assert abs(float(wrong) - 0.14) > 1e-3

    def test_differences_wrap_across_pi(self, skeleton, rig):
        order = skeleton.rotation_order(0)
        near = torch.from_numpy(euler_to_quaternion(np.array([[math.pi - 0.05, 0.1, 0.2]]),
                                                    order))
        across = torch.from_numpy(euler_to_quaternion(np.array([[-math.pi + 0.05, 0.1, 0.2]]),
                                                      order))
        base, _ = rest_pose(skeleton, 1)
        got = motion_loss(with_joint(base, 0, across), with_joint(base, 0, near),
                          rig.euler_orders)
        assert float(got) == pytest.approx(0.01, rel=1e-9)

    def test_positive_and_shape_checked(self, skeleton, rig):
        a, _, _ = random_pose(skeleton, (2,), seed=2)
        b, _, _ = random_pose(skeleton, (2,), seed=3)
        assert float(motion_loss(a, b, rig.euler_orders)) > 0.1
        with pytest.raises(ValueError, match="rotations"):
            motion_loss(a[:, :-1], b[:, :-1], rig.euler_orders)
        with pytest.raises(ValueError, match="rotations"):
            motion_loss(a, b[:1], rig.euler_orders)


class TestPositionLosses:
    def test_rig_positions_match_the_motion_class(self, skeleton, rig):
        q, pos, _ = random_pose(skeleton, (5,), seed=4)
        expected = Motion(skeleton, q.numpy(), pos.numpy(), 30.0).positions_with_end_sites()
        got = rig_positions(q, pos, rig)
        assert got.shape == (5, NUM_JOINTS + 5, 3)
        np.testing.assert_allclose(got.numpy(), expected, atol=1e-12)

    @pytest.mark.parametrize("loss", [pose_loss, affective_loss, foot_contact_loss])
    def test_zero_at_truth_positive_otherwise(self, skeleton, rig, loss):
        q, pos, _ = random_pose(skeleton, (2, 3), seed=5)
        other, _, _ = random_pose(skeleton, (2, 3), seed=6)
        assert float(loss(q, q, pos, rig)) == pytest.approx(0.0, abs=1e-20)
        assert float(loss(other, q, pos, rig)) > 1e-3

    def test_known_pose_offset(self, skeleton, rig):
        rest, pos = rest_pose(skeleton)
        # The left elbow turns half round: the hand joint 0.25 m below it goes 0.25 m above
        # (0.5 m away); the hand's end site is not a joint and does not count.
        bent = with_joint(rest, LOWER_ARM_L, HALF_TURN_X)
        assert float(pose_loss(bent, rest, pos, rig)) == pytest.approx(0.25, rel=1e-12)

    def test_pose_loss_ignores_translation_but_not_facing(self, skeleton, rig):
        q, pos, _ = random_pose(skeleton, (4,), seed=7)
        moved = pos.clone()
        moved[:, 0] += torch.tensor([3.0, 0.5, -2.0], dtype=torch.float64)
        assert float(pose_loss(q, q, moved, rig)) == pytest.approx(0.0, abs=1e-20)
        turned = with_joint(q, 0, quaternion_multiply(
            yaw_quaternion(torch.tensor(0.7, dtype=torch.float64)), q[:, 0]))
        assert float(pose_loss(turned, q, pos, rig)) > 1e-2

    def test_affective_loss_is_invariant_to_turning_about_the_vertical(self, skeleton, rig):
        q, pos, _ = random_pose(skeleton, (4,), seed=8)
        turned = with_joint(q, 0, quaternion_multiply(
            yaw_quaternion(torch.tensor(1.3, dtype=torch.float64)), q[:, 0]))
        assert float(affective_loss(turned, q, pos, rig)) == pytest.approx(0.0, abs=1e-16)

    def test_affective_loss_matches_the_numpy_features_with_log_ratios(self, skeleton, rig):
        q, pos, _ = random_pose(skeleton, (3,), seed=9)
        other, _, _ = random_pose(skeleton, (3,), seed=10)

        def features(rotations):
            motion = Motion(skeleton, rotations.numpy(), pos.numpy(), 30.0)
            return gait_affective_np(motion.positions_with_end_sites(), rig.roles)

        expected = ((features(other) - features(q)) ** 2).sum(-1).mean()
        assert float(affective_loss(other, q, pos, rig)) == pytest.approx(expected, rel=1e-9)

    def test_known_foot_contact_offset(self, skeleton, rig):
        rest, pos = rest_pose(skeleton)
        # The left toe joint turns half round: its end site (the toe role) 5 cm ahead goes
        # 5 cm behind; the heel (ankle) stays. L1 = 0.1 m.
        turned = with_joint(rest, TOES_L, HALF_TURN_X)
        assert float(foot_contact_loss(turned, rest, pos, rig)) == pytest.approx(0.1, rel=1e-12)
        # A predicted trajectory 0.1 m to the side moves all four points: L1 = 4 x 0.1 m.
        shifted = pos.clone()
        shifted[:, 0, 0] += 0.1
        got = foot_contact_loss(rest, rest, pos, rig, pred_local_positions=shifted)
        assert float(got) == pytest.approx(0.4, rel=1e-12)


class TestRootLoss:
    def test_known_l1(self):
        true = torch.tensor([[0.02, 0.04, 0.3], [-0.01, 0.05, 0.0]], dtype=torch.float64)
        pred = true + torch.tensor([0.1, -0.2, 0.3], dtype=torch.float64)
        assert float(root_loss(true, true)) == 0.0
        assert float(root_loss(pred, true)) == pytest.approx(0.6)

    def test_shape_checked(self):
        with pytest.raises(ValueError, match="root features"):
            root_loss(torch.zeros(2, 3), torch.zeros(2, 4))


@pytest.fixture
def config(small_config) -> GaitConfig:
    return dataclasses.replace(
        small_config, motion_weight=0.5, pose_weight=2.0, affective_weight=3.0, root_weight=4.0,
        foot_contact_weight=5.0, versor_weight=0.1,
    )


def prediction(skeleton, shape, seed):
    q, pos, _ = random_pose(skeleton, shape, seed=seed)
    root = torch.from_numpy(np.random.default_rng(seed).normal(0, 0.1, (*shape, 3)))
    return q, pos, root


class TestGaitLoss:
    def test_zero_at_truth(self, config, rig, skeleton):
        q, pos, root = prediction(skeleton, (2, 3), 11)
        total, terms = GaitLoss(config, rig)(GaitOutputs(q, q, root), q, root, pos)
        assert float(total) == pytest.approx(0.0, abs=1e-18)
        assert set(terms) == {"motion", "pose", "affective", "root", "foot_contact", "total"}
        assert all(v == pytest.approx(0.0, abs=1e-18) for v in terms.values())

    def test_total_is_the_weighted_sum_of_the_terms(self, config, rig, skeleton):
        true_q, pos, true_root = prediction(skeleton, (2, 3), 12)
        q, _, root = prediction(skeleton, (2, 3), 13)
        raw = 1.3 * q
        total, terms = GaitLoss(config, rig)(GaitOutputs(q, raw, root), true_q, true_root, pos)
        expected = {
            "motion": motion_loss(raw, true_q, rig.euler_orders, 0.1),
            "pose": pose_loss(q, true_q, pos, rig),
            "affective": affective_loss(q, true_q, pos, rig),
            "root": root_loss(root, true_root),
            "foot_contact": foot_contact_loss(q, true_q, pos, rig),
        }
        for name, value in expected.items():
            assert terms[name] == pytest.approx(float(value), rel=1e-12), name
            assert float(value) > 0, name
        weights = {"motion": 0.5, "pose": 2.0, "affective": 3.0, "root": 4.0,
                   "foot_contact": 5.0}
        weighted = sum(weights[k] * float(v) for k, v in expected.items())
        assert float(total) == pytest.approx(weighted, rel=1e-12)
        assert terms["total"] == pytest.approx(weighted, rel=1e-12)

    @pytest.mark.parametrize(("switch", "term"), [("use_affective", "affective"),
                                                  ("use_root_loss", "root")])
    def test_ablation_switches_drop_their_term(self, config, rig, skeleton, switch, term):
        true_q, pos, true_root = prediction(skeleton, (3,), 14)
        q, _, root = prediction(skeleton, (3,), 15)
        outputs = GaitOutputs(q, q, root)
        full_total, full = GaitLoss(config, rig)(outputs, true_q, true_root, pos)
        ablated = GaitLoss(dataclasses.replace(config, **{switch: False}), rig)
        total, terms = ablated(outputs, true_q, true_root, pos)
        assert term not in terms and term not in ablated.active_terms
        assert float(total) == pytest.approx(
            float(full_total) - ablated.weights[term] * full[term], rel=1e-12)

    def test_rig_must_match_the_config(self, rig):
        with pytest.raises(ValueError, match="joints"):
            GaitLoss(GaitConfig(num_joints=22), rig)

    def test_gradients_finite_for_every_parameter(self, config, rig, skeleton):
        torch.manual_seed(0)
        net = GaitNetwork(config).double()
        outputs, _ = net(random_inputs(config, 2, 4, seed=16))
        true_q, pos, true_root = prediction(skeleton, (2, 4), 17)
        total, _ = GaitLoss(config, rig)(outputs, true_q, true_root, pos)
        total.backward()
        for name, p in net.named_parameters():
            assert p.grad is not None and torch.isfinite(p.grad).all(), name
            assert p.grad.abs().sum() > 0, name

    def test_gradients_finite_at_the_truth(self, config, rig, skeleton):
        q, pos, root = prediction(skeleton, (2, 3), 18)
        raw = q.clone().requires_grad_()
        pred_root = root.clone().requires_grad_()
        outputs = GaitOutputs(raw / raw.norm(dim=-1, keepdim=True), raw, pred_root)
        total, _ = GaitLoss(config, rig)(outputs, q, root, pos)
        total.backward()
        assert torch.isfinite(raw.grad).all() and torch.isfinite(pred_root.grad).all()

    def test_float32_network_outputs(self, small_config, rig, skeleton):
        net = GaitNetwork(small_config)
        outputs, _ = net(random_inputs(small_config, 2, 3, dtype=torch.float32))
        true_q, pos, true_root = prediction(skeleton, (2, 3), 19)
        total, _ = GaitLoss(small_config, rig)(
            outputs, true_q.float(), true_root.float(), pos.float())
        assert total.dtype == torch.float32 and torch.isfinite(total)


class TestRig:
    def test_static_top_joint_like_the_bandai_rig(self, skeleton):
        # joint_Root without channels above the Hips, which carry the translation.
        parents = np.concatenate(([-1], np.asarray(skeleton.parents) + 1))
        parents[1] = 0
        top = Skeleton(
            ("joint_Root", *skeleton.names), parents,
            np.vstack(([0.0, 0.0, 0.0], skeleton.offsets)), ((), *skeleton.channels),
            np.asarray(skeleton.end_site_parents) + 1, skeleton.end_site_offsets,
        )
        rig = GaitRig.from_skeleton(top)
        assert rig.euler_orders[0] == "" and rig.root_index == 1
        q, pos, _ = random_pose(skeleton, (2,), seed=20)
        q = torch.cat((torch.tensor([1.0, 0, 0, 0], dtype=torch.float64).expand(2, 1, 4), q), 1)
        pos = torch.cat((torch.zeros(2, 1, 3, dtype=torch.float64), pos), 1)
        # A joint without rotation channels is left out of the Euler difference.
        other = with_joint(q, 0, HALF_TURN_X)
        assert float(motion_loss(other, q, rig.euler_orders)) == pytest.approx(0.0, abs=1e-20)
        assert float(pose_loss(other, q, pos, rig)) > 0.1

    def test_inconsistent_rig_is_rejected(self, rig):
        with pytest.raises(ValueError, match="Euler orders"):
            dataclasses.replace(rig, euler_orders=rig.euler_orders[:-1])
        with pytest.raises(ValueError, match="end sites"):
            dataclasses.replace(rig, end_site_parents=(*rig.end_site_parents[:-1], 99))


class TestAmplitude:
    def test_zero_when_the_spread_matches_even_if_the_poses_differ(self, rig, skeleton):
        _, pos, root = prediction(skeleton, (2, 6), 30)
        shifted = pos + torch.tensor([0.1, -0.2, 0.3], dtype=pos.dtype)  # same spread
        assert float(amplitude_loss(shifted, pos, root[..., 0] + 1.0, root[..., 0], rig)) == (
            pytest.approx(0.0, abs=1e-12))

    def test_damped_motion_costs_its_lost_spread(self, rig, skeleton):
        q, local, root = prediction(skeleton, (1, 8), 31)
        pos = rig_positions(q, local, rig)
        r = rig.root_index
        rel = pos - pos[..., r : r + 1, :]
        damped = pos[..., r : r + 1, :] + rel.mean(1, keepdim=True) + 0.5 * (
            rel - rel.mean(1, keepdim=True))
        h = root[..., 0]
        value = float(amplitude_loss(damped, pos, 0.5 * h, h, rig))
        expected = 0.5 * (float(rel.std(1).sum()) + float(h.std(1).sum()))
        assert value == pytest.approx(expected, rel=1e-9)

    def test_only_computed_when_weighted(self, config, rig, skeleton):
        true_q, pos, true_root = prediction(skeleton, (2, 5), 32)
        q, _, root = prediction(skeleton, (2, 5), 33)
        outputs = GaitOutputs(q, q, root)
        total, terms = GaitLoss(config, rig)(outputs, true_q, true_root, pos)
        assert "amplitude" not in terms
        weighted = GaitLoss(dataclasses.replace(config, amplitude_weight=2.5), rig)
        total_a, terms_a = weighted(outputs, true_q, true_root, pos)
        assert terms_a["amplitude"] > 0 and "amplitude" in weighted.active_terms
        assert float(total_a) == pytest.approx(float(total) + 2.5 * terms_a["amplitude"],
                                               rel=1e-12)

    def test_needs_windows(self, rig):
        with pytest.raises(ValueError, match="windows"):
            amplitude_loss(torch.zeros(3, 5, 3), torch.zeros(3, 5, 3), torch.zeros(3),
                           torch.zeros(3), rig)
