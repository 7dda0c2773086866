"""Tests of :mod:`emotive.eval.feet` on hand-built synthetic motions with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stick_figures import FPS, IDX, ROLE_MAP, standing

from emotive.eval import feet


@settings(max_examples=25, deadline=None)
@given(speed=st.floats(0.0, 3.0), direction=st.floats(-np.pi, np.pi))
def test_a_foot_sliding_in_contact_gives_its_speed(speed, direction):
    pos = standing(20)
    t = np.arange(20) / FPS
    slide = speed * t[:, None] * np.array([np.cos(direction), 0.0, np.sin(direction)])
    pos[:, [IDX["l_ankle"], IDX["l_toe"]]] += slide[:, None]
    contacts = np.ones((20, 2), dtype=bool)
    report = feet.foot_skating(pos, ROLE_MAP, FPS, contacts=contacts)
    assert report.intervals == 2 * 19
    assert report.mean_speed == pytest.approx(speed / 2, abs=1e-9)
    if abs(speed - feet.SKATE_SPEED) > 1e-6:
        assert report.ratio == (0.5 if speed > feet.SKATE_SPEED else 0.0)
    only_left = contacts & np.array([True, False])
    assert feet.foot_skating(pos, ROLE_MAP, FPS, contacts=only_left).mean_speed == pytest.approx(
        speed, abs=1e-9)


def test_rolling_over_a_planted_toe_is_not_skating():
    pos = standing(20)
    pos[:, IDX["l_ankle"]] += (np.arange(20) * 0.01)[:, None] * np.array([0.0, 1.0, 0.5])
    report = feet.foot_skating(pos, ROLE_MAP, FPS, contacts=np.ones((20, 2), dtype=bool))
    assert report.mean_speed == pytest.approx(0.0)


def test_skating_detects_contacts_batched_and_ignores_swing():
    batch = np.stack((standing(30), standing(30)))
    report = feet.foot_skating(batch, ROLE_MAP, FPS)
    np.testing.assert_array_equal(report.intervals, [58, 58])
    np.testing.assert_allclose(report.mean_speed, 0.0)
    # A foot moving fast but never in contact does not count.
    pos = standing(30)
    pos[:, IDX["r_toe"]] += (np.arange(30) * 0.1)[:, None] * np.array([1.0, 0.0, 0.0])
    report = feet.foot_skating(pos, ROLE_MAP, FPS, contacts=np.zeros((30, 2), dtype=bool))
    assert report.intervals == 0 and report.mean_speed == 0.0 and report.ratio == 0.0
    # The swing that ends in a strike is not sliding: only frame pairs both in contact count.
    pos = standing(30)
    swing = np.minimum(np.arange(30), 10) * 0.05
    pos[:, [IDX["r_ankle"], IDX["r_toe"]], 2] += swing[:, None]
    strike = np.zeros((30, 2), dtype=bool)
    strike[10:, 1] = True
    report = feet.foot_skating(pos, ROLE_MAP, FPS, contacts=strike)
    assert report.intervals == 19 and report.mean_speed == 0.0
    with pytest.raises(ValueError, match="contacts"):
        feet.foot_skating(pos, ROLE_MAP, FPS, contacts=np.zeros((29, 2), dtype=bool))


def test_ground_penetration_of_a_sinking_toe():
    pos = standing(10)
    pos[5:, IDX["r_toe"], 1] = -0.03
    pos[7, IDX["r_toe"], 1] = -0.05
    report = feet.ground_penetration(pos, ROLE_MAP)
    assert report.max == pytest.approx(0.05)
    assert report.mean == pytest.approx((4 * 0.03 + 0.05) / 40)
    assert report.ratio == pytest.approx(5 / 40)
    assert feet.ground_penetration(standing(10), ROLE_MAP).max == 0.0
