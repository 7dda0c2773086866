"""FCRBM speed: generation with multiplied-out factors, and training time per epoch.

FCRBM speed: generation with the factors multiplied out against through the factors, and
training time per epoch at the config's sizes against the paper's.

Generation, ours: :meth:`emotive.models.fcrbm.model.FCRBM.generate`, which multiplies the
three-way weights out once per context (:meth:`~emotive.models.fcrbm.model.FCRBM.context_weights`)
so that each Gibbs half-step is one ``D x H`` product per agent. Baseline: the same chain (same
biases, same samples, same mean-field last step) with every half-step through the factors,
``F (D + H)`` products per agent, as the model is written. Both with a constant context, the
issue's case of 1 and 20 agents at 30 fps (real time for 20 agents is 600 agent-frames/s).

Training: seconds per mini-batch of 100 frames of CD-1 (``train_step``) times the mini-batches
of an epoch of ``configs/fcrbm.toml`` (41,514 examples with its context balancing), for the
config's sizes against the paper's (order 6, 400 hidden, 300 factors each, with the
past-to-visible term).

Weights are random (the speed does not depend on them), so no data or checkpoint is needed.
One torch thread, as in the gait benchmark.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import torch

from bench.common import comparison, median_seconds
from emotive.models.fcrbm.model import FCRBM
from emotive.models.fcrbm.training import load_fcrbm_settings

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "fcrbm.toml"
#: Visible units of the Bandai walks after the codec drops the constant dimensions.
VISIBLE = 55
#: Examples in an epoch of ``configs/fcrbm.toml`` (with ``balance_contexts``).
EPOCH_EXAMPLES = 41_514


def factored_generate(net: FCRBM, past: torch.Tensor, context: torch.Tensor,
                      generator: torch.Generator) -> torch.Tensor:
    """The baseline: :meth:`FCRBM.generate` with every Gibbs half-step through the factors.

    Args:
        net: the trained model.
        past: ``(B, N, D)`` seed frames.
        context: ``(T, B, C)`` context per frame.
        generator: random generator of the Gibbs samples.

    Returns:
        ``(B, T, D)`` frames.
    """
    window, batch, gibbs = past.clone(), past.shape[0], net.config.gibbs
    frames = []
    for z in net.features(context):
        a_hat, b_hat = net._biases(window.reshape(batch, -1), z)
        zf = z @ net.w_ctx
        v = window[:, -1]
        for it in range(gibbs):
            prob = torch.sigmoid(net._hidden_input(v, zf, b_hat))
            h = prob if it == gibbs - 1 else torch.bernoulli(prob, generator=generator)
            v = net._visible_mean(h, zf, a_hat)
        frames.append(v)
        window = torch.cat([window[:, 1:], v[:, None]], dim=1)
    return torch.stack(frames, 1)


def run(agents: tuple[int, ...] = (1, 20), frames: int = 30, repeats: int = 3) -> list[dict]:
    """Generation rates (agent-frames/s) per agent count and seconds per training epoch."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        return _run(agents, frames, repeats)
    finally:
        torch.set_num_threads(threads)


def _run(agents: tuple[int, ...], frames: int, repeats: int) -> list[dict]:
    config, settings = load_fcrbm_settings(CONFIG)
    config = replace(config, visible=VISIBLE)
    net = FCRBM(config).requires_grad_(False)
    sizes = f"order {config.order}, {config.hidden} hidden, {config.factors} factors"
    out = []
    for n in agents:
        past = torch.zeros(n, config.order, VISIBLE)
        context = torch.full((frames, n, config.context), 2.0)
        ours = median_seconds(
            lambda p=past, z=context: net.generate(p, z, generator=torch.Generator()),
            repeats=repeats)
        base = median_seconds(
            lambda p=past, z=context: factored_generate(net, p, z, torch.Generator()),
            repeats=repeats)
        out.append(comparison(f"fcrbm_generate[{n} agents, {sizes}]", "agent-frames/s",
                              n * frames / ours, n * frames / base, "through the factors"))
        print(f"fcrbm generation, {n} agents: {n * frames / ours:,.0f} agent-frames/s "
              f"({n * frames / base:,.0f} through the factors)", flush=True)
    paper = replace(config, order=6, hidden=400, factors=300, factors_past_visible=300,
                    factors_past_hidden=300, visible_autoregression=True)
    epoch = {}
    for name, cfg in (("config", config), ("paper", paper)):
        model = FCRBM(cfg)
        gen = torch.Generator().manual_seed(0)
        v = torch.randn(settings.batch_size, VISIBLE, generator=gen)
        past = torch.randn(settings.batch_size, cfg.order, VISIBLE, generator=gen)
        z = torch.full((settings.batch_size, cfg.context), 2.0)
        step = median_seconds(
            lambda m=model, v=v, p=past, z=z, g=gen: m.train_step(v, p, z, g),
            repeats=5 * repeats)
        epoch[name] = step * -(-EPOCH_EXAMPLES // settings.batch_size)
    out.append(comparison(f"fcrbm_train_epoch[{sizes}, CD-{config.cd_steps}]", "s/epoch",
                          epoch["config"], epoch["paper"],
                          "the paper's sizes (order 6, 400 hidden, 300 factors)",
                          higher_is_better=False))
    print(f"fcrbm training: {epoch['config']:.1f} s per epoch ({epoch['paper']:.1f} s at the "
          "paper's sizes)", flush=True)
    return out
