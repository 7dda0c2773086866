"""How far dataset 1's four labels carry from one take to another: a leave-one-clip-out probe.

Dataset 1 holds each style as one actor's few takes (about seven locomotion clips per label),
so whether *any* model trained on it can read a new take of a label is a property of the data,
not of the classifier's recipe. This probe measures it with the simplest model that could: for
each labelled (happy, sad, angry, normal) locomotion clip of dataset 1, a logistic regression
(scikit-learn, standardized inputs) on clip summaries, trained on every *other* labelled clip
of dataset 1, gives that clip's label probabilities. The summaries are the means and standard
deviations of the classifier's affective and movement features
(:func:`emotive.eval.classifier.track_features`, stepping phase left out), the mean body-frame
pose and the mean absolute body-frame velocity: :data:`SUMMARY_COLUMNS` numbers per clip.

Printed: the leave-one-clip-out accuracy per label, the probabilities of every straight-walk
clip beside the committed classifier's mean probabilities over its 4 s windows, and what a
probe trained on all of dataset 1's labelled clips reads in dataset 2's ``normal``,
``exhausted`` and ``active`` clips (another session, actors and rig).

Usage: ``python -m bench.eval_classifier_probe [--c 1.0]`` (about a minute; needs the data).
"""

from __future__ import annotations

import argparse

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from emotive.eval.classifier import EmotionClassifier, load_default_classifier, track_features
from emotive.eval.classifier_training import ClipTrack, load_tracks

#: Dataset-1 style of each classifier label, in the classifier's label order.
STYLE_OF_LABEL = {"happy": "happy", "sad": "sad", "angry": "angry", "neutral": "normal"}
#: Columns of the per-frame features: body-frame pose, body-frame velocity, the rest.
POSE, VELOCITY = slice(0, 63), slice(63, 126)
#: The affective and movement columns summarized (the stepping phase's sine and cosine left out).
AFFECT = np.r_[126:126 + 18 + 5, 126 + 18 + 7]
SUMMARY_COLUMNS = 2 * len(AFFECT) + 63 + 63
#: Dataset-2 styles read by the probe trained on all of dataset 1.
OTHER_SESSION_STYLES = ("normal", "exhausted", "active")


def clip_summary(features: np.ndarray) -> np.ndarray:
    """``(SUMMARY_COLUMNS,)`` summary of one clip's ``(T, F)`` classifier features."""
    a = features[:, AFFECT]
    return np.concatenate((a.mean(0), a.std(0), features[:, POSE].mean(0),
                           np.abs(features[:, VELOCITY]).mean(0)))


def _row(p: np.ndarray) -> str:
    return " ".join(f"{v:.2f}" for v in p)


def _probe(c: float):
    return make_pipeline(StandardScaler(), LogisticRegression(C=c, max_iter=5000))


def leave_one_clip_out(tracks: list[ClipTrack], model: EmotionClassifier, c: float
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Leave-one-clip-out probabilities ``(N, 4)``, labels ``(N,)`` and summaries ``(N, S)``."""
    labels = model.labels
    style_to_index = {STYLE_OF_LABEL[name]: k for k, name in enumerate(labels)}
    x = np.array([clip_summary(track_features(t.points, t.fps, model.config)) for t in tracks])
    y = np.array([style_to_index[t.style] for t in tracks])
    probabilities = np.zeros((len(tracks), len(labels)))
    for i in range(len(tracks)):
        keep = np.arange(len(tracks)) != i
        probabilities[i] = _probe(c).fit(x[keep], y[keep]).predict_proba(x[i:i + 1])[0]
    return probabilities, y, x


def main() -> None:
    """Print the probe's numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--c", type=float, default=1.0, help="inverse L2 strength")
    args = parser.parse_args()
    model = load_default_classifier()
    labels = model.labels
    styles = set(STYLE_OF_LABEL.values())
    tracks = load_tracks(["bandai-namco-1", "bandai-namco-2-locomotion"])
    d1 = [t for t in tracks if t.dataset == "bandai-namco-1" and t.style in styles]
    probabilities, y, x = leave_one_clip_out(d1, model, args.c)
    hit = probabilities.argmax(1) == y
    print(f"leave-one-clip-out probe over {len(d1)} labelled dataset-1 locomotion clips: "
          f"accuracy {hit.mean():.3f}")
    for k, name in enumerate(labels):
        print(f"  {name:8} {hit[y == k].mean():.2f} of {(y == k).sum()} clips")
    print(f"\n{'clip':28} {'split':6} {'probe (left out)':>24}   committed classifier")
    for i, t in enumerate(d1):
        if not t.name.startswith("dataset-1_walk_"):
            continue
        _, windows = model.windows(track_features(t.points, t.fps, model.config), 4.0, 1.0)
        ours = model.predict_features(windows).mean(0)
        print(f"{t.name[10:]:28} {t.split:6} {_row(probabilities[i]):>24}   {_row(ours)}")
    probe = _probe(args.c).fit(x, y)
    print(f"\nprobe trained on all {len(d1)} clips, mean probabilities "
          f"({', '.join(labels)}) on dataset 2:")
    for style in OTHER_SESSION_STYLES:
        clips = [t for t in tracks if t.dataset != "bandai-namco-1" and t.style == style]
        z = np.array([clip_summary(track_features(t.points, t.fps, model.config))
                      for t in clips])
        print(f"  {style:10} {len(clips):4} clips  "
              f"{_row(probe.predict_proba(z).mean(0))}")


if __name__ == "__main__":
    main()
