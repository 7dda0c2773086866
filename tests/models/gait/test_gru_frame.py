"""FrameGRU against torch's GRU over one frame."""

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from emotive.models.gait.gru_frame import FrameGRU


@settings(max_examples=25, deadline=None)
@given(layers=st.integers(1, 3), batch=st.integers(1, 9), width=st.integers(1, 12),
       inputs=st.integers(1, 12), seed=st.integers(0, 2**31 - 1))
def test_one_frame_matches_torch_gru(layers, batch, width, inputs, seed):
    torch.manual_seed(seed)
    gru = torch.nn.GRU(inputs, width, num_layers=layers, batch_first=True).double()
    x = torch.randn(batch, 1, inputs, dtype=torch.float64)
    state = torch.randn(layers, batch, width, dtype=torch.float64)
    want, want_state = gru(x, state)
    got, got_state = FrameGRU(gru)(x, state)
    assert got.shape == want.shape and got_state.shape == want_state.shape
    torch.testing.assert_close(got, want, rtol=1e-10, atol=1e-10)
    torch.testing.assert_close(got_state, want_state, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("kwargs", [{"bidirectional": True}, {"bias": False},
                                    {"batch_first": False}])
def test_other_grus_are_refused(kwargs):
    settings = {"batch_first": True, **kwargs}
    with pytest.raises(ValueError, match="unidirectional, batch_first GRU with biases"):
        FrameGRU(torch.nn.GRU(3, 4, **settings))
