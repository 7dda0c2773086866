"""The Local Grid Bootstrap through the registry, on synthetic clips in place of the data."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.data.emotion import DEFAULT_LABELS, EmotionSchedule
from emotive.errors import EmotionError
from emotive.models.api import GenerationRequest, Generator, RequestError
from emotive.models.lgb.bootstrap import LGBError
from emotive.models.registry import get_model
from emotive.paths import figure8


@pytest.fixture
def generator(sad_clips, monkeypatch):
    import emotive.data.clips

    monkeypatch.setattr(emotive.data.clips, "load_clips", lambda name: sad_clips)
    return get_model("lgb").load("generator", workers=1)


def test_a_request_is_what_emotive_resample_makes(generator, sad_clips):
    from emotive.models.lgb.resampler import EmotionResampler

    assert isinstance(generator, Generator) and not generator.capabilities.blends
    made = generator.generate(GenerationRequest("sad", EmotionSchedule.parse("sad"), 1.0,
                                                seed=4))
    ref = EmotionResampler.fit(sad_clips, "sad", source="bandai-namco-1").generate(
        30, 4, workers=1).motion
    np.testing.assert_array_equal(made.motion.rotations, ref.rotations)
    np.testing.assert_array_equal(made.motion.positions, ref.positions)
    assert made.labels == DEFAULT_LABELS and made.path is None
    np.testing.assert_array_equal(made.emotion, np.tile([0.0, 1.0, 0.0, 0.0], (30, 1)))
    assert made.summary.startswith("sad, seed 4: 30 frames")


def test_the_output_rate_option_resamples(sad_clips, monkeypatch):
    import emotive.data.clips

    monkeypatch.setattr(emotive.data.clips, "load_clips", lambda name: sad_clips)
    slow = get_model("lgb").load("generator", workers=1, fps=10.0)
    made = slow.generate(GenerationRequest("sad", EmotionSchedule.parse("sad"), 1.0))
    assert made.motion.fps == 10.0 and len(made.emotion) == made.motion.num_frames


def test_only_one_constant_label_is_accepted(generator):
    blend = EmotionSchedule.parse("sad=0.5,happy=0.5")
    with pytest.raises(EmotionError, match=r"request 'b' to lgb: .* blends"):
        generator.generate(GenerationRequest("b", blend, 1.0))
    change = EmotionSchedule.from_keyframes([{"t": 0, "emotion": "sad"},
                                             {"t": 1, "emotion": "happy"}])
    with pytest.raises(EmotionError, match="changes over time"):
        generator.generate(GenerationRequest("c", change, 1.0))
    with pytest.raises(RequestError, match="follows no path"):
        generator.generate(GenerationRequest("p", EmotionSchedule.parse("sad"), 1.0,
                                             path=figure8()))
    with pytest.raises(LGBError, match="fps 500"):
        get_model("lgb").load("generator", fps=500.0)
    with pytest.raises(LGBError, match="workers 0"):
        get_model("lgb").load("generator", workers=0)
