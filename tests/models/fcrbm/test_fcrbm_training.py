"""CD training on a synthetic context-controlled oscillator, then generation at two contexts.

The data: 2D rotations whose angular step is set by the second context value ("arousal",
1..3 as in the paper): ``ω = 0.15 + 0.15 (arousal − 1)``, so 0.15 rad/frame at arousal 1 and
0.45 at arousal 3. The model can only reproduce it if the context gates the dynamics.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from emotive.models.fcrbm.config import FCRBMConfig
from emotive.models.fcrbm.model import FCRBM, sliding_windows

ORDER = 3
VALENCE = 2.0


def angular_step(arousal: float) -> float:
    return 0.15 + 0.15 * (arousal - 1.0)


def oscillator(arousal: float, frames: int, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(frames)
    phase = rng.uniform(0, 2 * np.pi)
    angle = angular_step(arousal) * t + phase
    # √2 makes each coordinate unit-variance, the standardized data the model assumes.
    x = math.sqrt(2) * np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return x + 0.02 * rng.standard_normal(x.shape)


def mean_angular_step(frames: torch.Tensor) -> float:
    """Mean signed angle between consecutive 2D frames ``(B, T, 2)``."""
    a, b = frames[:, :-1], frames[:, 1:]
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return float(torch.atan2(cross, (a * b).sum(-1)).mean())


def one_step_error(model: FCRBM, v, past, z) -> float:
    """Squared error of the frame generated from the true past, per value."""
    pred = model.generate(past, z, steps=1, gibbs=5, generator=torch.Generator().manual_seed(0))
    return float(((pred[:, 0] - v) ** 2).mean())


@pytest.fixture(scope="module")
def trained():
    rng = np.random.default_rng(0)
    parts = []
    for arousal in (1.0, 2.0, 3.0):
        for _ in range(4):
            x = torch.tensor(oscillator(arousal, 150, rng), dtype=torch.float32)
            z = torch.tensor([[VALENCE, arousal]], dtype=torch.float32).expand(150, 2)
            parts.append(sliding_windows(x, z, ORDER))
    v, past, z = (torch.cat(p) for p in zip(*parts, strict=True))
    cfg = FCRBMConfig(
        visible=2, order=ORDER, hidden=16, factors=16, factors_past_visible=16,
        factors_past_hidden=16, learning_rate=0.01, momentum=0.9, weight_decay=0.0,
        gibbs=10, init_std=0.1, seed=0,
    )  # fmt: skip
    model = FCRBM(cfg)
    before = one_step_error(model, v, past, z)
    g = torch.Generator().manual_seed(1)
    recon = []
    for _ in range(25):
        perm = torch.randperm(len(v), generator=g)
        for i in range(0, len(v), 50):
            idx = perm[i : i + 50]
            recon.append(model.train_step(v[idx], past[idx], z[idx], generator=g))
    return model, (v, past, z), before, recon


def test_training_lowers_one_step_and_reconstruction_errors(trained) -> None:
    model, (v, past, z), before, recon = trained
    after = one_step_error(model, v, past, z)
    assert after < 0.05 * before, (before, after)
    # Predicting the next frame from the past alone must beat repeating the last frame.
    hold = float(((past[:, -1] - v) ** 2).mean())
    assert after < 0.2 * hold, (hold, after)
    assert np.mean(recon[-10:]) < 0.1 * np.mean(recon[:10])


def test_context_controls_generated_frequency_and_energy(trained) -> None:
    model, (_, past, _), _, _ = trained
    seeds = past[[0, 300]]  # arousal-1 windows: the context alone must speed the motion up
    out = {}
    for arousal in (1.0, 3.0):
        ctx = torch.tensor([[VALENCE, arousal]]).expand(2, 2)
        out[arousal] = model.generate(
            seeds, ctx, steps=150, generator=torch.Generator().manual_seed(0)
        )
        assert torch.isfinite(out[arousal]).all()
    slow, fast = mean_angular_step(out[1.0]), mean_angular_step(out[3.0])
    assert slow == pytest.approx(angular_step(1.0), abs=0.05)
    assert fast == pytest.approx(angular_step(3.0), abs=0.05)
    energy = {a: float((x.diff(dim=1) ** 2).sum(-1).mean()) for a, x in out.items()}
    assert energy[3.0] > 2 * energy[1.0], energy


def test_context_can_change_every_frame(trained) -> None:
    model, (_, past, _), _, _ = trained
    ctx = torch.empty(200, 1, 2)
    ctx[:, :, 0] = VALENCE
    ctx[:100, :, 1] = 1.0
    ctx[100:, :, 1] = 3.0
    out = model.generate(past[:1], ctx, generator=torch.Generator().manual_seed(0))
    first, second = mean_angular_step(out[:, 10:100]), mean_angular_step(out[:, 110:])
    assert second > first + 0.2, (first, second)
