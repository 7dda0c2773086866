"""``emotive generate``'s gait walks stand on the floor: no heel or toe sinks under it.

The committed network's stream sinks into the floor by up to 3 cm (a happy walk's toes at
push-off, a sad walk's stance); the generator lifts those feet straight up.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from emotive.core.roles import resolve_roles
from emotive.data.emotion import EmotionSchedule
from emotive.features.contacts import FOOT_ROLES
from emotive.ik.floor import FLOOR_TOLERANCE, depth_below_floor
from emotive.models.api import GenerationRequest
from emotive.models.gait.adapter import at_output_rate, model_floor
from emotive.models.gait.walks import generate_walks
from emotive.models.registry import get_model
from emotive.paths import load_path

SECONDS = 3.0


@pytest.fixture(scope="module")
def generator():
    torch.set_num_threads(1)
    return get_model("gait").load("generator")


def test_the_floor_is_where_the_standing_pose_puts_the_feet(generator):
    floor = model_floor(generator.model)
    # Heels (ankle joints) stand higher than toes, both above y = 0 and under 20 cm.
    assert floor.shape == (2, 2)
    assert (floor[:, 0] > floor[:, 1]).all() and (floor > 0).all() and (floor < 0.2).all()


@pytest.mark.parametrize("emotion", ["happy", "sad"])
def test_generated_feet_never_go_a_centimetre_below_the_floor(generator, emotion):
    schedule = EmotionSchedule.parse(emotion, generator.labels)
    made = generator.generate(GenerationRequest(emotion, schedule, SECONDS, seed=0)).motion
    roles = resolve_roles(made.skeleton)
    points = made.positions_with_end_sites()
    floor = model_floor(generator.model)
    assert depth_below_floor(points, roles, floor).max() <= FLOOR_TOLERANCE
    assert points[:, roles.indices(FOOT_ROLES), 1].min() >= -FLOOR_TOLERANCE

    # Only straight up: the stream's feet keep their ground positions (to float32
    # rounding: the stream's frames are float32), its hips stay.
    walk = generate_walks(generator.model, [load_path("figure8")], [schedule], SECONDS)[0]
    stream, _ = at_output_rate(walk.motion, walk.emotion)
    before = stream.positions_with_end_sites()
    feet = roles.indices(FOOT_ROLES)
    np.testing.assert_allclose(points[:, feet][..., [0, 2]], before[:, feet][..., [0, 2]],
                               atol=1e-6)
    np.testing.assert_array_equal(made.positions, stream.positions)


def test_raw_walks_are_the_network_as_it_is():
    raw = get_model("gait").load("generator", raw=True)
    schedule = EmotionSchedule.parse("happy", raw.labels)
    made = raw.generate(GenerationRequest("raw", schedule, 1.0, seed=0)).motion
    walk = generate_walks(raw.model, [load_path("figure8")], [schedule], 1.0, foot_lock=False)[0]
    np.testing.assert_array_equal(made.rotations, at_output_rate(walk.motion, walk.emotion)[0]
                                  .rotations)
