"""Steering rules of the crowd: who steps aside which way, and where an exit is aimed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("shapely", reason="the crowd extra is not installed")

from shapely.geometry import Polygon

from emotive.crowd.goals import EXIT_DEPTH, GoalState
from emotive.crowd.scene import Goal
from emotive.crowd.steering import (
    ONCOMING_COS,
    ONCOMING_RANGE,
    ONCOMING_WIDTH,
    OVERTAKE_RANGE,
    OVERTAKE_SPEED,
    next_corner,
    sidestep,
)

EAST, WEST, NORTH = np.array([1.0, 0.0]), np.array([-1.0, 0.0]), np.array([0.0, 1.0])


def side(ground, unit, speed=None, moving=None):
    ground = np.asarray(ground, dtype=float)
    n = len(ground)
    speed = np.ones(n) if speed is None else np.asarray(speed, dtype=float)
    moving = np.ones(n, dtype=bool) if moving is None else np.asarray(moving)
    return sidestep(ground, np.asarray(unit, dtype=float), moving, speed)


def test_two_agents_meeting_head_on_both_step_to_their_right():
    out = side([[0, 0], [3, 0.2]], [EAST, WEST])
    assert out.tolist() == [1.0, 1.0]


def test_no_side_step_for_someone_behind_beside_or_far():
    assert side([[0, 0], [-2, 0]], [EAST, WEST]).tolist() == [0.0, 0.0]
    assert side([[0, 0], [2, ONCOMING_WIDTH + 0.1]], [EAST, WEST]).tolist() == [0.0, 0.0]
    assert side([[0, 0], [ONCOMING_RANGE + 0.1, 0]], [EAST, WEST]).tolist() == [0.0, 0.0]
    assert side([[0, 0], [2, 0]], [EAST, NORTH]).tolist() == [0.0, 0.0]


def test_a_faster_agent_passes_a_slower_one_on_the_left():
    out = side([[0, 0], [OVERTAKE_RANGE - 0.5, 0]], [EAST, EAST], speed=[1.4, 0.5])
    assert out.tolist() == [-1.0, 0.0]
    same = side([[0, 0], [1, 0]], [EAST, EAST], speed=[1.0, 0.95])
    assert same.tolist() == [0.0, 0.0]
    far = side([[0, 0], [OVERTAKE_RANGE + 0.5, 0]], [EAST, EAST], speed=[1.4, 0.5])
    assert far.tolist() == [0.0, 0.0]


def test_oncoming_wins_over_passing_and_standing_agents_are_ignored():
    out = side([[0, 0], [1, 0], [3, 0.3]], [EAST, EAST, WEST], speed=[1.4, 0.4, 1.0])
    assert out[0] == 1.0
    still = side([[0, 0], [3, 0]], [EAST, WEST], moving=[True, False])
    assert still.tolist() == [0.0, 0.0]


def test_an_exit_is_aimed_at_its_nearest_point_inside():
    exit_ = ((19, 0), (20, 0), (20, 4), (19, 4))
    roam = Polygon([(0.35, 0.35), (19.65, 0.35), (19.65, 3.65), (0.35, 3.65)])
    state = GoalState(Goal("exit", polygon=exit_), np.random.default_rng(0), roam)
    state.update(np.array([5.0, 3.2]))
    x, y = state.destination
    assert not state.done
    assert x == pytest.approx(19.0 + EXIT_DEPTH, abs=1e-6)
    assert y == pytest.approx(3.2, abs=1e-6)
    state.update(np.array([19.5, 1.0]))
    assert state.done and state.finished


def test_the_next_corner_skips_corners_passed_or_reached():
    route = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 3.0], [5.0, 3.0]])
    assert next_corner(route, np.array([0.5, 0.0])).tolist() == [2.0, 0.0]
    assert next_corner(route, np.array([1.9, 0.05])).tolist() == [2.0, 3.0]
    assert next_corner(route, np.array([2.1, 1.0])).tolist() == [2.0, 3.0]
    assert next_corner(route, np.array([2.3, 3.1])).tolist() == [5.0, 3.0]
    assert next_corner(route[:2], np.array([1.9, 0.0])).tolist() == [2.0, 0.0]


def brute_side(ground, unit, moving, speed):
    """The rule of :func:`sidestep` pair by pair, for comparison."""
    out = np.zeros(len(ground))
    for i in range(len(ground)):
        oncoming = slower = False
        for j in range(len(ground)):
            if i == j or not (moving[i] and moving[j]):
                continue
            rel = ground[j] - ground[i]
            if np.hypot(*rel) > ONCOMING_RANGE:
                continue
            ahead = rel @ unit[i]
            in_way = ahead > 0 and abs(rel[0] * unit[i, 1] - rel[1] * unit[i, 0]) < ONCOMING_WIDTH
            facing = unit[j] @ unit[i]
            oncoming |= in_way and facing < ONCOMING_COS
            slower |= (in_way and ahead < OVERTAKE_RANGE and facing > -ONCOMING_COS
                       and speed[j] < speed[i] - OVERTAKE_SPEED)
        out[i] = 1.0 if oncoming else (-1.0 if slower else 0.0)
    return out


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 30))
def test_the_vectorised_rule_is_the_pairwise_rule(seed, n):
    rng = np.random.default_rng(seed)
    ground = rng.uniform(0, 6, (n, 2))
    angle = rng.choice([0.0, np.pi, np.pi / 2], n) + rng.normal(0, 0.3, n)
    unit = np.stack((np.cos(angle), np.sin(angle)), axis=1)
    moving = rng.random(n) > 0.1
    speed = rng.choice([0.44, 1.13, 1.43, 1.9], n)
    np.testing.assert_array_equal(sidestep(ground, unit, moving, speed),
                                  brute_side(ground, unit, moving, speed))
