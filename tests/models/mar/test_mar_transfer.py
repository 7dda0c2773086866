"""Streaming and whole-clip style transfer on the synthetic styles."""

from __future__ import annotations

import numpy as np
import pytest
from mar_helpers import STYLES, styled

from emotive.core.roles import BANDAI
from emotive.data.emotion import EmotionSchedule
from emotive.models.mar.config import TransferError
from emotive.models.mar.representation import RigCodec, RigMappingError
from emotive.models.mar.transfer import StyleTransfer, transfer_motion
from emotive.transforms.np_rotations import quaternion_to_axis_angle

CHEST, UPPER_ARM_L = 2, 5


def _angle(motion_or_rot, joint: int, axis: int) -> np.ndarray:
    rot = getattr(motion_or_rot, "rotations", motion_or_rot)
    return quaternion_to_axis_angle(rot[:, joint])[:, axis]


def _swing(motion) -> float:
    a = _angle(motion, UPPER_ARM_L, 0)
    return float(a.max() - a.min())


def test_neutral_to_neutral_keeps_the_input(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2)
    out = transfer_motion(inp, mar_db, "neutral", search=mar_search, pin=False).motion
    assert out.num_frames == pytest.approx(inp.num_frames, abs=4)
    n = min(out.num_frames, inp.num_frames)
    a = out.global_positions()[:n] - out.global_positions()[:n, :1] * np.array([1, 0, 1])
    b = inp.global_positions()[:n] - inp.global_positions()[:n, :1] * np.array([1, 0, 1])
    assert np.linalg.norm(a - b, axis=-1).mean() < 0.03


@pytest.mark.parametrize("style", ["proud", "sad"])
def test_neutral_walks_take_the_target_style_posture_swing_and_timing(mar_db, mar_search, style):
    inp = styled("walk", "neutral", take=2)
    target = styled("walk", style, take=2)
    result = transfer_motion(inp, mar_db, style, search=mar_search, pin=False)
    out = result.motion
    chest = _angle(out, CHEST, 0).mean()
    assert chest == pytest.approx(STYLES[style][3], abs=0.05)
    assert abs(_swing(out) - _swing(target)) < 0.3 * abs(_swing(target) - _swing(inp))
    # Slower styles stretch the clip by the ratio of tempos.
    expected = inp.num_frames / STYLES[style][0]
    assert out.num_frames == pytest.approx(expected, rel=0.1)
    assert all(f.time >= p.time for p, f in zip(result.frames, result.frames[1:], strict=False))


def test_unlabeled_input_mixes_the_classes_of_its_own_action(mar_db, mar_search):
    inp = styled("wave", "neutral", take=2, frames=40)
    result = transfer_motion(inp, mar_db, "sad", search=mar_search, pin=False)
    weights = {}
    for frame in result.frames[5:]:
        for key, w in frame.mixture.items():
            weights[key.split("/")[1]] = weights.get(key.split("/")[1], 0.0) + w
    assert weights.get("wave", 0.0) > 0.95 * sum(weights.values())
    labelled = transfer_motion(inp, mar_db, "sad", action="wave", input_style="neutral",
                               search=mar_search, pin=False)
    assert all(set(f.mixture) == {"synthetic/wave/neutral"} for f in labelled.frames)


def test_the_style_changes_live_in_the_stream(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2)
    stream = StyleTransfer(mar_db, RigCodec.for_motion(inp), "neutral", search=mar_search)
    chest = []
    for t in range(inp.num_frames):
        if t == 45:
            stream.set_style("sad=1")
        frame = stream.push(inp.rotations[t], inp.positions[t])
        assert frame.rotations.shape == (19, 4) and frame.positions.shape == (19, 3)
        chest.append(_angle(frame.rotations[None], CHEST, 0)[0])
    assert np.mean(chest[10:40]) == pytest.approx(0.0, abs=0.05)
    assert np.mean(chest[60:]) == pytest.approx(STYLES["sad"][3], abs=0.08)
    assert stream.style == {"sad": 1.0}


