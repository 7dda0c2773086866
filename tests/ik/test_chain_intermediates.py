"""IK chains with intermediate joints between chain joints, on other rig families' layouts."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from aligned_frames import world_aligned

from emotive.core.rig_layouts import to_layout
from emotive.core.roles import resolve_roles
from emotive.errors import RigError
from emotive.ik import link_transforms, reconstruct, resolve_chains, solve_chains
from emotive.ik.chains import theta_from_rotations
from emotive.ik.solver import OFF_TARGET, _ChainKernel
from emotive.transforms.np_rotations import (
    axis_angle_to_quaternion,
    quaternion_apply,
    quaternion_multiply,
)
from layout_clips import bandai_clip, synthetic_clip

#: Layout -> the intermediate joints of the head-torso chain (every other chain has none).
TORSO_INTERMEDIATES = {
    "cmu": ["Neck1"],
    "mixamo": ["mixamorig:Spine1"],
    "unreal": ["spine_02", "spine_03", "spine_04", "neck_02"],
    "cmu-plain": [],
}


def _names(motion, joints) -> list[str]:
    return [motion.skeleton.names[j] for j in joints]


@pytest.mark.parametrize("layout", sorted(TORSO_INTERMEDIATES))
def test_intermediates_are_the_joints_between_chain_joints(layout):
    clip = to_layout(synthetic_clip(), layout)
    chains = resolve_chains(clip.skeleton, clip)
    torso = [n for path in chains["head_torso"].between for n in _names(clip, path)]
    assert torso == TORSO_INTERMEDIATES[layout]
    assert chains["head_torso"].has_intermediates == bool(torso)
    for name in ("left_arm", "right_arm", "left_leg", "right_leg"):
        assert not chains[name].has_intermediates
    bandai = resolve_chains(synthetic_clip().skeleton)
    assert not any(c.has_intermediates for c in bandai.values())


def test_a_chain_joint_off_the_parent_path_is_a_rig_error():
    clip = to_layout(synthetic_clip(), "cmu")
    roles = {**resolve_roles(clip.skeleton).names, "head": "LeftHand"}
    with pytest.raises(RigError, match="head_torso: LeftHand does not hang below Neck; map"):
        resolve_chains(clip.skeleton, clip, roles)


def _twisted(layout: str, seed: int = 1):
    """A synthetic clip on ``layout`` whose intermediate joints are turned (not identity)."""
    clip = to_layout(synthetic_clip(frames=8), layout)
    chains = resolve_chains(clip.skeleton, clip)
    rot = clip.rotations.copy()
    rng = np.random.default_rng(seed)
    for path in chains["head_torso"].between:
        for j in path:
            rot[:, j] = axis_angle_to_quaternion(rng.uniform(-0.3, 0.3, (len(rot), 3)))
    return clip.replace(rotations=rot), chains


def test_link_transforms_place_each_chain_joint_as_forward_kinematics_does():
    clip, chains = _twisted("unreal")
    grot, gpos = clip.global_transforms()
    parents = clip.skeleton.parents
    for chain in chains.values():
        local_pos, link_rot = link_transforms(chain, clip.rotations, clip.positions)
        prev = np.concatenate(([chain.base], chain.joints[:-1]))
        got = gpos[:, prev] + quaternion_apply(grot[:, prev], local_pos)
        np.testing.assert_allclose(got, gpos[:, chain.joints], atol=1e-12)
        if link_rot is None:
            assert not chain.has_intermediates
            continue
        turned = quaternion_multiply(grot[:, prev], link_rot)
        want = grot[:, parents[chain.joints]]
        np.testing.assert_allclose(np.abs((turned * want).sum(-1)), 1.0, atol=1e-12)


def test_the_kernel_through_intermediates_matches_forward_kinematics(rng):
    clip, chains = _twisted("unreal")
    chain = chains["head_torso"]
    t = clip.num_frames
    local_pos, link_rot = link_transforms(chain, clip.rotations, clip.positions)
    grot, gpos = clip.global_transforms()
    offsets = rng.normal(0, 0.1, (t, len(chain.targets), 3))
    nodes = torch.as_tensor(np.concatenate((gpos[:, chain.base, None], local_pos, offsets), 1))
    theta = torch.as_tensor(rng.uniform(-0.5, 0.5, (t, len(chain.joints), 3)))
    kern = _ChainKernel(chain)
    base = torch.as_tensor(grot[:, chain.base])
    link = torch.as_tensor(link_rot)
    fast = kern.points(theta, base, nodes, link)
    slow = kern.points_reference(theta, base, nodes, link)
    for a, b in zip(fast, slow, strict=True):
        np.testing.assert_allclose(a.numpy(), b.numpy(), atol=1e-12)
    plain = kern.points(theta, base, nodes)
    assert np.abs(plain[2].numpy() - fast[2].numpy()).max() > 1e-3


def test_solving_through_turned_intermediates_hits_the_targets_and_keeps_them():
    clip, chains = _twisted("unreal")
    torso = {"head_torso": chains["head_torso"]}
    points = clip.positions_with_end_sites()
    targets = {"head_torso": points[:, chains["head_torso"].targets]}
    start = clip.replace(rotations=np.where(
        np.isin(np.arange(clip.skeleton.num_joints), chains["head_torso"].joints)[None, :, None],
        np.array([1.0, 0.0, 0.0, 0.0]), clip.rotations))
    result = solve_chains(start, targets, torso, frame="world", init="neutral")
    # Random poses, frame to frame: the median frame is on target, none visibly off.
    solved = result.motion.positions_with_end_sites()[:, chains["head_torso"].targets]
    miss = np.linalg.norm(solved - targets["head_torso"], axis=-1).max(-1)
    assert np.median(miss) < 1e-3 and miss.max() < OFF_TARGET
    np.testing.assert_allclose(miss, result.residuals["head_torso"], atol=1e-9)
    middle = np.concatenate(chains["head_torso"].between)
    np.testing.assert_array_equal(result.motion.rotations[:, middle], clip.rotations[:, middle])


def test_hinge_flexion_counts_from_the_straight_limb_whatever_the_joint_frames(bandai1_dir):
    clip = bandai_clip(bandai1_dir, frames=30)
    bandai = resolve_chains(clip.skeleton, clip)
    limbs = ("left_leg", "right_leg", "left_arm", "right_arm")
    flex = {n: theta_from_rotations(bandai[n], clip.rotations[:, bandai[n].joints])[:, 1, 0]
            for n in limbs}
    # The aligned rig's rest pose is the frame with every knee and elbow most bent.
    rest = int(np.argmax(np.min([np.abs(f) for f in flex.values()], axis=0)))
    assert np.degrees(min(abs(f[rest]) for f in flex.values())) > 5.0
    other = world_aligned(to_layout(clip, "cmu"), frame=rest)
    chains = resolve_chains(other.skeleton, other)
    for name in limbs:
        chain = chains[name]
        got = theta_from_rotations(chain, other.rotations[:, chain.joints])[:, 1, 0]
        np.testing.assert_allclose(np.degrees(got), np.degrees(flex[name]), atol=1.0)


def test_reconstruct_on_cmu_frames_and_intermediates_is_as_close_as_on_bandai(bandai1_dir):
    clip = bandai_clip(bandai1_dir, frames=40)
    base = reconstruct(clip)
    other = world_aligned(to_layout(clip, "cmu"))
    result = reconstruct(other)
    assert result.motion.skeleton is other.skeleton
    for name, residual in result.residuals.items():
        assert residual.max() < 2.0 * base.residuals[name].max() + 1e-3, name
    head = other.skeleton.names.index("Head")
    bandai_head = clip.skeleton.names.index("Head")
    gap = result.motion.global_positions()[:, head] - base.motion.global_positions()[:, bandai_head]
    assert np.linalg.norm(gap, axis=-1).max() < 5e-3
