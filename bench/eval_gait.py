"""Evaluation of the emotive gait network (issue 3, section 6); prints and saves JSON.

Usage: ``python -m bench.eval_gait [--out bench/results/gait-eval.json] [--quick]``. Needs the
Bandai Namco data and the committed checkpoints (``src/emotive/assets/gait/``).

* Table 1 protocol (:func:`emotive.eval.table1.table1`) on the held-out test clips, at 10 and
  30 fps, for the pretrained network, its two ablations, QuaterNet and zero velocity: on the
  dataset-1 test clips (the four emotions live there) and on the test clips of both data sets.
* Long horizon: :data:`LONG_STEPS` steps on a figure-8 per emotion, all four agents in one
  batch: NaN, distance of the root to the path, and, per 10-second window, the mean joint speed
  against the 5-95 % range of real walks of that emotion (1-second windows of the ``walk``
  clips of that emotion in both data sets).
* The evaluation suite on generated 10-second walks (:data:`SEEDS` seeds per emotion on a
  figure-8, plus the angry-to-happy and sad-to-happy transitions): perceived emotion against the
  classifier's accuracy on real held-out walks, transition smoothness, foot skating against real
  held-out walks, path following.
* Emotion control (:mod:`bench.eval_gait_control`): speed over sad-happy blends, speed and arm
  swing along valence and arousal lines, the classifier at the four labels' points.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from rich.progress import track

from bench import eval_gait_control as control
from bench.common import machine_info, write_record
from emotive.data.clips import load_clips
from emotive.data.emotion import ALL_LABELS, Emotion, EmotionSchedule
from emotive.data.splits import split_clips
from emotive.eval.classifier import load_default_classifier
from emotive.eval.evaluate import Subject, resolve_subject, run_suites
from emotive.eval.sources import standard_requests
from emotive.eval.table1 import table1
from emotive.models.api import GenerationRequest
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.walks import generate_walks
from emotive.models.registry import get_model, model_names
from emotive.paths import circle, figure8, line

HERE = Path(__file__).resolve().parent

#: Steps of the long-horizon run (issue 3: 10,000).
LONG_STEPS = 10_000
#: Seeds per emotion of the generated 10-second walks.
SEEDS = 5
EMOTIONS = ("happy", "sad", "angry", "neutral")
WINDOW_SECONDS = 10.0


def table1_rows(quick: bool, checkpoint: Path | None = None) -> dict:
    """Table 1 per test set and rate, every model side by side (and ``checkpoint``'s)."""
    predictors = [get_model(name).load("predictor") for name in model_names("predictor")]
    if checkpoint is not None:
        predictor = get_model("gait").load("predictor", weights=checkpoint)
        predictor.name = f"{checkpoint.parent.name}/{checkpoint.name}"
        predictors.insert(-1, predictor)
    d1 = split_clips(load_clips("bandai-namco-1", locomotion=True))["test"]
    sets = {"dataset-1 test": d1}
    if not quick:
        d2 = split_clips(load_clips("bandai-namco-2-locomotion", locomotion=True))["test"]
        sets["both data sets, test"] = d1 + d2
    out = {}
    for set_name, clips in sets.items():
        for fps in (10.0, 30.0):
            start = time.perf_counter()
            result = table1(predictors, clips, fps=fps, labels=ALL_LABELS)
            key = f"{set_name}, {fps:g} fps"
            out[key] = {"markdown": result.to_markdown(), "result": result.to_dict(),
                        "seconds": time.perf_counter() - start}
            print(f"\nTable 1, {key} ({result.windows} windows, {result.clips} clips)")
            print(result.to_markdown(), flush=True)
    return out


def _mean_joint_speed(world: np.ndarray, fps: float, window: int) -> np.ndarray:
    """Per window of ``window`` frames, the mean over frames and joints of joint speed (m/s)."""
    speed = np.linalg.norm(np.diff(world, axis=0), axis=-1).mean(-1) * fps
    n = len(speed) // window
    return speed[: n * window].reshape(n, window).mean(1)


def real_speed_bands() -> dict[str, dict]:
    """5-95 % of the mean joint speed of real walks per emotion.

    5-95 % of the mean joint speed over 1-second windows of the real ``walk`` clips of each
    emotion (both data sets: dataset 2's ``normal`` walks are neutral too), all splits.
    """
    clips = [c for name in ("bandai-namco-1", "bandai-namco-2-locomotion")
             for c in load_clips(name, locomotion=True) if c.content == "walk"]
    bands = {}
    for label in EMOTIONS:
        values, count = [], 0
        for c in clips:
            if c.info.emotion == label:
                m = c.motion
                values.extend(_mean_joint_speed(m.positions_with_end_sites(), m.fps,
                                                round(m.fps)))
                count += 1
        lo, hi = np.percentile(values, [5, 95])
        bands[label] = {"band": [float(lo), float(hi)], "clips": count, "windows": len(values)}
    return bands


def long_horizon(steps: int, checkpoint: Path | None = None) -> dict:
    """:data:`LONG_STEPS` steps per emotion on a figure-8 (see the module docstring)."""
    model = get_model("gait").load("generator", weights=checkpoint).model
    path = figure8()
    gen = GaitGenerator(model)
    for e in EMOTIONS:
        gen.add_agent(path, e)
    window = round(WINDOW_SECONDS * model.fps)
    world = np.empty((steps + 1, len(EMOTIONS), *gen.first_frame().world.shape[1:]),
                     dtype=np.float32)
    world[0] = gen.first_frame().world
    dist = np.zeros(len(EMOTIONS))
    start = time.perf_counter()
    for t in track(range(1, steps + 1), description="long horizon"):
        frame = gen.step()
        world[t] = frame.world
        _, d = path.nearest(frame.root)
        dist = np.maximum(dist, d)
    seconds = time.perf_counter() - start
    bands = real_speed_bands()
    out = {"steps": steps, "seconds": seconds, "emotions": {}}
    for k, e in enumerate(EMOTIONS):
        w = world[:, k].astype(np.float64)
        speeds = _mean_joint_speed(w, model.fps, window)
        lo, hi = bands[e]["band"]
        inside = (speeds >= lo) & (speeds <= hi)
        out["emotions"][e] = {
            "finite": bool(np.isfinite(w).all()),
            "max_path_distance_m": float(dist[k]),
            "windows": len(speeds), "windows_in_real_band": int(inside.sum()),
            "real_band_m_s": [lo, hi], "real_clips": bands[e]["clips"],
            "real_windows": bands[e]["windows"],
            "window_speed_min_median_max": [float(speeds.min()), float(np.median(speeds)),
                                            float(speeds.max())],
        }
        print(f"long horizon {e}: {inside.sum()}/{len(speeds)} windows in the real band "
              f"[{lo:.2f}, {hi:.2f}] m/s (median {np.median(speeds):.2f}), finite "
              f"{np.isfinite(w).all()}, max path distance {dist[k]:.3g} m", flush=True)
    return out


def turn_speeds(checkpoint: Path | None = None) -> dict:
    """Walking speed on curved paths against straight ones, generated and in the data.

    Walking speed of a neutral agent on circles of decreasing radius against a straight
    line, and in the data: dataset-2 ``walk-turn-*`` clips against its straight ``walk`` clips
    (root speed over the frames where the root moves).
    """
    model = get_model("gait").load("generator", weights=checkpoint).model
    paths = {"line": line(40.0), "circle r=3 m": circle(3.0), "circle r=1.5 m": circle(1.5),
             "circle r=0.75 m": circle(0.75)}
    walks = generate_walks(model, list(paths.values()), ["neutral"] * len(paths), 12.0)
    out = {"generated_m_s": {}}
    for name, walk in zip(paths, walks, strict=True):
        hips = walk.motion.positions[:, model.controls.mover][:, [0, 2]]
        out["generated_m_s"][name] = float(
            np.linalg.norm(np.diff(hips[90:], axis=0), axis=1).mean() * model.fps)
    real: dict[str, list[float]] = {"walk": [], "walk-turn": []}
    for c in load_clips("bandai-namco-2-locomotion", locomotion=True):
        kind = "walk-turn" if c.content.startswith("walk-turn") else c.content
        if kind in real and c.style == "normal":
            hips = c.motion.positions_with_end_sites()[:, 1][:, [0, 2]]
            speed = np.linalg.norm(np.diff(hips, axis=0), axis=1) * c.motion.fps
            real[kind].append(float(speed[speed > 0.3].mean()))
    out["real_m_s"] = {k: float(np.mean(v)) for k, v in real.items() if v}
    print(f"turning: generated {out['generated_m_s']}; real normal walks {out['real_m_s']}")
    return out


def generated_suites(seeds: int, checkpoint: Path | None = None) -> dict:
    """Emotion, transition, quality and path suites on generated 10-second walks."""
    classifier = load_default_classifier()
    labels = classifier.labels
    requests = [
        GenerationRequest(f"{e}-{s}", EmotionSchedule.constant(Emotion.one_hot(e, labels)),
                          10.0, figure8(), seed=s)
        for e in EMOTIONS for s in range(seeds)
    ] + [r for r in standard_requests(labels, seconds=20.0) if "-to-" in r.name]
    out = {}
    subject = resolve_subject("gait" if checkpoint is None else checkpoint, labels)
    for suite in ("emotion", "transition", "quality", "path"):
        results, _ = run_suites(subject, suite, classifier, requests=requests)
        out[suite] = results[suite]
    raw = Subject("raw", generator=replace(subject.generator, foot_lock=False))
    out["quality_raw"] = run_suites(raw, "quality", classifier, requests=requests)[0]["quality"]
    e = out["emotion"]
    print(f"\nperceived emotion: window accuracy {e['window_accuracy']:.3f} on generated walks, "
          f"{e['real_window_accuracy']:.3f} on real held-out walks "
          f"(share {e['share_of_real_accuracy']:.2f}); confusion {e['confusion']}")
    q = out["quality"]
    print(f"foot skating {q['mean_skate_speed']:.3f} m/s vs real {q['real_skate_speed']:.3f} "
          f"(ratio {q['skate_vs_real']:.2f}); without the stream's foot lock "
          f"{out['quality_raw']['mean_skate_speed']:.3f} (ratio "
          f"{out['quality_raw']['skate_vs_real']:.2f})")
    for item in out["transition"]["items"]:
        print(f"transition {item['name']}: smooth {item.get('smooth')}, jerk percentile "
              f"{item.get('jerk_percentile')}, perceived {item['initial_perceived']} -> "
              f"{item['final_perceived']}")
    return out


def main() -> None:
    """Run the evaluation from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "gait-eval.json")
    parser.add_argument("--quick", action="store_true",
                        help="dataset-1 Table 1 only, 1,000 long-horizon steps, 2 seeds")
    parser.add_argument("--part", choices=("all", "table1", "long", "suites", "control"),
                        default="all")
    parser.add_argument("--checkpoint", type=Path, default=None,
                        help="a gait checkpoint to evaluate instead of the pretrained one (and "
                        "beside the committed models in Table 1)")
    args = parser.parse_args()
    record: dict = {"machine": machine_info(), "date": time.strftime("%Y-%m-%d %H:%M")}
    if args.part in ("all", "table1"):
        record["table1"] = table1_rows(args.quick, args.checkpoint)
    if args.part in ("all", "long"):
        record["long_horizon"] = long_horizon(1000 if args.quick else LONG_STEPS, args.checkpoint)
    if args.part in ("all", "suites"):
        record["turns"] = turn_speeds(args.checkpoint)
        record["suites"] = generated_suites(2 if args.quick else SEEDS, args.checkpoint)
    if args.part in ("all", "control"):
        model = get_model("gait").load("generator", weights=args.checkpoint).model
        record["control"] = {
            "blend": control.blend_rows(model),
            "valence_arousal": control.valence_arousal_rows(model),
            "label_points": control.label_point_rows(model, load_default_classifier()),
        }
    write_record(args.out, record)


if __name__ == "__main__":
    main()
