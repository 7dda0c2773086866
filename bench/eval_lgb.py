"""Resampling study of issue 7 (section 3): Local Grid Bootstrap motion of four emotions.

Usage: ``python bench/eval_lgb.py [--frames 30000] [--seed 0] [--workers 2]
[--out bench/results/eval_lgb.json]``. Needs Bandai Namco dataset 1.

For each of happy, sad, angry and neutral, an :class:`emotive.models.lgb.model.EmotionResampler`
is fitted on every dataset-1 clip of the emotion and ``--frames`` frames (the paper's 30,000)
are resampled and rebuilt by IK. Measured:

* **Trajectories** (per process, on the chain-frame points of the final rebuilt motion, taken
  relative to the chain's first joint: head; elbow and wrist; both ankles): speed distribution
  (mean ratio to the observed, quantiles, Kolmogorov-Smirnov distance), stalling (share of 1-s
  stretches whose path is shorter than the observed 5th percentile; the observed share is 5 %
  by definition), drift (distance from each generated point set to the nearest observed one,
  first and last third of the run), explosion (largest coordinate) and the mean run between
  jumps. For comparison, the paper's barycentre rule (``carry`` 0, and 1) straight from the
  bootstrap on :data:`BASELINE_FRAMES` frames, with the paper's orders (head 3, others 1).
* **Recognition**: the built-in classifier's window accuracy (4 s windows, 1 s hop) on the
  resampled motion against its accuracy on the real clips of the emotion (all clips, and the
  held-out test split); the issue asks for at least :data:`MIN_ACCURACY_RATIO` of the real
  accuracy.
* **Not a replay**: for 1-s windows (every 10th frame) of the rebuilt motion's end effectors
  (head, wrists, ankles, chain frames), the RMS distance to the nearest 1-s window of any
  captured clip of the emotion (every frame). The threshold: how close two *distinct* captured
  clips of the same emotion come, the 5th percentile over the windows of each clip of the
  distance to the nearest window of another clip; for scale, the replay level is the same
  distance between a captured clip and its own IK reconstruction.
* **ANOVA**: the paper's second study, with the classifier as observer. Each source (original
  clips, their IK reconstructions, resampled motion) is judged by :data:`OBSERVERS`
  pseudo-observers; observer ``k`` of a source sees, for each emotion, the ``k``-th of
  :data:`OBSERVERS` evenly spaced 4-s windows of that source and emotion, and gives the
  classifier's probability of the intended emotion. Mixed ANOVA
  (:func:`emotive.eval.stats.mixed_anova`): source between observers, emotion within.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import machine_info, write_record  # noqa: E402
from eval_ik import DATASET, EMOTIONS, HOP_SECONDS, WINDOW_SECONDS  # noqa: E402

#: Frames of the barycentre-rule baselines (they step through a KD-tree query each frame).
BASELINE_FRAMES = 10000
#: Frames of a not-a-replay window (1 s) and the hop between generated windows.
REPLAY_WINDOW = 30
REPLAY_HOP = 10
#: End effectors compared for not-a-replay.
EFFECTORS = ("head_torso:head", "left_arm:l_wrist", "right_arm:r_wrist", "left_leg:l_ankle",
             "right_leg:r_ankle")
#: Percentile of the distinct-clip distances used as the not-a-replay threshold.
THRESHOLD_PERCENTILE = 5.0
#: Issue 7: resampled motion recognized at no less than this fraction of the real accuracy.
MIN_ACCURACY_RATIO = 0.7
#: Pseudo-observers per source in the ANOVA.
OBSERVERS = 16


# --------------------------------------------------------------------------------------------
# Trajectory statistics


def _point_columns(model, process: str) -> list[np.ndarray]:
    """Columns (within the process's state) of each 3-D point of a process."""
    from emotive.models.lgb.model import PROCESSES

    cols, off = [], 0
    for block in PROCESSES[process][0]:
        width = model.layout[block].width
        if width == 3:
            cols.append(np.arange(off, off + 3))
        off += width
    return cols


def trajectory_stats(observed: np.ndarray, generated: np.ndarray, points: list[np.ndarray],
                     fps: float, index: np.ndarray | None = None) -> dict:
    """Speed, stalling, drift and range of generated ``(n, D)`` against closed observed rows."""
    from scipy.spatial import cKDTree
    from scipy.stats import ks_2samp

    def speeds(x: np.ndarray) -> np.ndarray:
        return fps * np.mean([np.linalg.norm(np.diff(x[:, c], axis=0), axis=1) for c in points],
                             0)

    so, sg = speeds(np.concatenate([observed, observed[:1]])), speeds(generated)

    def path_1s(s: np.ndarray) -> np.ndarray:
        c = np.concatenate([[0.0], np.cumsum(s / fps)])
        w = round(fps)
        return c[w:] - c[:-w]

    po, pg = path_1s(so), path_1s(sg)
    cols = np.concatenate(points)
    tree = cKDTree(observed[:, cols])
    near, _ = tree.query(generated[:, cols])
    third = max(1, len(near) // 3)
    q = (10, 50, 90, 99)
    out = {
        "speed_mean_ratio": float(sg.mean() / so.mean()),
        "speed_quantiles_observed_m_s": dict(zip(map(str, q), np.percentile(so, q).tolist(),
                                                 strict=True)),
        "speed_quantiles_generated_m_s": dict(zip(map(str, q), np.percentile(sg, q).tolist(),
                                                  strict=True)),
        "speed_ks": float(ks_2samp(so, sg).statistic),
        "stall_fraction": float(np.mean(pg < np.percentile(po, 5))),
        "nearest_observed_mm": {
            "median": 1000 * float(np.median(near)),
            "p99": 1000 * float(np.percentile(near, 99)),
            "median_first_third": 1000 * float(np.median(near[:third])),
            "median_last_third": 1000 * float(np.median(near[-third:])),
        },
        "largest_coordinate_m": {"observed": float(np.abs(observed[:, cols]).max()),
                                 "generated": float(np.abs(generated[:, cols]).max())},
    }
    if index is not None:
        jumps = np.diff(index) % len(observed) != 1
        out["mean_run_frames"] = float(len(jumps) / max(1, int(jumps.sum())))
    return out


def _relative_to_anchor(model, rows: np.ndarray, state: tuple[str, ...]) -> np.ndarray:
    """A process's state columns of ``(T, F)`` rows, each 3-D point taken relative to its
    chain's first joint (the shoulder for the arms, which moves with the clavicle)."""
    out = []
    for block in state:
        col = model.layout[block]
        x = rows[:, col.slice]
        chain = block.split(":")[0]
        if col.width == 3 and f"anchor:{chain}" in model.layout:
            x = x - rows[:, model.layout[f"anchor:{chain}"].slice]
        out.append(x)
    return np.concatenate(out, axis=1)


def process_stats(model, final: np.ndarray, samples: dict, baseline_frames: int,
                  seed: int) -> dict:
    """:func:`trajectory_stats` per process for the final motion's ``(T, F)`` feature rows
    (``final``) and for the baselines; points relative to their chain's first joint."""
    from emotive.models.lgb.bootstrap import LocalGridBootstrap
    from emotive.models.lgb.model import PROCESSES

    out = {}
    for name, (state, _) in PROCESSES.items():
        observed = _relative_to_anchor(model, model.observed, state)
        points = _point_columns(model, name)
        rec = {"resampled": trajectory_stats(observed, _relative_to_anchor(model, final, state),
                                             points, model.fps, samples[name].index)}
        paper_order = 3 if name == "head" else 1
        for carry in (0.0, 1.0):
            boot = LocalGridBootstrap(order=paper_order, rule="barycentre", carry=carry)
            s = boot.fit(observed).sample(baseline_frames, np.random.default_rng(seed))
            rec[f"paper_barycentre_carry_{carry:g}"] = trajectory_stats(observed, s.states,
                                                                        points, model.fps)
        out[name] = rec
    return out


# --------------------------------------------------------------------------------------------
# Not a replay


def _windows(x: np.ndarray, hop: int) -> np.ndarray:
    starts = np.arange(0, len(x) - REPLAY_WINDOW + 1, hop)
    return np.stack([x[s : s + REPLAY_WINDOW].ravel() for s in starts])


def _nearest(queries: np.ndarray, pool: np.ndarray) -> np.ndarray:
    """RMS distance (metres per effector point) from each query window to the nearest in
    ``pool``."""
    scale = np.sqrt(queries.shape[1] / 3)
    pool_sq = (pool**2).sum(1)
    best = np.full(len(queries), np.inf)
    for a in range(0, len(queries), 512):
        q = queries[a : a + 512]
        d2 = (q**2).sum(1)[:, None] + pool_sq[None] - 2.0 * q @ pool.T
        best[a : a + 512] = np.sqrt(np.maximum(d2.min(1), 0.0))
    return best / scale


def replay_stats(model, clips: list, rebuilt: dict, motion) -> dict:
    """Nearest captured-window distances of the resampled motion, the distinct-clip threshold
    and the replay level."""
    from emotive.models.lgb.model import clip_features

    cols = np.concatenate([np.arange(model.layout[k].start, model.layout[k].start + 3)
                           for k in EFFECTORS])

    rig = model.reference.skeleton

    def feats(m) -> np.ndarray:
        return clip_features(m.replace(skeleton=rig), model.chains, model.layout)[:, cols]

    per_clip = {c.name: _windows(feats(c.motion), 1) for c in clips
                if c.motion.num_frames >= REPLAY_WINDOW}
    pool = np.concatenate(list(per_clip.values()))
    generated = _nearest(_windows(feats(motion), REPLAY_HOP), pool)
    between = np.concatenate([
        _nearest(w, np.concatenate([v for k, v in per_clip.items() if k != name]))
        for name, w in per_clip.items()
    ])
    replay = np.concatenate([
        np.sqrt(((per_clip[n] - _windows(feats(rebuilt[n]), 1)) ** 2).mean(1) * 3)
        for n in per_clip if n in rebuilt
    ])
    threshold = float(np.percentile(between, THRESHOLD_PERCENTILE))
    return {
        "generated_windows": len(generated),
        "generated_nearest_mm": {"min": 1000 * float(generated.min()),
                                 "p5": 1000 * float(np.percentile(generated, 5)),
                                 "median": 1000 * float(np.median(generated))},
        "distinct_clips_nearest_mm": {"p5": 1000 * threshold,
                                      "median": 1000 * float(np.median(between))},
        "replay_level_mm": {"median": 1000 * float(np.median(replay)),
                            "max": 1000 * float(replay.max())},
        "threshold_mm": 1000 * threshold,
        "fraction_above_threshold": float(np.mean(generated > threshold)),
        "all_above_threshold": bool(generated.min() > threshold),
    }


# --------------------------------------------------------------------------------------------
# Classifier and ANOVA


def _accuracy(probs: list[np.ndarray], k: int) -> float:
    p = np.concatenate(probs)
    return float((p.argmax(1) == k).mean()) if len(p) else float("nan")


def _spaced(p: np.ndarray, count: int) -> np.ndarray:
    """``count`` evenly spaced rows of ``p`` (all of them, cycled, if fewer)."""
    return p[np.linspace(0, len(p) - 1, count).round().astype(int)]


def anova(p_intended: dict[str, dict[str, np.ndarray]]) -> dict:
    """Mixed ANOVA on P(intended): source between pseudo-observers, emotion within."""
    from emotive.eval.stats import MissingDependencyError, StatsInputError, mixed_anova

    rows = [
        {"observer": f"{source}:{k}", "source": source, "emotion": e, "p_intended": float(v)}
        for source, per_emotion in p_intended.items()
        for e, values in per_emotion.items()
        for k, v in enumerate(_spaced(values, OBSERVERS))
    ]
    try:
        import pandas as pd

        result = mixed_anova(pd.DataFrame(rows), dv="p_intended", within="emotion",
                             between="source", subject="observer")
    except (StatsInputError, MissingDependencyError, ImportError) as exc:
        return {"ran": False, "reason": str(exc)}
    effects = {
        eff.source: {"F": eff.f, "df1": eff.df1, "df2": eff.df2, "p_unc": eff.p_unc,
                     "p_gg": eff.p_gg, "partial_eta_sq": eff.partial_eta_sq,
                     "generalized_eta_sq": eff.generalized_eta_sq}
        for eff in (result.between, result.within, result.interaction)
    }
    means = {s: {e: float(np.mean(_spaced(v, OBSERVERS))) for e, v in pe.items()}
             for s, pe in p_intended.items()}
    return {"ran": True, "observers_per_source": OBSERVERS, "effects": effects,
            "mean_p_intended": means}


# --------------------------------------------------------------------------------------------


def evaluate(frames: int, seed: int, workers: int) -> dict:
    """The whole study (see the module docstring)."""
    import torch
    from rich.progress import track

    from emotive.data.clips import load_clips
    from emotive.data.splits import split_clips
    from emotive.eval.classifier import ClassifierError, load_default_classifier
    from emotive.ik import reconstruct, resolve_chains
    from emotive.models.lgb.model import EmotionResampler, clip_features

    torch.set_num_threads(1)
    classifier = load_default_classifier()
    labels = classifier.labels
    clips = load_clips(DATASET)
    test_names = {c.name for c in split_clips([c for c in clips if c.info.emotion in EMOTIONS])
                  ["test"]}
    out: dict = {"emotions": {}}
    p_intended: dict[str, dict[str, np.ndarray]] = {"original": {}, "rebuilt": {},
                                                     "resampled": {}}
    for emotion in EMOTIONS:
        k = labels.index(emotion)
        mine = [c for c in clips if c.info.emotion == emotion]
        start = time.perf_counter()
        model = EmotionResampler.fit(clips, emotion)
        fit_s = time.perf_counter() - start
        start = time.perf_counter()
        features, samples = model.sample_features(frames, seed)
        base = model.base_motion(features)
        result = model.rebuild(model.trajectories(features, base), base, workers=workers)
        result = model.smooth_jumps(result, samples)
        gen_s = time.perf_counter() - start
        motion = result.motion
        rebuilt, real_p, rebuilt_p, test_p = {}, [], [], []
        for clip in track(mine, description=f"{emotion}: rebuilding the real clips"):
            m = clip.motion
            rec = reconstruct(m, resolve_chains(m.skeleton, m)).motion
            rebuilt[clip.name] = rec
            try:
                _, po = classifier.classify(m, WINDOW_SECONDS, HOP_SECONDS)
                _, pr = classifier.classify(rec, WINDOW_SECONDS, HOP_SECONDS)
            except ClassifierError:
                continue
            real_p.append(po)
            rebuilt_p.append(pr)
            if clip.name in test_names:
                test_p.append(po)
        _, ps = classifier.classify(motion, WINDOW_SECONDS, HOP_SECONDS)
        acc_real, acc_res = _accuracy(real_p, k), _accuracy([ps], k)
        recognition = {
            "windows_real": int(sum(len(p) for p in real_p)),
            "windows_resampled": len(ps),
            "accuracy_real_all_clips": acc_real,
            "accuracy_real_test_clips": _accuracy(test_p, k),
            "accuracy_rebuilt": _accuracy(rebuilt_p, k),
            "accuracy_resampled": acc_res,
            "ratio_resampled_to_real": acc_res / acc_real if acc_real else float("nan"),
            "meets_target": bool(acc_res >= MIN_ACCURACY_RATIO * acc_real),
            "perceived_resampled": {lab: float((ps.argmax(1) == j).mean())
                                    for j, lab in enumerate(labels)},
        }
        p_intended["original"][emotion] = np.concatenate(real_p)[:, k]
        p_intended["rebuilt"][emotion] = np.concatenate(rebuilt_p)[:, k]
        p_intended["resampled"][emotion] = ps[:, k]
        replay = replay_stats(model, mine, rebuilt, motion)
        final = clip_features(motion, model.chains, model.layout)
        procs = process_stats(model, final, samples, BASELINE_FRAMES, seed)
        out["emotions"][emotion] = {
            "clips": len(mine),
            "observed_frames": len(model.observed),
            "frames": frames,
            "fit_seconds": fit_s,
            "resample_and_rebuild_seconds": gen_s,
            "ik": {
                "residual_mean_mm": {n: 1000 * float(r.mean()) for n, r in
                                     result.residuals.items()},
                "off_target_frames": {n: len(f) for n, f in result.off_target.items()},
                "unreachable_targets": {n: len(u) for n, u in result.unreachable.items()},
            },
            "recognition": recognition,
            "not_a_replay": replay,
            "processes": procs,
        }
        report_emotion(emotion, out["emotions"][emotion])
    out["anova"] = anova(p_intended)
    report_anova(out["anova"])
    return out


def report_emotion(emotion: str, rec: dict) -> None:
    """Print one emotion's numbers."""
    r, nr = rec["recognition"], rec["not_a_replay"]
    print(f"\n{emotion}: {rec['clips']} clips, {rec['observed_frames']} closed frames; "
          f"{rec['frames']} frames resampled and rebuilt in "
          f"{rec['resample_and_rebuild_seconds']:.1f} s")
    print(f"  classifier accuracy: real {r['accuracy_real_all_clips']:.3f} "
          f"({r['windows_real']} windows; held-out test clips {r['accuracy_real_test_clips']:.3f})"
          f", rebuilt {r['accuracy_rebuilt']:.3f}, resampled {r['accuracy_resampled']:.3f} "
          f"({r['windows_resampled']} windows): ratio {r['ratio_resampled_to_real']:.2f} "
          f"({'meets' if r['meets_target'] else 'MISSES'} the {MIN_ACCURACY_RATIO:g} target)")
    g = nr["generated_nearest_mm"]
    print(f"  not a replay: nearest captured 1-s window min {g['min']:.1f} mm, p5 {g['p5']:.1f},"
          f" median {g['median']:.1f}; threshold (distinct clips p{THRESHOLD_PERCENTILE:g}) "
          f"{nr['threshold_mm']:.1f} mm; {100 * nr['fraction_above_threshold']:.1f} % above; "
          f"replay level {nr['replay_level_mm']['median']:.1f} mm")
    print(f"  {'process':10s} {'rule':26s} {'speed':>6s} {'KS':>5s} {'stall':>6s} "
          f"{'near mm':>8s} {'first':>6s} {'last':>6s} {'run':>5s}")
    for name, rules in rec["processes"].items():
        for rule, s in rules.items():
            nm = s["nearest_observed_mm"]
            run = f"{s['mean_run_frames']:5.1f}" if "mean_run_frames" in s else f"{'-':>5s}"
            print(f"  {name:10s} {rule:26s} {s['speed_mean_ratio']:6.2f} {s['speed_ks']:5.2f} "
                  f"{s['stall_fraction']:6.3f} {nm['median']:8.2f} "
                  f"{nm['median_first_third']:6.2f} {nm['median_last_third']:6.2f} {run}")


def report_anova(aov: dict) -> None:
    """Print the ANOVA."""
    print("\nmixed ANOVA on P(intended emotion), source between pseudo-observers, emotion "
          "within:")
    if not aov["ran"]:
        print(f"  not run: {aov['reason']}")
        return
    for name, e in aov["effects"].items():
        print(f"  {name:12s} F({e['df1']:.0f}, {e['df2']:.0f}) = {e['F']:.3f}, p = "
              f"{e['p_unc']:.4f} (GG {e['p_gg']:.4f}), partial eta2 {e['partial_eta_sq']:.3f}")
    for source, means in aov["mean_p_intended"].items():
        print(f"  mean P(intended) {source:9s} " +
              ", ".join(f"{e} {v:.3f}" for e, v in means.items()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=30000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "eval_lgb.json")
    args = parser.parse_args()
    study = evaluate(args.frames, args.seed, args.workers)
    write_record(args.out, {
        "machine": machine_info(),
        "date": time.strftime("%Y-%m-%d %H:%M"),
        "dataset": DATASET,
        "seed": args.seed,
        "window_seconds": WINDOW_SECONDS,
        "hop_seconds": HOP_SECONDS,
        "threshold_percentile": THRESHOLD_PERCENTILE,
        **study,
    })


if __name__ == "__main__":
    main()
