"""Evaluation of the valence/arousal FCRBM (issue 6, section 3).

Usage: ``python -m bench.eval_fcrbm [--checkpoint PATH] [--seeds 3] [--seconds 20]
[--long-seconds 300] [--out bench/results/fcrbm-eval.json]``. Needs the data for the real
references (``EMOTIVE_DATA`` or ``../shared/data``).

* **control**: root speed, joint speed (relative to the root) and step frequency of motion
  generated along each axis (arousal 1, 1.5, ..., 3.5 at valence 2; valence likewise at arousal
  2), ``--seeds`` samples of ``--seconds`` each, with whether each measure rises monotonically
  over 1, 2, 3, 3.5 and whether every run at those four values is *walking* (as in the walking
  screen below: a rise that starts from a still pose is not control), with the root path
  rebuilt from the stance foot (the generator's default, ``root="feet"``) and with the model's
  own root velocity (``root="model"``, the same generated frames); beside them the same
  measures on the real walks of the data sets grouped by their arousal or valence (the training
  data's own trend).
* **emotion**: motion generated at the valence/arousal of happy, sad, angry and neutral, judged
  by the evaluation suite's classifier (its emotion suite): window accuracy against the
  classifier's accuracy on real held-out walks (with either root path); the classifier's
  reading of the checkpoint's own real training walks at the style nearest each emotion (what
  the model could reach by copying its data); the same suite on motion started from frames of
  those real walks, as in the paper (the requested emotion's, and neutral's); and the affect
  suite's Fréchet distance of the 26 affective and movement features to real walks of the same
  emotion.
* **transition**: every ordered pair of the four emotions, 10 s each side with a one-second
  linear change, through the transition suite (jerk against the real data's windowed jerk,
  perceived emotion before and after), with the root speed per second through the change.
* **stability**: ``--long-seconds`` of generation per emotion through the long-run suite
  (collapse and explosion against real energy).
* **speed**: generated frames per second for 1 and 20 agents in one batch (real time for 20
  agents at 30 fps is 600 frames per second).
* **walking** (``--part walking``, the screen used while the model still freezes): from the
  mean frame, 7 emotions x ``--seeds`` runs of 15 s, a run *walking* when its joint speed is
  above 0.25 m/s and it makes more than 0.8 steps/s (root from the stance foot; a gait whose
  feet slide and never plant makes almost no steps); and from a real clip, frames 30-32 of the
  first training clip of each style the checkpoint was trained on, 600 frames at that style's
  valence/arousal, the style *sustained* when the mean frame-to-frame change of frames 300-599
  is more than half the clip's own.
"""

from __future__ import annotations

import argparse
import itertools
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import machine_info, write_record
from emotive.core.ops import crop
from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.data.emotion import VALENCE_AROUSAL, Emotion, EmotionSchedule, style_to_label
from emotive.eval.classifier import load_default_classifier, window_labels
from emotive.eval.sources import EvaluatedMotion
from emotive.eval.suites import (
    affect_suite,
    emotion_suite,
    longrun_suite,
    real_reference,
    transition_suite,
)
from emotive.features.contacts import foot_contacts, foot_strikes
from emotive.models.fcrbm.checkpoint import load_fcrbm_checkpoint
from emotive.models.fcrbm.generate import (
    ROOT_MODES,
    constant_context,
    decode_frames,
    default_checkpoint_path,
    emotion_context,
    generate_motion,
    schedule_context,
)
from emotive.models.fcrbm.training import FCRBMTrainSettings, load_fcrbm_data
from emotive.models.registry import get_model

HERE = Path(__file__).resolve().parent

EMOTIONS = ("happy", "sad", "angry", "neutral")
AXIS_VALUES = (1.0, 1.5, 2.0, 2.5, 3.0, 3.5)
MONOTONIC_AT = (1.0, 2.0, 3.0, 3.5)
#: A run is walking when its joint speed (m/s) and step frequency (1/s) are above these.
WALKING_JOINT_SPEED = 0.25
WALKING_STEPS = 0.8


