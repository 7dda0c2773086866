"""The FCRBM through the registry: ``emotive fcrbm generate``'s numbers from a request."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.emotion import ALL_LABELS, EmotionSchedule
from emotive.models.api import GenerationRequest, Generator, RequestError
from emotive.models.fcrbm.generate import (
    FCRBMInputError,
    constant_context,
    generate_motion,
    load_fcrbm_model,
)
from emotive.models.registry import get_model
from emotive.paths import figure8


@pytest.fixture(scope="module")
def generator():
    return get_model("fcrbm").load("generator")


def test_valence_arousal_minus_one_is_the_command_s_one_one(generator):
    """Golden: the toolkit's (-1, -1) is ``emotive fcrbm generate --valence 1 --arousal 1``."""
    assert isinstance(generator, Generator) and generator.capabilities.valence_arousal
    schedule = EmotionSchedule.from_keyframes([{"t": 0, "valence": -1, "arousal": -1}],
                                              ALL_LABELS)
    made = generator.generate(GenerationRequest("low", schedule, 2.0, seed=0))
    model = load_fcrbm_model()
    frames = max(1, round(2.0 * model.fps))
    ref, _ = generate_motion(model, constant_context(1.0, 1.0, frames), seed=0, name="low")
    np.testing.assert_array_equal(made.motion.rotations, ref.rotations)
    np.testing.assert_array_equal(made.motion.positions, ref.positions)
    assert made.path is None and "valence/arousal [-1.0, -1.0]" in made.summary
    assert made.emotion.shape == (ref.num_frames, len(ALL_LABELS))


def test_a_label_schedule_goes_through_its_valence_arousal(generator):
    schedule = EmotionSchedule.from_keyframes([{"t": 0, "emotion": "sad"},
                                               {"t": 2, "emotion": "happy"}])
    context = generator.context(GenerationRequest("s", schedule, 2.0))
    expected = 2.0 + schedule.sample_valence_arousal(len(context), generator.model.fps)
    np.testing.assert_array_equal(context, expected)
    made = generator.generate(GenerationRequest("s", schedule, 2.0))
    np.testing.assert_allclose(made.emotion[0], schedule.weights[0])
    assert made.labels == schedule.labels


def test_options_and_requests_it_cannot_honour(generator):
    schedule = EmotionSchedule.parse("sad")
    with pytest.raises(RequestError, match="follows no path"):
        generator.generate(GenerationRequest("p", schedule, 2.0, path=figure8()))
    with pytest.raises(RequestError, match="at most 3600"):
        generator.generate(GenerationRequest("p", schedule, 4000.0))
    with pytest.raises(FCRBMInputError, match="--root must be one of"):
        get_model("fcrbm").load("generator", root="hips")
    with pytest.raises(FCRBMInputError, match="gibbs must be a whole number"):
        get_model("fcrbm").load("generator", gibbs=0)
    tuned = get_model("fcrbm").load("generator", gibbs=2, root="model")
    assert (tuned.gibbs, tuned.root) == (2, "model")
