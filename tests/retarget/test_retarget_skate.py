"""Feet stay planted through retargeting: skate on the target no worse than on the source.

Skate is the suite's measure (:func:`emotive.eval.feet.foot_skating`) over the intervals in
which the source's feet are planted (:func:`emotive.features.contacts.foot_contacts` of the
source), on the Mixamo-named rig in centimetres of :func:`retarget_helpers.mixamo_cm_rig`.
"""

from __future__ import annotations

import numpy as np
import pytest
from retarget_helpers import mixamo_cm_rig, walk

from cli_helpers import invoke_command
from emotive.commands.generate import generate
from emotive.core.roles import resolve_roles
from emotive.eval.feet import foot_skating
from emotive.features.contacts import foot_contacts
from emotive.io.bvh import read_bvh
from emotive.retarget import retarget
from emotive.retarget.feet import plant_feet

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