def measures(motion) -> dict[str, float]:
    """Root speed and joint speed relative to the root (m/s) and steps per second."""
    roles = resolve_roles(motion.skeleton)
    p = motion.positions_with_end_sites()
    root = p[:, roles.index["root"]]
    ground = np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1) * motion.fps
    rel = p - root[:, None]
    joints = np.linalg.norm(np.diff(rel, axis=0), axis=2).mean(1) * motion.fps
    strikes = foot_strikes(foot_contacts(p, roles, motion.fps)).sum()
    return {"root_speed": float(ground.mean()), "joint_speed": float(joints.mean()),
            "step_frequency": float(strikes / motion.duration)}


def is_walking(measured: dict[str, float]) -> bool:
    """Whether :func:`measures` of a run show walking.

    Whether :func:`measures` of a run show walking (:data:`WALKING_JOINT_SPEED`,
    :data:`WALKING_STEPS`).
    """
    return bool(measured["joint_speed"] > WALKING_JOINT_SPEED
                and measured["step_frequency"] > WALKING_STEPS)


def real_trend() -> dict:
    """The measures of real walks grouped by their style's arousal and valence.

    The measures of real walks grouped by their style's arousal and valence (1-3 scale,
    rounded to the nearest half).
    """
    groups: dict[str, dict[float, list[dict]]] = {"arousal": {}, "valence": {}}
    for name in ("bandai-namco-1", "bandai-namco-2-locomotion"):
        for clip in load_clips(name, contents=("walk",)):
            point = VALENCE_AROUSAL.get(style_to_label(clip.style))
            if point is None or clip.motion.duration < 2.0:
                continue
            for axis, value in (("valence", point.valence), ("arousal", point.arousal)):
                key = round(2 * (2.0 + value)) / 2
                groups[axis].setdefault(key, []).append(measures(clip.motion))
    return {axis: {str(k): {m: float(np.mean([r[m] for r in rows])) for m in rows[0]}
                   | {"clips": len(rows)}
                   for k, rows in sorted(table.items())}
            for axis, table in groups.items()}


def control(model, seeds: int, seconds: float) -> dict:
    """Measures along the arousal and valence axes (the other held at 2), per root path."""
    frames = round(seconds * model.fps)
    out: dict = {}
    for axis in ("arousal", "valence"):
        rows: dict[str, dict] = {root: {} for root in ROOT_MODES}
        for value in AXIS_VALUES:
            va = (2.0, value) if axis == "arousal" else (value, 2.0)
            runs = [generate_motion(model, constant_context(*va, frames), seed=s)[1]
                    for s in range(seeds)]
            for root in ROOT_MODES:
                samples = [measures(decode_frames(model, run, root=root)) for run in runs]
                rows[root][str(value)] = {m: float(np.mean([r[m] for r in samples]))
                                          for m in samples[0]}
                rows[root][str(value)]["walking_share"] = float(np.mean(
                    [is_walking(r) for r in samples]))
        out[axis] = {}
        for root, table in rows.items():
            monotonic = {m: bool(all(table[str(b)][m] > table[str(a)][m]
                                     for a, b in itertools.pairwise(MONOTONIC_AT)))
                         for m in ("root_speed", "joint_speed", "step_frequency")}
            walking = all(table[str(v)]["walking_share"] == 1.0 for v in MONOTONIC_AT)
            out[axis][root] = {"values": table, "monotonic_1_2_3_3.5": monotonic,
                               "walking_at_1_2_3_3.5": walking}
            print(f"{axis} (root {root}): " + "; ".join(
                f"{v}: root {r['root_speed']:.2f} joints {r['joint_speed']:.2f} steps "
                f"{r['step_frequency']:.2f} walking {r['walking_share']:.0%}"
                for v, r in table.items())
                + f"  monotonic {monotonic}, every run walking at 1, 2, 3, 3.5: {walking}")
    return out


def _item(name, motion, context_emotions, labels):
    return EvaluatedMotion(name, motion, context_emotions, labels)


