"""Emotion control of the gait network: label blends and valence/arousal points.

Part of ``python -m bench.eval_gait`` (``--part control``). Every walk is 10 seconds of the
committed network on a straight 40 m line (the stream, foot lock on), measured after its
first :data:`SETTLE_SECONDS`:

* **Blends**: walking speed for ``happy=w,sad=1-w`` over :data:`HAPPY_WEIGHTS`; monotone when
  every step up in ``w`` walks faster.
* **Valence/arousal**: walking speed and arm swing along a valence line (arousal
  :data:`LINE_AROUSAL`) and an arousal line (valence 0), :data:`LINE_POINTS` points each from
  -0.8 to 0.8; smoothness is the largest change between neighbours as a share of the whole
  change along the line (1 / (points - 1) for an even ramp, 1 for a single jump).
* **Label points**: at the valence/arousal point of each of the four labels, the classifier's
  mean probability of that label for the point's walk beside the label's own walk (the point
  is a kernel blend of nearby labels, not the one-hot label).

Arm swing: the 5-95 % range of each wrist's forward offset from the mover joint (the line runs
along +Z), mean of the two wrists, metres.
"""

from __future__ import annotations

import numpy as np

from emotive.core.roles import resolve_roles
from emotive.data.emotion import Emotion
from emotive.eval.classifier import EmotionClassifier
from emotive.models.gait.model import GaitModel
from emotive.models.gait.walks import GeneratedWalk, generate_walks
from emotive.paths import line

HAPPY_WEIGHTS = (0.0, 0.25, 0.5, 0.75, 1.0)
LINE_POINTS = 9
LINE_AROUSAL = 0.3
SETTLE_SECONDS = 3.0
SECONDS = 10.0
LABELS = ("happy", "sad", "angry", "neutral")


def walk_measures(walk: GeneratedWalk, model: GaitModel) -> tuple[float, float]:
    """Walking speed (m/s) and arm swing (m) of one walk on a straight +Z line."""
    m = walk.motion
    start = round(SETTLE_SECONDS * m.fps)
    p = m.positions_with_end_sites()[start:]
    mover = p[:, model.controls.mover]
    speed = float(np.linalg.norm(np.diff(mover[:, [0, 2]], axis=0), axis=1).mean() * m.fps)
    roles = resolve_roles(m.skeleton)
    swing = [np.subtract(*np.percentile(p[:, roles.index[w], 2] - mover[:, 2], [95, 5]))
             for w in ("l_wrist", "r_wrist")]
    return speed, float(np.mean(swing))


def _walks(model: GaitModel, emotions: list) -> list[GeneratedWalk]:
    return generate_walks(model, [line(40.0)] * len(emotions), emotions, SECONDS)


def _smoothness(values: np.ndarray) -> float:
    span = float(values.max() - values.min())
    return float(np.abs(np.diff(values)).max() / span) if span > 0 else 0.0


def blend_rows(model: GaitModel) -> dict:
    """Walking speed over ``happy=w,sad=1-w`` (see the module docstring)."""
    emotions = [{"happy": w, "sad": 1.0 - w} if 0 < w < 1 else ("happy" if w else "sad")
                for w in HAPPY_WEIGHTS]
    speeds = [walk_measures(w, model)[0] for w in _walks(model, emotions)]
    monotone = bool(np.all(np.diff(speeds) > 0))
    print(f"blend sad -> happy, speed over happy weight {HAPPY_WEIGHTS}: "
          f"{np.round(speeds, 3).tolist()} m/s, monotone {monotone}", flush=True)
    return {"happy_weights": list(HAPPY_WEIGHTS), "speed_m_s": speeds, "monotone": monotone}


def valence_arousal_rows(model: GaitModel) -> dict:
    """Speed and arm swing along a valence line and an arousal line."""
    grid = np.linspace(-0.8, 0.8, LINE_POINTS)
    out = {}
    for name, points in (("valence", [(v, LINE_AROUSAL) for v in grid]),
                         ("arousal", [(0.0, a) for a in grid])):
        emotions = [{"valence": float(v), "arousal": float(a)} for v, a in points]
        measures = np.array([walk_measures(w, model) for w in _walks(model, emotions)])
        out[name] = {
            "points": [list(p) for p in points],
            "speed_m_s": measures[:, 0].tolist(), "arm_swing_m": measures[:, 1].tolist(),
            "speed_smoothness": _smoothness(measures[:, 0]),
            "arm_swing_smoothness": _smoothness(measures[:, 1]),
        }
        print(f"{name} line: speed {np.round(measures[:, 0], 2).tolist()} m/s (largest step "
              f"{out[name]['speed_smoothness']:.2f} of the change), arm swing "
              f"{np.round(measures[:, 1], 3).tolist()} m "
              f"({out[name]['arm_swing_smoothness']:.2f})", flush=True)
    return out


def label_point_rows(model: GaitModel, classifier: EmotionClassifier) -> dict:
    """The classifier on each label's walk and on its valence/arousal point's walk."""
    points = [Emotion.one_hot(e, classifier.labels).valence_arousal() for e in LABELS]
    emotions = list(LABELS) + [{"valence": float(v), "arousal": float(a)} for v, a in points]
    walks = _walks(model, emotions)
    out = {}
    for k, label in enumerate(LABELS):
        c = classifier.labels.index(label)
        by_label = classifier.judge(walks[k].motion).probabilities.mean(0)
        by_point = classifier.judge(walks[len(LABELS) + k].motion).probabilities.mean(0)
        out[label] = {
            "point": [float(x) for x in points[k]],
            "p_label_walk": float(by_label[c]), "p_point_walk": float(by_point[c]),
            "perceived_label_walk": classifier.labels[int(np.argmax(by_label))],
            "perceived_point_walk": classifier.labels[int(np.argmax(by_point))],
        }
        print(f"{label}: P({label}) {by_label[c]:.2f} for the label, {by_point[c]:.2f} at its "
              f"point {np.round(points[k], 2).tolist()} (perceived "
              f"{out[label]['perceived_label_walk']} / {out[label]['perceived_point_walk']})",
              flush=True)
    return out
