"""The style transfer on real walks of Bandai Namco dataset 1 (skipped without the data)."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.data

HELD_OUT = "dataset-1_walk_angry_002"


@pytest.fixture(scope="module")
def walks(bandai1_dir):
    from emotive.data.clips import load_clips

    return load_clips("bandai-namco-1", contents=["walk"])


def test_a_real_angry_walk_becomes_a_slower_sad_walk_and_stays_a_walk(walks):
    from emotive.models.mar.build import build_database
    from emotive.models.mar.config import MARConfig
    from emotive.models.mar.database import Example
    from emotive.models.mar.transfer import transfer_motion

    examples = [Example(c.motion, "bandai-namco-1", c.content, c.info.emotion, c.name)
                for c in walks if c.name != HELD_OUT]
    db = build_database(examples, MARConfig(datasets=("bandai-namco-1",), actions=("walk",)))
    inp = next(c.motion for c in walks if c.name == HELD_OUT)
    # Labelled input: its own style's timing is its own; whole takes of sad walks last about
    # twice as long as angry ones.
    same = transfer_motion(inp, db, "angry", input_style="angry", pin=False).motion
    sad = transfer_motion(inp, db, "sad", input_style="angry", pin=False).motion
    assert same.num_frames == pytest.approx(inp.num_frames, rel=0.25)
    assert sad.num_frames > 1.3 * inp.num_frames
    # The root still travels forward and stays at walking height.
    for out in (same, sad):
        root = out.global_positions()[:, 1]
        assert np.linalg.norm(root[-1, [0, 2]] - root[0, [0, 2]]) > 1.0
        assert 0.7 < root[:, 1].mean() < 1.1