def nearest_training_walks(checkpoint: Path | None) -> dict:
    """Per emotion: the nearest training style, its distance and its real walks.

    Per emotion: the checkpoint's training style nearest the emotion's valence/arousal, its
    distance and that style's real walks (every split), ``{emotion: (style, distance,
    [Motion])}``.
    """
    *_, ckpt = load_fcrbm_checkpoint(checkpoint or default_checkpoint_path())
    settings = FCRBMTrainSettings(**ckpt["train"])
    points: dict[str, np.ndarray] = {}
    walks: dict[str, list] = {}
    for dataset in settings.datasets:
        for clip in load_clips(dataset, contents=settings.contents):
            key = f"{dataset}:{clip.style}"
            point = VALENCE_AROUSAL.get(style_to_label(clip.style))
            if point is None or (settings.styles and key not in settings.styles):
                continue
            points[key] = 2.0 + np.array([point.valence, point.arousal])
            walks.setdefault(key, []).append(clip.motion)
    out = {}
    for emotion in EMOTIONS:
        target = emotion_context(emotion)
        style = min(points, key=lambda k: float(np.linalg.norm(points[k] - target)))
        out[emotion] = (style, float(np.linalg.norm(points[style] - target)), walks[style])
    return out


def real_ceiling(nearest: dict, classifier) -> dict:
    """Per emotion: classifier accuracy on the nearest training style's real walks.

    Per emotion: the classifier's window accuracy on the real walks of the nearest training
    style (:func:`nearest_training_walks`).
    """
    out = {}
    for emotion, (style, distance, motions) in nearest.items():
        read = [label for motion in motions if motion.duration >= classifier.config.min_seconds
                for label in window_labels(classifier.classify(motion)[1], classifier.labels)]
        out[emotion] = {"style": style, "distance": distance,
                        "accuracy": float(np.mean([r == emotion for r in read])),
                        "windows": len(read)}
    return out


