"""Data-parallel training: N gloo processes against one, at the same global batch and seed.

Usage: ``python -m bench.bench_ddp [--repeats 2] [--nproc 2] [--models gait classifier]
[--max-clips 0] [--classifier-epochs 20] [--out bench/results/bench_ddp.json]``. Needs the
Bandai Namco data.

Every run starts fresh processes with :func:`emotive.models.distributed.launch`, the path of
``emotive train gait --nproc N``: ``N`` processes of one torch thread each, against one process
of one thread (the documented ``OMP_NUM_THREADS=1 emotive train gait``) and one process with a
thread per CPU. Each process loads its own data, as the command does.

* Gait network: one epoch of ``configs/gait.toml`` (seed 0; ``--max-clips`` for fewer batches).
  Compared: the epoch's training and validation totals and its seconds (``log.csv``: the
  updates and the validation, without start-up and data loading, which are in the wall time).
* Classifier: ``configs/classifier.toml`` for ``--classifier-epochs`` epochs (its 20).
  Compared: the loss after the first epoch on 20 fixed training batches (dropout off; the
  training loss's three terms), the validation balanced accuracy at the end, and the epochs'
  seconds (updates and process 0's validation; the calibration after training is process 0's
  alone and left out).

Numbers are medians of ``--repeats`` runs; the load average before each run is recorded, as the
machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from bench.common import comparison, machine_info, write_record
from emotive.configs import resolve_config
from emotive.eval import classifier_training as ct
from emotive.models.distributed import available_cpus, current_world, launch
from emotive.models.gait.training import load_gait_settings, train_gait

HERE = Path(__file__).resolve().parent
#: Fixed training batches the classifier's loss is measured on, and their seed.
PROBE_BATCHES = 20
PROBE_SEED = 12345
#: What the benchmark trains.
MODELS = ("gait", "classifier")


def _gait_run(max_clips: int, nproc: int, threads: int) -> dict:
    """One epoch of the gait recipe on ``nproc`` processes of ``threads`` threads."""
    config, settings = load_gait_settings(resolve_config("gait"))
    settings = replace(settings, epochs=1, max_clips=max_clips)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        result = launch(train_gait, (config, settings),
                        {"progress": False, "out_dir": Path(out), "seed": 0}, nproc,
                        threads=threads)
        wall = time.perf_counter() - start
    row = result.history[0]
    return {"nproc": nproc, "threads": threads, "load_before": load, "wall_seconds": wall,
            "epoch_seconds": row["seconds"], "train_total": row["train_total"],
            "val_total": row["val_total"]}


def _probe_loss(model, sampler, rng: np.random.Generator) -> float:
    """The classifier's training loss, dropout off, on :data:`PROBE_BATCHES` fixed batches."""
    cfg = model.config
    label_loss = torch.nn.CrossEntropyLoss(
        weight=torch.tensor(sampler.label_weight, dtype=torch.float32), ignore_index=-1)
    style_loss = torch.nn.CrossEntropyLoss(ignore_index=-1)
    total = 0.0
    model.net.eval()
    with torch.no_grad():
        for _ in range(PROBE_BATCHES):
            x, y, style, va = sampler.draw(rng, cfg.batch_size)
            _, logits, va_out, style_out = model.net.heads(
                torch.from_numpy((x - model.mean) / model.std))
            y, style = torch.from_numpy(y), torch.from_numpy(style)
            loss = cfg.valence_arousal_weight * ((va_out - torch.from_numpy(va)) ** 2).mean()
            if (y >= 0).any():
                loss = loss + label_loss(logits, y)
            if (style >= 0).any():
                loss = loss + cfg.style_weight * style_loss(style_out, style)
            total += float(loss)
    return total / PROBE_BATCHES


def classifier_job(epochs: int) -> dict:
    """The classifier recipe in one of the processes: its data, training and measurements.

    The epochs are timed, and the loss measured after the first, by wrapping the trainer's
    epoch in this process.
    """
    cfg = replace(ct.read_config(resolve_config("classifier")), epochs=epochs)
    data = ct.split_features(ct.load_tracks(cfg.datasets), cfg)
    world, seconds, losses = current_world(), [], []
    epoch = ct._train_epoch

    def timed(model, sampler, *args):
        start = time.perf_counter()
        score = epoch(model, sampler, *args)
        seconds.append(time.perf_counter() - start)
        if world.is_main and len(seconds) == 1:
            losses.append(_probe_loss(model, sampler, np.random.default_rng(PROBE_SEED)))
        return score

    ct._train_epoch = timed
    start = time.perf_counter()
    model = ct.train_classifier(cfg, data=data)
    return {"epoch_seconds": sum(seconds), "train_seconds": time.perf_counter() - start,
            "loss_after_epoch_1": losses[0] if losses else None,
            "val_balanced_accuracy": (model.metrics["val"]["balanced_accuracy"]
                                      if world.is_main else None)}