def test_a_schedule_blends_styles_over_time(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2)
    schedule = EmotionSchedule.from_keyframes(
        [{"t": 0, "emotion": "proud"}, {"t": 3, "emotion": "proud=0.5,sad=0.5"}], mar_db.styles)
    out = transfer_motion(inp, mar_db, schedule, search=mar_search, pin=False).motion
    chest = _angle(out, CHEST, 0)
    assert chest[:10].mean() == pytest.approx(STYLES["proud"][3], abs=0.06)
    blend = 0.5 * (STYLES["proud"][3] + STYLES["sad"][3])
    assert chest[-10:].mean() == pytest.approx(blend, abs=0.08)


def test_brute_force_and_tree_search_give_nearly_the_same_output(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2, frames=30)
    codec = RigCodec.for_motion(inp)
    fast = StyleTransfer(mar_db, codec, "proud", search=mar_search)
    slow = StyleTransfer(mar_db, codec, "proud", search=mar_search, brute_force=True)
    gap = [np.abs(fast.push(r, p).vector - slow.push(r, p).vector).max()
           for r, p in zip(inp.rotations, inp.positions, strict=True)]
    assert np.median(gap) < 0.05


def test_feet_are_pinned_where_the_output_plants_them(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2)
    result = transfer_motion(inp, mar_db, "proud", search=mar_search, pin=True)
    assert result.contacts.shape == (result.motion.num_frames, 2)
    assert result.pinned == bool(result.contacts.any())


def test_another_rig_is_retargeted_and_written_back_on_its_own_rig(mar_db, mar_search):
    rename = {"Hips": "pelvis", "LowerArm_L": "forearm_l", "UpperLeg_R": "thigh_r"}
    inp = styled("walk", "neutral", take=2, frames=45, rename=rename, scale=1.2)
    roles = {**BANDAI, "root": "pelvis", "l_elbow": "forearm_l", "r_hip": "thigh_r"}
    # The Bandai names lack the renamed joints (without a map the rig's shape names them).
    with pytest.raises(RigMappingError, match=r"synthetic_walk_neutral_2.*roles"):
        transfer_motion(inp, mar_db, "proud", role_map="bandai", search=mar_search, pin=False)
    out = transfer_motion(inp, mar_db, "proud", role_map=roles, search=mar_search,
                          pin=False).motion
    assert out.skeleton.names == inp.skeleton.names and out.skeleton.same_as(inp.skeleton)
    assert _angle(out, CHEST, 0).mean() < -0.1  # proud: chest up
    height = out.global_positions()[:, 0, 1].mean()
    assert height == pytest.approx(inp.global_positions()[:, 0, 1].mean(), rel=0.05)


def test_bad_input_raises_typed_errors_naming_it(mar_db, mar_search):
    inp = styled("walk", "neutral", take=2)
    with pytest.raises(TransferError, match=r"has 2 frames.*at least 3"):
        transfer_motion(inp.replace(rotations=inp.rotations[:2], positions=inp.positions[:2]),
                        mar_db, "proud", search=mar_search)
    rot = inp.rotations.copy()
    rot[7, 1] = np.nan
    with pytest.raises(TransferError, match="synthetic_walk_neutral_2: frame 7 holds NaN"):
        transfer_motion(inp.replace(rotations=rot), mar_db, "proud", search=mar_search)
    with pytest.raises(TransferError, match=r"unknown emotion 'prout'.*did you mean 'proud'"):
        transfer_motion(inp, mar_db, "prout", search=mar_search)
    stream = StyleTransfer(mar_db, RigCodec.for_motion(inp), "proud", search=mar_search)
    with pytest.raises(TransferError, match="input frame 0 holds NaN"):
        stream.push(rot[7], inp.positions[7])
    with pytest.raises(TransferError, match="rho"):
        StyleTransfer(mar_db, RigCodec.for_motion(inp), "proud", rho=2.0)
