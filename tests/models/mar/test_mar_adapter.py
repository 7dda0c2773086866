"""MAR style transfer through the contract, on the synthetic database."""

from __future__ import annotations

import numpy as np
import pytest
from mar_helpers import styled

from emotive.data.emotion import EmotionSchedule
from emotive.errors import EmotionError
from emotive.models.api import TransferModel
from emotive.models.mar.adapter import MARTransfer, load_transfer
from emotive.models.mar.config import TransferError
from emotive.models.mar.transfer import transfer_motion


def test_a_transfer_is_what_emotive_transfer_makes(mar_db):
    model = MARTransfer(mar_db, rho=0.5)
    assert isinstance(model, TransferModel) and model.labels == mar_db.styles
    inp = styled("walk", "neutral", take=2)
    style = EmotionSchedule.parse("proud", ("neutral", "proud"))
    made = model.transfer(inp, style)
    ref = transfer_motion(inp, mar_db, "proud", rho=0.5).motion
    np.testing.assert_array_equal(made.motion.rotations, ref.rotations)
    np.testing.assert_array_equal(made.motion.positions, ref.positions)
    assert made.labels == ("neutral", "proud")
    np.testing.assert_array_equal(made.emotion, np.tile([0.0, 1.0], (ref.num_frames, 1)))
    assert "proud" in made.summary


def test_a_schedule_and_styles_the_index_lacks(mar_db):
    model = MARTransfer(mar_db)
    inp = styled("walk", "neutral", take=2)
    schedule = EmotionSchedule.from_keyframes(
        [{"t": 0, "emotion": "neutral"}, {"t": 1, "emotion": "sad"}], ("neutral", "sad"))
    made = model.transfer(inp, schedule)
    ref = transfer_motion(inp, mar_db, schedule.relabel(mar_db.styles)).motion
    np.testing.assert_array_equal(made.motion.rotations, ref.rotations)
    assert made.emotion[0, 0] == 1.0 and made.emotion[-1, 1] == 1.0
    with pytest.raises(EmotionError, match="angry"):
        model.transfer(inp, EmotionSchedule.parse("angry"))


def test_a_missing_index_file_names_it(tmp_path):
    with pytest.raises(TransferError, match=r"missing\.npz does not exist"):
        load_transfer(weights=tmp_path / "missing.npz")
    with pytest.raises(TransferError, match="give the index once"):
        load_transfer(weights="a.npz", index="b.npz")
