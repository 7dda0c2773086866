"""The step's clamps on the network's root outputs (Sec. 4.3's placement): a network that
predicts far outside what it was trained on still moves its agent at most MAX_SPEED and keeps
the root height within HEIGHT_RANGE.

The trained network never predicts near these bounds, so a stub that scales its outputs is the
only way to reach them.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import load_gait_model
from emotive.models.gait.network import GaitOutputs
from emotive.models.gait.step_graph import HEIGHT_RANGE, MAX_SPEED
from emotive.paths import line


class _Runaway:
    """The model's network with its root outputs ``[h, s, delta]`` replaced by ``root``."""

    def __init__(self, network, root: tuple[float, float, float]) -> None:
        self.network = network
        self.config = network.config
        self.root = root

    def initial_state(self, *args, **kwargs) -> torch.Tensor:
        return self.network.initial_state(*args, **kwargs)

    def step(self, inputs, state):
        out, state = self.network.step(inputs, state, normalize=False)
        root = torch.tensor(self.root, dtype=out.root.dtype).expand_as(out.root)
        return GaitOutputs(out.rotations, out.raw_rotations, root), state


@pytest.fixture(scope="module")
def model():
    torch.set_num_threads(1)
    return load_gait_model()


def _walk(model, root: tuple[float, float, float], frames: int = 40) -> np.ndarray:
    """World positions ``(frames, 3)`` of one agent's mover (root joint) on a long line."""
    gen = GaitGenerator(model, network=_Runaway(model.network.float().eval(), root),
                        foot_lock=False)
    gen.add_agent(line(1000.0), "happy")
    mover = gen.graph.mover
    return np.stack([gen.step().positions[0, mover] for _ in range(frames)])


@pytest.mark.parametrize("per_frame", [1e3, 1e30])
def test_a_runaway_speed_is_clamped_to_max_speed(model, per_frame):
    roots = _walk(model, (0.0, per_frame, 0.0))
    ground = np.linalg.norm(np.diff(roots[:, [0, 2]], axis=0), axis=1)
    limit = MAX_SPEED / model.fps
    # Every frame after the first steps reaches the clamp, and none goes past it.
    assert ground.max() <= limit * (1 + 1e-5)
    np.testing.assert_allclose(ground[5:], limit, rtol=1e-3)


def test_a_negative_speed_stands_still(model):
    roots = _walk(model, (0.0, -5.0, 0.0))
    assert np.abs(np.diff(roots[:, [0, 2]], axis=0)).max() < 1e-6


@pytest.mark.parametrize(("h", "bound"), [(1e3, HEIGHT_RANGE[1]), (-1e3, HEIGHT_RANGE[0])])
def test_a_runaway_height_is_clamped(model, h, bound):
    # The same walk with the height at the bound itself: the runaway one is held there.
    at_bound = _walk(model, (bound, 0.01, 0.0))
    np.testing.assert_allclose(_walk(model, (h, 0.01, 0.0))[:, 1], at_bound[:, 1], atol=1e-6)
    inside = _walk(model, (bound / 2, 0.01, 0.0))
    assert np.abs(inside[5:, 1] - at_bound[5:, 1]).min() > 0.1