def primed(model, nearest: dict, classifier, seeds: int, seconds: float) -> dict:
    """The emotion suite on motion started from real frames, as in the paper.

    ``N + 1`` frames from frame 30 (then 60, 90, ... when there are fewer walks than seeds, wrapping
    within the walk) of the walks of the training style nearest the requested emotion (``same``), or
    of the style nearest neutral (``from_neutral``: can the context alone lead the motion to the
    emotion?).
    """
    frames, order = round(seconds * model.fps), model.network.config.order
    labels = classifier.labels
    out = {}
    for mode in ("same", "from_neutral"):
        items = []
        for emotion in EMOTIONS:
            walks = [m for m in nearest[emotion if mode == "same" else "neutral"][2]
                     if m.num_frames > 31 + order]
            for s in range(seeds):
                walk = walks[s % len(walks)]
                start = 30 + (30 * (s // len(walks))) % (walk.num_frames - 30 - order)
                motion, _ = generate_motion(
                    model, constant_context(*emotion_context(emotion), frames), seed=s,
                    primer=crop(walk, start, start + order + 1), name=f"{emotion}-{s}")
                intended = np.repeat(Emotion.one_hot(emotion, labels).weights[None],
                                     motion.num_frames, 0)
                items.append(_item(f"{emotion}-{s}", motion, intended, labels))
        out[mode] = emotion_suite(items, classifier)
    return out


def emotions_and_transitions(model, checkpoint: Path | None, seeds: int, seconds: float,
                             long_seconds: float) -> dict:
    """The emotion, affect, transition and long-run suites on generated motion."""
    classifier = load_default_classifier()
    labels = classifier.labels
    reference = real_reference(labels)
    frames = round(seconds * model.fps)
    singles, model_root = [], []
    for emotion, s in itertools.product(EMOTIONS, range(seeds)):
        motion, run = generate_motion(model, constant_context(*emotion_context(emotion), frames),
                                      seed=s, name=f"{emotion}-{s}")
        intended = np.repeat(Emotion.one_hot(emotion, labels).weights[None], motion.num_frames, 0)
        singles.append(_item(f"{emotion}-{s}", motion, intended, labels))
        model_root.append(_item(f"{emotion}-{s}", decode_frames(model, run, root="model"),
                                intended, labels))
    out = {"emotion": emotion_suite(singles, classifier),
           "emotion_model_root": emotion_suite(model_root, classifier),
           "affect": affect_suite(singles, reference)}
    nearest = nearest_training_walks(checkpoint)
    out["real_ceiling"] = real_ceiling(nearest, classifier)
    out["emotion_primed"] = primed(model, nearest, classifier, seeds, seconds)
    for key in ("emotion", "emotion_model_root"):
        e = out[key]
        print(f"perceived emotion ({key}): window accuracy {e['window_accuracy']:.3f}, real "
              f"{e['real_window_accuracy']:.3f} (share {e['share_of_real_accuracy']:.2f}); "
              f"confusion {e['confusion']} over {e['labels']}")
    for mode, e in out["emotion_primed"].items():
        print(f"perceived emotion started from real frames ({mode}): window accuracy "
              f"{e['window_accuracy']:.3f} (share {e['share_of_real_accuracy']:.2f}); "
              f"confusion {e['confusion']}")
    print("the classifier on the checkpoint's real training walks nearest each emotion: "
          + "; ".join(f"{k} ({r['style']}, {r['distance']:.2f} away) {r['accuracy']:.2f}"
                      for k, r in out["real_ceiling"].items()))
    for row in out["affect"]["labels"]:
        print(f"affect {row['label']}: Frechet to real {row.get('frechet_to_real', 'n/a'):.3g} "
              f"(real train to real {row.get('frechet_real_train_to_real', float('nan')):.3g})")

    transitions = []
    half = 0.5 * seconds
    for start, end in itertools.permutations(EMOTIONS, 2):
        keys = [{"t": 0.0, "emotion": start}, {"t": half - 0.5, "emotion": start},
                {"t": half + 0.5, "emotion": end}]
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "schedule.json"
            path.write_text(json.dumps(keys))
            context = schedule_context(path, frames, model.fps)
        motion, _ = generate_motion(model, context, name=f"{start}-to-{end}")
        intended = EmotionSchedule.from_keyframes(keys, labels).sample(
            model.fps, num_frames=motion.num_frames)
        item = _item(f"{start}-to-{end}", motion, intended, labels)
        transitions.append(item)
    out["transition"] = transition_suite(transitions, classifier, reference)
    for row, item in zip(out["transition"]["items"], transitions, strict=True):
        per_second = [measures(crop(item.motion, a, a + round(model.fps)))["root_speed"]
                      for a in range(0, item.motion.num_frames - round(model.fps) + 1,
                                     round(model.fps))]
        row["root_speed_per_second"] = per_second
        print(f"transition {row['name']}: smooth {row.get('smooth')}, max jerk percentile "
              f"{max(row.get('jerk_percentile', [float('nan')])):.1f}, perceived "
              f"{row['initial_perceived']} -> {row['final_perceived']}, root speed per second "
              f"{np.round(per_second, 2).tolist()}")

    long_frames = round(long_seconds * model.fps)
    context = np.stack([constant_context(*emotion_context(e), long_frames) for e in EMOTIONS], 1)
    began = time.perf_counter()
    _, frames_std = generate_motion(model, context, seed=0)
    long_items = []
    for k, emotion in enumerate(EMOTIONS):
        motion = decode_frames(model, frames_std[k], f"long-{emotion}")
        intended = np.repeat(Emotion.one_hot(emotion, labels).weights[None], motion.num_frames, 0)
        long_items.append(_item(f"long-{emotion}", motion, intended, labels))
    out["stability"] = longrun_suite(long_items, reference)
    out["stability"]["generation_seconds"] = time.perf_counter() - began
    for row in out["stability"]["items"]:
        print(f"long run {row['name']} ({long_seconds:.0f} s): stable {row['stable']}, collapsed "
              f"at {row['collapsed_at']}, exploded at {row['exploded_at']}, share of seconds in "
              f"the real energy band {row.get('share_in_real_band', float('nan')):.2f}")
    return out


def speed(model, seconds: float = 10.0) -> dict:
    """Generated frames per second for 1 and 20 agents in one batch (medians of 3)."""
    frames = round(seconds * model.fps)
    out = {}
    for agents in (1, 20):
        context = np.stack([constant_context(2.0, 2.0, frames)] * agents, 1)
        times = []
        for _ in range(3):
            began = time.perf_counter()
            generate_motion(model, context, seed=0)
            times.append(time.perf_counter() - began)
        rate = agents * frames / float(np.median(times))
        out[str(agents)] = {"agent_frames_per_second": rate,
                            "real_time_factor": rate / (agents * model.fps)}
        print(f"speed, {agents} agents: {rate:,.0f} agent-frames/s, "
              f"{rate / (agents * model.fps):.1f}x real time")
    return out


WALK_EMOTIONS = ("neutral", "happy", "sad", "angry", "tired", "elderly", "active")


def walking(model, checkpoint: Path | None, seeds: int) -> dict:
    """The walking screen of the module docstring."""
    runs = [e for e in WALK_EMOTIONS for _ in range(seeds)]
    context = np.stack([constant_context(*emotion_context(e), 450) for e in runs], 1)
    _, frames = generate_motion(model, context, seed=0)
    mean_frame: dict[str, int] = dict.fromkeys(WALK_EMOTIONS, 0)
    for emotion, run in zip(runs, frames, strict=True):
        r = measures(decode_frames(model, run))
        mean_frame[emotion] += is_walking(r)
    print(f"walking from the mean frame: {sum(mean_frame.values())} of {len(runs)} runs "
          f"{mean_frame}")

    *_, ckpt = load_fcrbm_checkpoint(checkpoint or default_checkpoint_path())
    data = load_fcrbm_data(FCRBMTrainSettings(**ckpt["train"]))
    net, order = model.network, model.network.config.order
    styles: dict[str, float] = {}
    for name, clip, z in data.splits["train"]:
        style = name.split("_")[0] + "_" + name.split("_")[2]
        if style in styles or len(clip) < 30 + order:
            continue
        out = net.generate(torch.from_numpy(clip[30:30 + order][None].astype(np.float32)),
                           torch.from_numpy(z[0].astype(np.float32))[None], steps=600,
                           generator=torch.Generator().manual_seed(0))[0].numpy()
        change = np.linalg.norm(np.diff(out, axis=0), axis=1)[300:].mean()
        styles[style] = float(change / np.linalg.norm(np.diff(clip, axis=0), axis=1).mean())
    sustained = [s for s, ratio in styles.items() if ratio > 0.5]
    print(f"sustained from a real clip: {len(sustained)} of {len(styles)} styles "
          + ", ".join(f"{s} {r:.2f}" for s, r in styles.items()))
    return {"mean_frame_walking": mean_frame, "mean_frame_runs": len(runs),
            "clip_change_ratio": styles, "sustained": sustained}


def main() -> None:
    """Run the evaluation from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path, default=None)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--long-seconds", type=float, default=300.0)
    parser.add_argument("--part", default="all",
                        choices=("all", "control", "suites", "speed", "walking"))
    parser.add_argument("--out", type=Path, default=HERE / "results" / "fcrbm-eval.json")
    args = parser.parse_args()
    torch.set_num_threads(1)

    model = get_model("fcrbm").load("generator", weights=args.checkpoint).model
    record: dict = {"machine": machine_info(), "date": time.strftime("%Y-%m-%d %H:%M"),
                    "checkpoint": str(args.checkpoint or "built-in")}
    if args.part in ("all", "control"):
        record["control"] = control(model, args.seeds, args.seconds)
        record["real_trend"] = real_trend()
        for axis, table in record["real_trend"].items():
            print(f"real walks by {axis}: " + "; ".join(
                f"{k}: root {r['root_speed']:.2f} joints {r['joint_speed']:.2f} steps "
                f"{r['step_frequency']:.2f} ({r['clips']} clips)" for k, r in table.items()))
    if args.part in ("all", "suites"):
        record["suites"] = emotions_and_transitions(model, args.checkpoint, args.seeds,
                                                    args.seconds, args.long_seconds)
    if args.part in ("all", "speed"):
        record["speed"] = speed(model)
    if args.part == "walking":
        record["walking"] = walking(model, args.checkpoint, args.seeds)
    write_record(args.out, record)


if __name__ == "__main__":
    main()
