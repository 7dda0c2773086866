"""Evaluation of the MAR style transfer (issue 5, section 3; Xia et al. 2015, section 7).

Usage: ``python -m bench.eval_mar [--out bench/results/eval_mar.json] [--folds N] [--quick]``.
Needs both Bandai Namco data sets.

1. Leave-one-out cross-validation (paper 7.2) on pairs of one action in two styles: in each
   fold one take of the input style and the same-numbered take of the output style are held
   out, the database is built from everything else (all actions and styles of the data set),
   the input take is translated and compared with the held-out output take. Correspondence
   and timing ground truth match the takes gait cycle by gait cycle from their foot strikes
   (:func:`_ground_truth`; whole-take warping for other actions). Input takes that are
   fragments are not used (dataset 1 has one whole neutral walk only, so its pair is
   happy -> sad). Pose error: mean 3D joint distance (cm) of root-relative, heading-aligned
   poses on the output take's rig; timing error: mean absolute difference of the cumulative
   output times (seconds). Methods: MAR, and the classic local models of paper 7.4 on the K
   nearest frames of all classes pooled (nearest neighbour, KNN interpolation, a single local
   AR model), and a global linear AR model (one ridge fit per degree of freedom over
   all pairs of the labelled classes, constant mean timing), all unlabeled except the global
   model (which needs labels). Labelling (paper Table 3): MAR with action and style given,
   action only, style only, neither.
2. Emotion (:func:`emotion_inputs`): every whole neutral walk of dataset 1 (walk, walk-left,
   walk-right) and the neutral walks of dataset 2's held-out split, each left out of the
   database, translated to happy, sad and angry; the built-in classifier's window accuracy
   against the target (4-s windows of all outputs pooled), over its accuracy on the real
   dataset-1 walks of that emotion (target ratio >= 0.8).
3. Foot skate of those outputs (feet pinned, the generator's own contacts) against real walks
   (contacts detected), by :func:`emotive.eval.feet.foot_skating` (target: at most the
   real mean speed + 10 %).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

from bench.common import machine_info, write_record
from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.data.splits import split_clips
from emotive.eval.classifier import load_default_classifier
from emotive.eval.feet import foot_skating
from emotive.features.contacts import foot_contacts
from emotive.models.mar.build import FRAGMENT, _interp_rows, build_database
from emotive.models.mar.config import MARConfig, TransferError
from emotive.models.mar.default_index import clip_examples
from emotive.models.mar.registration import GaitCycle, body_features, register
from emotive.models.mar.regression import ridge_ar, standardize, track_rows
from emotive.models.mar.representation import RigCodec, heading_of_points
from emotive.models.mar.search import PointCloudSearch
from emotive.models.mar.transfer import transfer_motion

HERE = Path(__file__).resolve().parent

#: (data set, action, input style, output style) of the cross-validation pairs.
PAIRS = (
    ("bandai-namco-2-locomotion", "walk", "normal", "elderly"),
    ("bandai-namco-2-locomotion", "run", "normal", "exhausted"),
    ("bandai-namco-1", "walk", "happy", "sad"),
)
LABELS = {"both": (True, True), "action": (True, False), "style": (False, True),
          "neither": (False, False)}
EMOTIONS = ("happy", "sad", "angry")
WALKS = ("walk", "walk-left", "walk-right", "walk-back")


def _examples(dataset: str, exclude: tuple[str, ...]):
    config = MARConfig(datasets=(dataset,))
    return config, clip_examples(config, exclude)


def _pose_cm(codec, pred: np.ndarray, true: np.ndarray) -> float:
    """Mean joint distance (cm) of pose vectors placed at the origin facing +Z."""
    zeros = np.zeros((len(pred), 2))
    yaw = np.zeros(len(pred))
    a = codec.world_points(*codec.decode(pred, zeros, yaw))[2]
    b = codec.world_points(*codec.decode(true, zeros, yaw))[2]
    return float(100 * np.linalg.norm(a - b, axis=-1).mean())


def _score(row: dict, truth: tuple, frames, key: str) -> None:
    """Pose (cm) and timing (s) errors of stream frames (or ``(vectors, times)``) into ``row``."""
    codec, gt_vec, gt_time = truth
    if isinstance(frames, tuple):
        vectors, times = frames
    else:
        vectors = np.stack([f.vector for f in frames])
        times = np.array([f.time for f in frames])
    n = min(len(vectors), len(gt_vec))
    row[f"{key}_pose_cm"] = _pose_cm(codec, vectors[:n], gt_vec[:n])
    row[f"{key}_timing_s"] = float(np.abs(times[:n] - gt_time[:n]).mean() / 30.0)


def _ground_truth(inp, out, db):
    """Output-take pose vectors and output times (frames) at each input frame.

    Gaits are matched cycle by cycle: both takes get the unwrapped canonical time of the
    output take's gait cycle from their foot strikes (:class:`GaitCycle`), the ``i``-th cycle
    of the input corresponding to the ``i``-th of the output. The output time of an input
    frame is the output frame at its canonical time (extrapolated at the last cycle's rate
    past the output take's end); its pose is the output take's at the same phase (taken from
    the output's last cycles when the input has more cycles). Other actions: dynamic time
    warping of the whole takes.
    """
    feats = []
    for m in (inp, out):
        codec = db.codec(RigCodec.for_motion(m))
        vec, pts = codec.encode_motion(m)
        yaw = heading_of_points(pts, (13, 14), (5, 6))
        contacts = foot_contacts(m.positions_with_end_sites(), resolve_roles(m.skeleton), m.fps)
        feats.append((codec, vec, body_features(pts, yaw), contacts))
    cycle = GaitCycle.of(feats[1][3])
    u_in = cycle.unwrapped(feats[0][3]) if cycle else None
    u_out = cycle.unwrapped(feats[1][3]) if cycle else None
    if u_in is None or u_out is None:
        frames, _ = register(feats[0][2], feats[1][2])
        return feats[1][0], _interp_rows(feats[1][1], frames), frames - frames[0]
    index = np.arange(len(u_out), dtype=np.float64)
    frames = np.interp(u_in, u_out, index)
    head = (u_out[1] - u_out[0])
    tail = (u_out[-1] - u_out[-2])
    frames = np.where(u_in < u_out[0], (u_in - u_out[0]) / head, frames)
    frames = np.where(u_in > u_out[-1], index[-1] + (u_in - u_out[-1]) / tail, frames)
    phase = u_in.copy()
    while (phase > u_out[-1]).any():
        phase = np.where(phase > u_out[-1], phase - cycle.length, phase)
    while (phase < u_out[0]).any():
        phase = np.where(phase < u_out[0], phase + cycle.length, phase)
    pose_frames = np.interp(phase, u_out, index)
    return feats[1][0], _interp_rows(feats[1][1], pose_frames), frames - frames[0]


def _global_model(db, inp_vectors, classes_in, out_style):
    """Recursive global ridge AR over all pairs of ``classes_in`` -> ``out_style``."""
    frames = np.flatnonzero(np.isin(db.frame_class, classes_in))
    out_cls = np.array([db.track_of(c, out_style) for c in db.frame_class[frames]])
    y_t, rate, _ = track_rows(db, out_cls, db.tau[frames])
    y_p, _, _ = track_rows(db, out_cls, db.tau[db.prev[frames]])
    x_t = standardize(db, db.vectors[frames].astype(np.float64))
    x_p = standardize(db, db.vectors[db.prev[frames]].astype(np.float64))
    y_t, y_p = standardize(db, y_t), standardize(db, y_p)
    u = np.stack((x_p, y_p, x_t, np.ones_like(x_t)), -1).transpose(1, 0, 2)
    beta = ridge_ar(u, y_t.T, db.config.ridge)
    advance = float(np.mean(db.rate[frames] * rate))
    xs = standardize(db, inp_vectors)
    y = y_t[np.argmin(((x_t - xs[0]) ** 2).sum(1))]
    out = [y]
    for t in range(1, len(xs)):
        u_q = np.stack((xs[t - 1], out[-1], xs[t], np.ones(len(y))), -1)
        out.append((u_q * beta).sum(-1))
    return np.stack(out) * db.std + db.mean, np.arange(len(xs)) * advance


def cross_validation(folds: int) -> list[dict]:
    """Section 1 of the module docstring."""
    rows = []
    for dataset, action, s_in, s_out in PAIRS:
        clips = {c.name: c for c in load_clips(dataset, contents=[action])}
        prefix = f"{dataset.split('-')[0]}-{1 if dataset.endswith('1') else 2}"
        takes = sorted({n.rsplit("_", 1)[1] for n in clips
                        if f"_{s_in}_" in n and n.replace(f"_{s_in}_", f"_{s_out}_") in clips})
        for take in takes[:folds]:
            name_in = f"dataset-{prefix[-1]}_{action}_{s_in}_{take}"
            name_out = f"dataset-{prefix[-1]}_{action}_{s_out}_{take}"
            inp, out = clips[name_in].motion, clips[name_out].motion
            config, examples = _examples(dataset, (name_in, name_out))
            db = build_database(examples, config)
            style_label = "neutral" if s_in == "normal" else s_in
            try:
                db.classes_where(action, style_label)
            except TransferError:
                # The held-out take was the class's only whole take (the rest are fragments).
                print(f"  skipped {name_in}: no other whole {s_in} take", flush=True)
                continue
            search = PointCloudSearch(db)
            codec, gt_vec, gt_time = _ground_truth(inp, out, db)
            target = {"normal": "neutral"}.get(s_out, s_out)
            row = {"pair": f"{dataset}/{action}: {s_in} -> {s_out}", "take": take,
                   "frames": inp.num_frames}

            truth = (codec, gt_vec, gt_time)
            for method in ("mar", "ar", "knn", "nn"):
                res = transfer_motion(inp, db, target, search=search, pin=False, method=method)
                _score(row, truth, res.frames, method)
            for label, (give_action, give_style) in LABELS.items():
                res = transfer_motion(inp, db, target, search=search, pin=False,
                                      action=action if give_action else None,
                                      input_style=style_label if give_style else None)
                _score(row, truth, res.frames, f"mar_{label}")
            in_vec = db.codec(RigCodec.for_motion(inp)).encode_motion(inp)[0]
            vec, times = _global_model(db, in_vec, db.classes_where(action, style_label), target)
            _score(row, truth, (vec, times), "global")
            rows.append(row)
            print(f"  {row['pair']} take {take}: " + ", ".join(
                f"{k}={v:.2f}" for k, v in row.items() if k.endswith(("cm", "_s"))), flush=True)
    return rows


def emotion_inputs() -> list:
    """Neutral walks to transfer, from both data sets.

    Neutral walks to transfer: every whole neutral walk of dataset 1 (walk, walk-left,
    walk-right; its split has no held-out walk) and the neutral walks of dataset 2's held-out
    (validation and test) split.
    """
    walks = load_clips("bandai-namco-1", contents=list(WALKS))
    median = {a: np.median([c.motion.num_frames for c in walks if c.content == a])
              for a in WALKS}
    first = [c for c in walks if c.style == "normal"
             and c.motion.num_frames >= FRAGMENT * median[c.content]]
    second = split_clips(load_clips("bandai-namco-2-locomotion", contents=["walk"]))
    return first + [c for split in ("val", "test") for c in second[split] if c.style == "normal"]


def emotion_and_skate(max_inputs: int | None) -> dict:
    """Sections 2 and 3 of the module docstring."""
    classifier = load_default_classifier()
    walks = load_clips("bandai-namco-1", contents=list(WALKS))
    inputs = emotion_inputs()[:max_inputs]

    def hits(motion, label) -> tuple[int, int]:
        _, prob = classifier.classify(motion)
        return int((np.array(classifier.labels)[prob.argmax(1)] == label).sum()), len(prob)

    real_hits = {e: np.sum([hits(c.motion, e) for c in walks if c.info.emotion == e
                            and c.motion.duration >= classifier.config.min_seconds], axis=0)
                 for e in EMOTIONS}
    real = {e: float(h[0] / h[1]) for e, h in real_hits.items()}
    real_skate = []
    for c in walks:
        if c.info.emotion in EMOTIONS:
            pts = c.motion.positions_with_end_sites()
            real_skate.append(foot_skating(pts, resolve_roles(c.motion.skeleton),
                                           c.motion.fps).mean_speed)
    config = MARConfig()
    everything = clip_examples(config)
    got = {e: np.zeros(2, dtype=int) for e in EMOTIONS}
    per_input = []
    skate, skate_detected = [], []
    for clip in inputs:
        db = build_database([x for x in everything if x.name != clip.name], config)
        search = PointCloudSearch(db)
        row = {"input": clip.name}
        for e in EMOTIONS:
            res = transfer_motion(clip.motion, db, e, search=search)
            h = hits(res.motion, e)
            got[e] += h
            row[e] = f"{h[0]}/{h[1]}"
            pts = res.motion.positions_with_end_sites()
            roles = resolve_roles(res.motion.skeleton)
            skate.append(foot_skating(pts, roles, res.motion.fps, res.contacts).mean_speed)
            skate_detected.append(foot_skating(pts, roles, res.motion.fps).mean_speed)
        per_input.append(row)
        print("  " + ", ".join(f"{k}={v}" for k, v in row.items()), flush=True)
    transfer = {e: float(got[e][0] / got[e][1]) for e in EMOTIONS}
    return {
        "inputs": per_input,
        "real_accuracy": real,
        "real_windows": {e: int(h[1]) for e, h in real_hits.items()},
        "transfer_accuracy": transfer,
        "transfer_windows": {e: int(got[e][1]) for e in EMOTIONS},
        "ratio": {e: transfer[e] / real[e] if real[e] else float("nan") for e in EMOTIONS},
        "foot_skate_m_s": {"real": float(np.mean(real_skate)),
                           "output_own_contacts": float(np.mean(skate)),
                           "output_detected_contacts": float(np.mean(skate_detected))},
    }


def main() -> None:
    """Run the evaluation from the command line and write its record."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "eval_mar.json")
    parser.add_argument("--folds", type=int, default=4)
    parser.add_argument("--max-inputs", type=int, default=None)
    args = parser.parse_args()
    from threadpoolctl import threadpool_limits  # noqa: PLC0415 (optional threadpoolctl)

    torch.set_num_threads(1)
    start = time.time()
    with threadpool_limits(1):
        print("cross-validation ...", flush=True)
        rows = cross_validation(args.folds)
        keys = [k for k in rows[0] if k.endswith(("_cm", "_s"))]
        summary = {k: float(np.mean([r[k] for r in rows])) for k in keys}
        for k, v in summary.items():
            print(f"{k:28} {v:8.3f}")
        print("emotion and foot skate ...", flush=True)
        emotion = emotion_and_skate(args.max_inputs)
    print(emotion)
    write_record(args.out, {"time": time.strftime("%Y-%m-%dT%H:%M:%S"),
                            "seconds": time.time() - start, "machine": machine_info(),
                            "cross_validation": {"folds": rows, "mean": summary},
                            "emotion": emotion})


if __name__ == "__main__":
    main()
