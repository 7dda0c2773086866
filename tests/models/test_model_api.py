"""The model contract: request checks against capabilities, and the protocols."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from emotive.data.emotion import DEFAULT_LABELS, Emotion, EmotionSchedule
from emotive.errors import EmotionError
from emotive.eval.table1 import ZeroVelocity
from emotive.models.api import (
    Capabilities,
    Generated,
    GenerationRequest,
    Generator,
    Predictor,
    RequestError,
    check_request,
)
from emotive.paths import figure8

FREE = Capabilities(paths=False, blends=False, schedules=False, valence_arousal=False,
                    primer=False, max_seconds=60.0)


def _request(emotion: str = "happy", **kw) -> GenerationRequest:
    return GenerationRequest("r", EmotionSchedule.constant(Emotion.parse(emotion)), **kw)


def test_a_request_within_the_capabilities_passes():
    check_request(_request(seconds=60.0), "m", FREE)


@pytest.mark.parametrize("seconds", [0.0, -1.0, 61.0, float("nan"), True])
def test_bad_lengths_name_the_request_and_the_bound(seconds):
    with pytest.raises(RequestError, match=r"request 'r' to m: seconds .* at most 60"):
        check_request(_request(seconds=seconds), "m", FREE)


def test_paths_primers_blends_and_schedules_beyond_the_capabilities(random_motion):
    with pytest.raises(RequestError, match="follows no path"):
        check_request(_request(seconds=1.0, path=figure8()), "m", FREE)
    with pytest.raises(RequestError, match="no primer"):
        check_request(_request(seconds=1.0, primer=random_motion()), "m", FREE)
    with pytest.raises(EmotionError, match="blends"):
        check_request(_request("happy=0.5,sad=0.5", seconds=1.0), "m", FREE)
    schedule = EmotionSchedule.from_keyframes([{"t": 0, "emotion": "sad"},
                                               {"t": 1, "emotion": "happy"}])
    with pytest.raises(EmotionError, match="changes over time"):
        check_request(GenerationRequest("r", schedule, 1.0), "m", FREE)


def test_the_protocols_are_runtime_checkable(random_motion):
    assert isinstance(ZeroVelocity(), Predictor)

    class Still:
        name = "still"
        labels = DEFAULT_LABELS
        capabilities = FREE

        def generate(self, request, progress=False):
            motion = random_motion(frames=3)
            return Generated(motion, np.tile(request.schedule.weights[0], (3, 1)),
                             request.schedule.labels)

    assert isinstance(Still(), Generator)
    made = Still().generate(_request(seconds=1.0))
    assert made.emotion.shape == (3, 4) and made.path is None and made.summary == ""


def test_importing_the_contract_loads_no_numpy_or_torch():
    code = ("import sys, emotive.models.api, emotive.models.registry; "
            "print(sorted(m for m in ('numpy', 'torch') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"
