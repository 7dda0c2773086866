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

The live stream (``python -m bench.bench_fcrbm``, the committed checkpoint): foot skate of
streamed agents against real walks (:func:`stream_skate_rows`, needs the data) and the tick
times of an ``emotive serve --model fcrbm`` scene while 50 agents are added
(:func:`add_tick_rows`).
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from bench.common import comparison, median_seconds, pinned_threads, print_rows
from emotive.core.roles import resolve_roles
from emotive.data import dataset_dir
from emotive.eval.feet import foot_skating
from emotive.io.bvh import read_bvh
from emotive.models.fcrbm.generate import load_fcrbm_model
from emotive.models.fcrbm.model import FCRBM
from emotive.models.fcrbm.stream import FCRBMStream
from emotive.models.fcrbm.training import load_fcrbm_settings
from emotive.paths import figure8
from emotive.serve.engines import load_engine
from emotive.serve.messages import to_command
from emotive.serve.settings import ServeSettings
from emotive.serve.simulation import Simulation

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


# --------------------------------------------------------------------------- the live stream

#: Emotions of the streamed skate rows, and the dataset-1 styles they are compared with.
STREAM_EMOTIONS = ("happy", "sad", "angry", "neutral")


def stream_skate_rows(clips: list, agents: int = 4, seconds: float = 10.0) -> list[dict]:
    """Foot skate of FCRBM stream agents per emotion against real dataset-1 walks.

    The evaluation suite's measure (:func:`emotive.eval.feet.foot_skating`, contacts detected
    from the motion) of ``agents`` agents streamed on a figure-8 for ``seconds``, against its
    mean over the real walks of that emotion in ``clips`` (neutral: the normal walks), as
    :func:`bench.bench_gait.skate_rows` measures the gait stream.
    """
    model = load_fcrbm_model()
    rows = []
    for emotion in STREAM_EMOTIONS:
        stream = FCRBMStream(model, seed=0)
        stream.add_agents([figure8()] * agents, [emotion] * agents)
        world = np.stack([stream.step().world for _ in range(round(seconds * stream.fps))], 1)
        roles = resolve_roles(stream.skeleton)
        ours = float(np.mean([foot_skating(w, roles, stream.fps).mean_speed for w in world]))
        style = "normal" if emotion == "neutral" else emotion
        real = [read_bvh(c) for c in clips if f"_walk_{style}_" in c.name]
        base = float(np.mean([foot_skating(r.positions_with_end_sites(),
                                           resolve_roles(r.skeleton), r.fps).mean_speed
                              for r in real]))
        rows.append(comparison(f"fcrbm_stream_skate[{emotion}, suite measure]", "m/s", ours,
                               base, f"real dataset-1 {style} walks", higher_is_better=False))
        print(f"fcrbm stream skate, {emotion}: {ours:.3f} m/s against {base:.3f} real "
              f"({ours / base:.2f}x)", flush=True)
    return rows


def add_tick_rows(walking: int = 4, added: int = 50, after: float = 3.0) -> list[dict]:
    """Tick times of an ``emotive serve --model fcrbm`` scene while ``added`` agents join.

    The server's own :class:`~emotive.serve.simulation.Simulation` (in this process, frames
    discarded) with ``walking`` agents already walking; ``added`` ``add_agent`` commands,
    prepared beforehand as the server's preparer does, are submitted at once, and every
    tick from then until ``after`` seconds after the last is in the frames is kept. Rows: the p50,
    p99 and largest tick (commands, step and encoding, ms) against the 100 ms target.
    """
    class Discard:
        def frame(self, data: bytes) -> None:
            pass

        def notice(self, client: int, message: dict) -> None:
            pass

    engine = load_engine("fcrbm")
    sim = Simulation(engine, ServeSettings(model="fcrbm"), Discard())
    labels = STREAM_EMOTIONS

    def command(k: int):
        return to_command({"type": "add_agent", "path": "figure8",
                           "emotion": labels[k % len(labels)]},
                          engine.labels, engine.points_over)

    sim.start()
    try:
        for f in [sim.submit(command(k)) for k in range(walking)]:
            f.result(timeout=120)
        time.sleep(1.0)
        commands = [command(k) for k in range(added)]
        first = sim.frames
        futures = [sim.submit(c) for c in commands]
        joined = sum(f.exception(timeout=120) is None for f in futures)
        deadline = time.monotonic() + 120.0
        while getattr(engine.generator, "warming", ()) and time.monotonic() < deadline:
            time.sleep(0.05)  # deferred warm-up: until every new agent is in the frames
        time.sleep(after)
        with sim._lock:
            ticks = np.array(list(sim._steps)[-(sim.frames - first):]) * 1000.0
    finally:
        sim.stop()
    p50, p99 = np.percentile(ticks, [50, 99])
    print(f"fcrbm serve, {added} added to {walking} ({joined} joined): tick p50 {p50:.1f} ms, "
          f"p99 {p99:.1f} ms, max {ticks.max():.1f} ms over {len(ticks)} ticks", flush=True)
    name = f"fcrbm_serve_add[{added} agents to {walking}, tick"
    return [comparison(f"{name} {which}]", "ms", float(value), 100.0, "target: 100 ms",
                       higher_is_better=False)
            for which, value in (("p50", p50), ("p99", p99), ("max", ticks.max()))]


def main() -> None:
    """The stream's rows: ``python -m bench.bench_fcrbm`` (skate needs the data)."""
    d1 = sorted((dataset_dir("bandai-namco-1") / "data").glob("*.bvh"))
    with pinned_threads():
        print_rows(lambda: add_tick_rows() + stream_skate_rows(d1))


if __name__ == "__main__":
    main()
