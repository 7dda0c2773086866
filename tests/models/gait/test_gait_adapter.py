"""The gait network through the registry: ``emotive generate``'s walks, the Table 1 predictor."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.emotion import EmotionSchedule
from emotive.models.api import GenerationRequest, Generator, Predictor, RequestError
from emotive.models.registry import get_model
from emotive.paths import circle, load_path


@pytest.fixture(scope="module")
def generator():
    return get_model("gait").load("generator")


def test_a_request_is_what_emotive_generate_makes(generator):
    from emotive.ik.floor import keep_above_floor
    from emotive.models.gait.adapter import model_floor
    from emotive.models.gait.model import load_gait_model
    from emotive.models.gait.walks import generate_walks

    assert isinstance(generator, Generator) and generator.capabilities.paths
    schedule = EmotionSchedule.parse("happy=0.7,neutral=0.3", generator.labels)
    made = generator.generate(GenerationRequest("blend", schedule, 2.0, seed=3))
    model = load_gait_model()
    walk = generate_walks(model, [load_path("figure8")], [schedule], 2.0, seed=3)[0]
    # The stream's walk with its feet kept above the floor (tests/models/gait/test_gait_floor.py).
    expected = keep_above_floor(walk.motion, model_floor(model))
    np.testing.assert_array_equal(made.motion.rotations, expected.rotations)
    np.testing.assert_array_equal(made.motion.positions, expected.positions)
    assert made.emotion.shape == (made.motion.num_frames, len(generator.labels))
    np.testing.assert_allclose(made.emotion.sum(1), 1.0)
    assert made.path.name == "figure8" and made.labels == generator.labels
    assert made.motion.metadata["name"] == "blend" and "figure8" in made.summary


def test_the_request_path_is_followed_and_length_bounded(generator):
    schedule = EmotionSchedule.parse("sad", generator.labels)
    made = generator.generate(GenerationRequest("c", schedule, 1.0, path=circle(1.5)))
    assert made.path.name == "circle" and made.motion.num_frames == 31
    with pytest.raises(RequestError, match="at most 3600"):
        generator.generate(GenerationRequest("c", schedule, 3601.0))


def test_predictors_of_the_model_and_its_ablations():
    ours = get_model("gait").load("predictor")
    assert isinstance(ours, Predictor) and ours.name == "Ours"
    ablation = get_model("gait-no-affective").load("predictor")
    assert ablation.name == "gait-no-affective"
    assert ablation.model.source.name == "gait-no-affective.pt"
