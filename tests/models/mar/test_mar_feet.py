"""The transfer's feet: skate measured beside the input's and held under it, floor kept."""

from __future__ import annotations

import numpy as np
import pytest
from mar_helpers import styled

from emotive.core.roles import resolve_roles
from emotive.eval.feet import foot_skating
from emotive.ik.floor import FLOOR_TOLERANCE, clip_floor, depth_below_floor
from emotive.models.mar.transfer import TransferResult, pin_detected_contacts, transfer_motion


def _skate(motion) -> float:
    """The evaluation suite's foot skate of a clip, m/s."""
    points = motion.positions_with_end_sites()
    return float(foot_skating(points, resolve_roles(motion.skeleton), motion.fps).mean_speed)


@pytest.mark.parametrize("style", ["proud", "sad"])
def test_the_output_skates_no_more_than_the_input_and_stays_above_its_floor(
        mar_db, mar_search, style):
    inp = styled("walk", "neutral", take=2)
    result = transfer_motion(inp, mar_db, style, search=mar_search)
    assert result.pinned
    assert result.skate == pytest.approx(_skate(result.motion), abs=1e-12)
    assert result.input_skate == pytest.approx(_skate(inp), abs=1e-12)
    assert result.skate <= result.input_skate + 1e-9
    assert result.feet_summary() == (f"foot skate {result.skate:.3f} m/s "
                                     f"(input {result.input_skate:.3f} m/s)")
    roles = resolve_roles(inp.skeleton)
    floor = clip_floor(inp.positions_with_end_sites(), roles)
    depth = depth_below_floor(result.motion.positions_with_end_sites(), roles, floor)
    assert depth.max() <= FLOOR_TOLERANCE
    # Unpinned, the stream's own feet slide (what the pins take away), and the line says so.
    raw = transfer_motion(inp, mar_db, style, search=mar_search, pin=False)
    assert raw.skate > 2 * result.skate + 0.01
    assert raw.feet_summary().endswith("; feet not pinned")


def test_feet_the_vote_missed_are_pinned_where_the_clip_plants_them():
    # A standing clip whose body drifts forward: both feet are down all along and slide.
    clip = styled("wave", "neutral", take=2)
    positions = clip.positions.copy()
    positions[:, 0, 2] += 0.05 * np.arange(clip.num_frames) / clip.fps
    drifting = clip.replace(positions=positions)
    roles = resolve_roles(drifting.skeleton)
    floor = clip_floor(drifting.positions_with_end_sites(), roles)
    before = _skate(drifting)
    assert before > 0.04
    none = np.zeros((drifting.num_frames, 2), dtype=bool)
    pinned, contacts, skate = pin_detected_contacts(drifting, none, floor)
    assert contacts.all(0).all()
    assert skate == pytest.approx(_skate(pinned), abs=1e-12)
    assert skate < 0.2 * before


def test_the_line_says_when_the_output_skates_more_than_the_input():
    motion = styled("walk", "neutral", take=2)
    contacts = np.ones((motion.num_frames, 2), dtype=bool)
    above = TransferResult(motion, contacts, [], True, 0.30, 0.25)
    assert above.feet_summary().startswith("foot skate 0.300 m/s (input 0.250 m/s): above")
    none = TransferResult(motion, contacts & False, [], False, 0.30, 0.25)
    assert none.feet_summary().endswith("feet not pinned (no planted feet found)")