def _classifier_run(epochs: int, nproc: int, threads: int) -> dict:
    load = os.getloadavg()[0]
    start = time.perf_counter()
    out = launch(classifier_job, (epochs,), {}, nproc, threads=threads)
    return {"nproc": nproc, "threads": threads, "load_before": load,
            "wall_seconds": time.perf_counter() - start, **out}


def _rows(name: str, runs: dict[str, list[dict]], seconds: str, losses: tuple[str, ...],
          nproc: int) -> tuple[list[dict], dict]:
    """Comparison records and the medians of one model's runs."""
    med = {k: {m: statistics.median(r[m] for r in v) for m in (seconds, "wall_seconds", *losses)}
           for k, v in runs.items()}
    par, one, all_threads = med["parallel"], med["one_thread"], med["all_threads"]
    label = f"ddp_{name}[{nproc} processes]"
    rows = [
        comparison(f"{label} {seconds}", "s", par[seconds], one[seconds],
                   "one process, one thread", higher_is_better=False),
        comparison(f"{label} {seconds} vs threads", "s", par[seconds], all_threads[seconds],
                   f"one process, {available_cpus()} threads", higher_is_better=False),
    ]
    for loss in losses:
        rows.append(comparison(f"{label} {loss}", "loss", par[loss], one[loss],
                               "one process, same global batch", higher_is_better=False))
    summary = {"medians": med, "speed_up": one[seconds] / par[seconds],
               "speed_up_vs_threads": all_threads[seconds] / par[seconds],
               "relative_loss_difference": {
                   loss: abs(par[loss] - one[loss]) / abs(one[loss]) for loss in losses}}
    return rows, summary


def run(repeats: int = 2, nproc: int = 2, models: tuple[str, ...] = MODELS, max_clips: int = 0,
        classifier_epochs: int = 20, details: dict | None = None) -> list[dict]:
    """Side-by-side records of ``nproc`` processes against one, gait network and classifier.

    Args:
        repeats: runs of each setting (medians reported).
        nproc: processes of the parallel runs.
        models: which of :data:`MODELS` to train.
        max_clips: the gait recipe's ``max_clips`` (0: every clip, the recipe's epoch).
        classifier_epochs: epochs of the classifier's runs (the recipe's 20).
        details: if given, every run and summary is stored in it.
    """
    settings = {"parallel": (nproc, 1), "one_thread": (1, 1),
                "all_threads": (1, available_cpus())}
    jobs = [("gait", lambda n, t: _gait_run(max_clips, n, t), "epoch_seconds",
             ("train_total", "val_total")),
            ("classifier", lambda n, t: _classifier_run(classifier_epochs, n, t),
             "epoch_seconds", ("loss_after_epoch_1", "val_balanced_accuracy"))]
    out = []
    for name, job, seconds, losses in (j for j in jobs if j[0] in models):
        runs: dict[str, list[dict]] = {k: [] for k in settings}
        for _ in range(repeats):
            for key, (n, threads) in settings.items():
                runs[key].append(job(n, threads))
                r = runs[key][-1]
                print(f"{name:10s} {n} process(es) x {threads} thread(s): {seconds} "
                      f"{r[seconds]:7.2f}, wall {r['wall_seconds']:7.2f} s, "
                      + ", ".join(f"{m} {r[m]:.6g}" for m in losses)
                      + f"  (load {r['load_before']:.2f})", flush=True)
        rows, summary = _rows(name, runs, seconds, losses, nproc)
        out += rows
        print(f"{name}: speed-up x{summary['speed_up']:.2f} (x{summary['speed_up_vs_threads']:.2f}"
              f" against one process of {available_cpus()} threads); relative loss difference "
              + ", ".join(f"{k} {v:.3%}" for k, v in summary["relative_loss_difference"].items()),
              flush=True)
        if details is not None:
            details[name] = {"runs": runs, **summary}
    return out


def main() -> None:
    """Run the benchmark from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--nproc", type=int, default=2)
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    parser.add_argument("--max-clips", type=int, default=0)
    parser.add_argument("--classifier-epochs", type=int, default=20)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "bench_ddp.json")
    args = parser.parse_args()
    details: dict = {"load_average_start": os.getloadavg()}
    results = run(args.repeats, args.nproc, tuple(args.models), args.max_clips,
                  args.classifier_epochs, details)
    details["load_average_end"] = os.getloadavg()
    print(f"\n{'benchmark':58} {'unit':5} {'emotive':>9} {'baseline':>9} {'ratio':>6}  baseline")
    for r in results:
        print(f"{r['name']:58} {r['unit']:5} {r['ours']:9.4g} {r['baseline']:9.4g} "
              f"{r['ratio']:6.3f}  {r['baseline_name']}")
    write_record(args.out, {
        "time": time.strftime("%Y-%m-%dT%H:%M:%S"), "machine": machine_info(),
        "nproc": args.nproc, "max_clips": args.max_clips,
        "classifier_epochs": args.classifier_epochs, "results": results, "details": details,
    })


if __name__ == "__main__":
    main()
