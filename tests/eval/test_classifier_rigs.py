"""The committed classifier reads a clip alike on every rig family, unit and frame rate.

Other rigs are built by the project's own code from a real held-out walk
(:func:`emotive.core.rig_layouts.to_layout`, written to BVH in the family's unit and read back
with the unit detected); the classifier reads joints only (hand tips at the wrists, toes at the
toe joint), which every family places alike, so the calibrated probabilities must stay within
0.02 and the walk must not read as unsure. Random rig variants: ``test_judge_invariance.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from emotive.core.ops import resample
from emotive.core.rig_layouts import LAYOUTS, to_layout
from emotive.eval.classifier import load_default_classifier
from emotive.io.bvh import read_bvh, write_bvh

#: A dataset-1 walk of the test split (never trained on).
HELD_OUT = "dataset-1_walk_angry_002"


@pytest.fixture(scope="module")
def judged_walk(bandai1_dir):
    model = load_default_classifier()
    walk = read_bvh(bandai1_dir / "data" / f"{HELD_OUT}.bvh")
    return model, walk, model.judge(walk)


@pytest.mark.data
@pytest.mark.parametrize("layout", LAYOUTS)
def test_every_rig_family_reads_alike(judged_walk, layout, tmp_path):
    model, walk, base = judged_walk
    path = write_bvh(to_layout(walk, layout), tmp_path / f"{layout}.bvh")
    other = read_bvh(path)
    assert other.skeleton.names != walk.skeleton.names
    judged = model.judge(other)
    assert len(judged.times) == len(base.times)
    assert np.abs(judged.probabilities - base.probabilities).max() <= 0.02
    assert not judged.clip_unsure


@pytest.mark.data
@pytest.mark.parametrize("fps", [24.0, 60.0, 120.0])
def test_frame_rates_read_alike(judged_walk, fps):
    model, walk, base = judged_walk
    judged = model.judge(resample(walk, fps))
    assert np.abs(judged.probabilities.mean(0) - base.probabilities.mean(0)).max() <= 0.1
    assert not judged.clip_unsure
