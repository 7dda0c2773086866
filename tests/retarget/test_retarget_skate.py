"""Feet stay planted through retargeting: skate on the target no worse than on the source.

Two measures, on the Mixamo-named rig in centimetres of :func:`retarget_helpers.mixamo_cm_rig`:
the suite's (:func:`emotive.eval.feet.foot_skating`) over the intervals in which the source's
feet are planted (:func:`emotive.features.contacts.foot_contacts` of the source), and the one
``emotive retarget`` prints (:func:`emotive.retarget.feet.foot_skate`: every heel and toe
while it is near its own floor, so a target toe that scuffs the floor counts).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from retarget_helpers import mixamo_cm_rig, walk

from cli_helpers import invoke_command
from emotive.commands.generate import generate
from emotive.commands.retarget import retarget as retarget_command
from emotive.core import Motion
from emotive.core.roles import resolve_roles
from emotive.eval.feet import foot_skating
from emotive.features.contacts import FOOT_ROLES, foot_contacts, ground_heights
from emotive.io.bvh import read_bvh, write_bvh
from emotive.retarget import retarget
from emotive.retarget.feet import SKATE_HEIGHT, foot_skate, plant_feet

#: Most the target's skate may exceed the source's (the legs scale it by about 6 %).
RATIO = 1.1


def _skate(motion, contacts) -> float:
    roles = resolve_roles(motion.skeleton)
    return float(foot_skating(motion.positions_with_end_sites(), roles, motion.fps,
                              contacts).mean_speed)


def _ratio(source) -> float:
    contacts = foot_contacts(source.positions_with_end_sites(), resolve_roles(source.skeleton),
                             source.fps)
    moved = retarget(source, mixamo_cm_rig())
    assert moved.skeleton.names[0] == "mixamorig:Hips"
    return _skate(moved, contacts) / _skate(source, contacts)


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """A 10 s generated walk (the gait network, seed 0)."""
    out = tmp_path_factory.mktemp("walk") / "walk.bvh"
    result = invoke_command("generate", generate, "--seconds", "10", "--out", out)
    assert result.exit_code == 0, result.output
    return read_bvh(out)


def test_a_generated_walk_keeps_its_skate_on_a_mixamo_rig(generated):
    # Before the two-bone stance fix: 2.6 times the source's on a 20 s walk.
    assert _ratio(generated) <= RATIO


def test_a_real_walk_keeps_its_skate_on_a_mixamo_rig(bandai1_dir):
    assert _ratio(walk(bandai1_dir, "normal", 6.0)) <= RATIO


def _printed_ratio(source, tmp_path) -> float:
    """The skate ratio of ``emotive retarget``'s summary line, onto the Mixamo-like rig."""
    rig = mixamo_cm_rig()
    rest = np.zeros((1, rig.num_joints, 4))
    rest[..., 0] = 1.0
    write_bvh(source, tmp_path / "source.bvh")
    write_bvh(Motion(rig, rest, rig.offsets[None].copy(), 30.0), tmp_path / "rig.bvh",
              unit="cm")
    result = invoke_command("retarget", retarget_command, tmp_path / "source.bvh", "--to",
                            tmp_path / "rig.bvh", "--out", tmp_path / "out.bvh")
    assert result.exit_code == 0, result.output
    before, after = (float(x) for x in
                     re.search(r"foot skate ([\d.]+) -> ([\d.]+) m/s", result.output).groups())
    assert after == pytest.approx(foot_skate(read_bvh(tmp_path / "out.bvh")), abs=2e-3)
    return after / before


def test_the_skate_retarget_prints_stays_within_the_source_s(generated, tmp_path):
    # Before the clearance lift: 1.20x (toes of the longer feet scuffing the floor).
    assert _printed_ratio(generated, tmp_path) <= RATIO


def test_the_skate_retarget_prints_on_a_real_walk(bandai1_dir, tmp_path):
    assert _printed_ratio(walk(bandai1_dir, "normal", 6.0), tmp_path) <= RATIO


def test_target_feet_touch_the_floor_about_as_often_as_the_source_s(generated):
    """The lift keeps the target's toes off the floor in the swing, not off their plants."""
    moved = retarget(generated, mixamo_cm_rig())
    grounded = [(ground_heights(m.positions_with_end_sites()[
        :, resolve_roles(m.skeleton).indices(FOOT_ROLES)]) < SKATE_HEIGHT).sum(0)
        for m in (generated, moved)]
    assert np.all(grounded[1] >= 0.75 * grounded[0]), grounded
    assert np.all(grounded[1] <= 1.1 * grounded[0]), grounded


def test_planted_heels_land_on_their_targets(generated):
    """During each source contact the target heel moves as the source's does, scaled."""
    rig = mixamo_cm_rig()
    src_roles = resolve_roles(generated.skeleton)
    src = generated.positions_with_end_sites()
    contacts = foot_contacts(src, src_roles, generated.fps)
    moved = retarget(generated, rig)
    scale = moved.metadata["leg_scale"]
    heel = moved.positions_with_end_sites()[:, resolve_roles(moved.skeleton).index["l_ankle"]]
    source_heel = src[:, src_roles.index["l_ankle"]]
    planted = np.flatnonzero(contacts[1:, 0] & contacts[:-1, 0])
    step = np.diff(heel[:, [0, 2]], axis=0)[planted]
    wanted = scale * np.diff(source_heel[:, [0, 2]], axis=0)[planted]
    assert len(planted) > 30
    np.testing.assert_allclose(step, wanted, atol=1e-6)


def test_feet_that_already_follow_the_source_are_left_alone(generated):
    points = generated.positions_with_end_sites()
    roles = resolve_roles(generated.skeleton)
    contacts = foot_contacts(points, roles, generated.fps)
    same = plant_feet(generated, points, roles, contacts, 1.0)
    np.testing.assert_array_equal(same.rotations, generated.rotations)
