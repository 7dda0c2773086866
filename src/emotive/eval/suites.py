"""The evaluation suites over motions with an intended emotion (see :mod:`.sources`).

Each suite takes :class:`~emotive.eval.sources.EvaluatedMotion` items and returns a JSON-ready
dict; :mod:`emotive.eval.report` turns the dicts into ``report.md``, ``metrics.json`` and
plots.

* ``emotion``: the perceived-emotion classifier judges every item in windows; intended versus
  perceived per item with the main paper's Table-3 test (2-sample Anderson-Darling between the
  item's mean intended and mean perceived emotion vectors), a confusion matrix of dominant
  labels per window, and the accuracy as a share of the classifier's accuracy on real
  held-out motion.
* ``transition``: items whose dominant intended label changes: Table-3 tests on the first and
  the last window, and the jerk around each change against the windowed jerk of real motion
  (above its 99th percentile counts as not smooth).
* ``path``: items with a path: distance of the root from the path and heading deviation.
* ``longrun``: motion energy (mean joint speed, root-relative) per second, collapse and
  explosion detection against the energy of real motion of the item's dominant emotion, and
  the share of seconds inside that real 5-95 % range.
* ``quality``: foot skating, ground penetration and jerk, against real motion.
* ``affect``: per emotion, the Fréchet distance between the per-frame affective and movement
  features (18 + 8 columns of :func:`emotive.eval.classifier.frame_features`) of the items and
  those of real held-out motion of that emotion, beside the same distance between real
  training and real held-out motion (what "as close as real data" looks like); and the
  diversity between items of one emotion.

Real reference statistics come from :func:`real_reference` (real clips of the labels).

One suite judges a predictor instead of motions: ``table1`` (:func:`table1_suite`), the main
paper's Table 1 protocol (:func:`emotive.eval.table1.table1`) on the locomotion test clips of
each data set and of both together, the predictor beside the baselines of
:func:`table1_baselines`, at 10 and 30 fps, with the pose error by horizon at 10 fps
(:mod:`emotive.eval.horizon`).

Legend: ``T`` frames, ``J`` joints, ``C`` labels, ``K`` windows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.data.clips import load_clips
from emotive.data.emotion import ALL_LABELS
from emotive.data.splits import split_clips
from emotive.errors import DataError
from emotive.eval import distributions, feet, path_following, smoothness, stability
from emotive.eval.classifier import EmotionClassifier, frame_features
from emotive.eval.horizon import by_horizon
from emotive.eval.sources import EvaluatedMotion
from emotive.eval.stats import StatsInputError, anderson_darling_ksamp
from emotive.eval.table1 import Predictor, Table1Result, ZeroVelocity, merge_results, table1


def real_test_metrics(classifier: EmotionClassifier) -> dict:
    """The classifier's own held-out numbers on the real walks the suites compare with.

    The dataset-1 test clips of its labels (the held-out subject of :mod:`emotive.eval.
    evaluate`) when the classifier records per data set, else its whole test split.
    """
    by_dataset = classifier.metrics.get("test_by_dataset", {})
    return by_dataset.get("bandai-namco-1") or classifier.metrics.get("test", {})

#: Seconds per window of the classifier and the energy measure.
WINDOW_SECONDS = 4.0
HOP_SECONDS = 1.0
ENERGY_WINDOW_SECONDS = 1.0
#: Significance level of the Table-3 tests.
ALPHA = 0.05


@dataclass(frozen=True)
class RealReference:
    """Statistics of real motion the suites compare against.

    Attributes:
        labels: the labels.
        window_jerk: ``(N,)`` windowed jerk samples of real clips (m/s^3).
        energy: label -> ``(N,)`` per-second motion energy samples (m/s).
        skate: mean planted-foot speed of the real clips (m/s).
        jerk: mean jerk of the real clips (m/s^3).
        held_out: label -> ``(N, 26)`` affect features of the real val and test clips.
        train: label -> ``(N, 26)`` affect features of the real train clips.
        source: which clips.
    """

    labels: tuple[str, ...]
    window_jerk: np.ndarray
    energy: dict[str, np.ndarray]
    skate: float
    jerk: float
    held_out: dict[str, np.ndarray]
    train: dict[str, np.ndarray]
    source: str


#: Columns of :func:`emotive.eval.classifier.frame_features` that the affect suite compares:
#: the 18 affective and 8 movement features (the body-frame pose and velocity are left out).
AFFECT_COLUMNS = slice(-26, None)
#: Frame rate of the affect features.
AFFECT_FPS = 15.0


def affect_features(motion: Motion) -> np.ndarray:
    """``(T', 26)`` affective and movement features of a clip at :data:`AFFECT_FPS`."""
    points, roles, _ = _points(motion)
    return frame_features(points, roles, motion.fps, AFFECT_FPS)[:, AFFECT_COLUMNS]


def _points(motion: Motion) -> tuple[np.ndarray, object, int]:
    roles = resolve_roles(motion.skeleton)
    return motion.positions_with_end_sites(), roles, roles.index["root"]


def _energy(motion: Motion) -> np.ndarray:
    """Per-second energy of the joints relative to the root role (Hips on the Bandai rig)."""
    root = motion.skeleton.index(resolve_roles(motion.skeleton).names["root"])
    return stability.motion_energy(motion.global_positions(), motion.fps, ENERGY_WINDOW_SECONDS,
                                   root_index=root)


def _bone_parents(motion: Motion) -> np.ndarray:
    """Parents for the bone-stretch check.

    A joint whose local translation moves (the hips carrying the world position) is no bone of its
    parent.
    """
    parents = np.array(motion.skeleton.parents)
    moving = np.ptp(motion.positions, axis=0).max(-1) > 0.05 if motion.num_frames else []
    parents[np.asarray(moving, dtype=bool)] = -1
    return parents


def real_reference(labels: Sequence[str], locomotion: bool = True) -> RealReference:
    """Reference statistics from the dataset-1 clips of ``labels``.

    Reference statistics from the dataset-1 clips of ``labels`` (all splits: a reference
    of what real motion does, not a test set). Needs the data (see :mod:`emotive.data`).
    """
    clips = [c for c in load_clips("bandai-namco-1", locomotion=locomotion)
             if c.info.emotion in labels]
    part = {c.name: split for split, members in split_clips(clips).items() for c in members}
    jerks, energy, skates, mean_jerk = [], {label: [] for label in labels}, [], []
    held_out: dict[str, list[np.ndarray]] = {label: [] for label in labels}
    train: dict[str, list[np.ndarray]] = {label: [] for label in labels}
    for clip in clips:
        m = clip.motion
        points, roles, _ = _points(m)
        if m.duration >= ENERGY_WINDOW_SECONDS:
            energy[clip.info.emotion].append(_energy(m))
        if m.num_frames > 8:
            jerks.append(smoothness.windowed_jerk(points, m.fps))
            mean_jerk.append(float(smoothness.jerk(points, m.fps).mean()))
        skates.append(float(feet.foot_skating(points, roles, m.fps).mean_speed))
        target = train if part[clip.name] == "train" else held_out
        target[clip.info.emotion].append(affect_features(m))

    def stack(table: dict[str, list[np.ndarray]]) -> dict[str, np.ndarray]:
        return {k: np.concatenate(v) if v else np.zeros((0, 26)) for k, v in table.items()}

    return RealReference(
        tuple(labels), np.concatenate(jerks),
        {k: np.concatenate(v) if v else np.zeros(0) for k, v in energy.items()},
        float(np.mean(skates)), float(np.mean(mean_jerk)), stack(held_out), stack(train),
        f"bandai-namco-1 {'locomotion ' if locomotion else ''}clips of {', '.join(labels)} "
        f"({len(clips)} clips)",
    )


def _table3(intended: np.ndarray, perceived: np.ndarray) -> dict:
    """The main paper's per-gait test: 2-sample Anderson-Darling of two emotion vectors."""
    try:
        result = anderson_darling_ksamp([intended, perceived])
    except StatsInputError as exc:
        return {"statistic": None, "p_value": None, "reject": None, "note": str(exc)}
    return {"statistic": result.statistic, "p_value": result.p_value,
            "p_value_bounded": result.p_value_bounded, "reject": result.p_value < ALPHA}


def _on_classifier_labels(item: EvaluatedMotion, labels: tuple[str, ...]) -> np.ndarray | None:
    """The item's intended weights over the classifier's labels, or ``None``.

    The item's intended weights over the classifier's labels, or ``None`` if it intends
    labels the classifier does not know.
    """
    index = {label: k for k, label in enumerate(item.labels)}
    foreign = [k for label, k in index.items() if label not in labels]
    if foreign and item.intended[:, foreign].max() > 1e-6:
        return None
    out = np.zeros((len(item.intended), len(labels)))
    for k, label in enumerate(labels):
        if label in index:
            out[:, k] = item.intended[:, index[label]]
    return out / np.maximum(out.sum(-1, keepdims=True), 1e-12)


def emotion_suite(items: Sequence[EvaluatedMotion], classifier: EmotionClassifier) -> dict:
    """Intended versus perceived emotion (see the module docstring)."""
    labels = classifier.labels
    n = len(labels)
    confusion = np.zeros((n, n), dtype=np.int64)
    rows, skipped = [], []
    for item in items:
        intended = _on_classifier_labels(item, labels)
        if intended is None or item.motion.duration < classifier.config.min_seconds:
            skipped.append(item.name)
            continue
        times, prob = classifier.classify(item.motion, WINDOW_SECONDS, HOP_SECONDS)
        frames = np.clip(np.round(times * item.motion.fps).astype(int), 0, len(intended) - 1)
        want = intended[frames].argmax(-1)
        got = prob.argmax(-1)
        np.add.at(confusion, (want, got), 1)
        mean_intended, mean_perceived = intended.mean(0), prob.mean(0)
        rows.append({
            "name": item.name,
            "intended": dict(zip(labels, map(float, mean_intended), strict=True)),
            "perceived": dict(zip(labels, map(float, mean_perceived), strict=True)),
            "window_accuracy": float((want == got).mean()),
            "table3": _table3(mean_intended, mean_perceived),
        })
    windows = int(confusion.sum())
    accuracy = float(np.trace(confusion) / windows) if windows else None
    real = real_test_metrics(classifier).get("window_accuracy")
    return {
        "labels": list(labels),
        "items": rows,
        "skipped": skipped,
        "windows": windows,
        "window_accuracy": accuracy,
        "real_window_accuracy": real,
        "share_of_real_accuracy": accuracy / real if accuracy is not None and real else None,
        "confusion": confusion.tolist(),
        "table3_rejected": sum(bool(r["table3"]["reject"]) for r in rows),
    }


def transition_suite(items: Sequence[EvaluatedMotion], classifier: EmotionClassifier,
                     reference: RealReference | None) -> dict:
    """Emotion changes: perceived start and end, smoothness (see the module docstring)."""
    labels = classifier.labels
    rows = []
    for item in items:
        changes = item.changes
        intended = _on_classifier_labels(item, labels)
        if not len(changes) or intended is None:
            continue
        times, prob = classifier.classify(item.motion, WINDOW_SECONDS, HOP_SECONDS)
        frames = np.clip(np.round(times * item.motion.fps).astype(int), 0, len(intended) - 1)
        row = {
            "name": item.name,
            "change_seconds": (changes / item.motion.fps).tolist(),
            "initial": _table3(intended[frames[0]], prob[0]),
            "final": _table3(intended[frames[-1]], prob[-1]),
            "initial_perceived": labels[int(prob[0].argmax())],
            "final_perceived": labels[int(prob[-1].argmax())],
            "initial_intended": labels[int(intended[frames[0]].argmax())],
            "final_intended": labels[int(intended[frames[-1]].argmax())],
        }
        if reference is not None:
            points, _, _ = _points(item.motion)
            smooth = smoothness.transition_smoothness(points, item.motion.fps, changes,
                                                      reference.window_jerk)
            row["jerk"] = np.asarray(smooth.jerk).tolist()
            row["jerk_percentile"] = np.asarray(smooth.percentile).tolist()
            row["smooth"] = not bool(np.any(smooth.exceeds))
            row["jerk_threshold"] = float(smooth.threshold)
        rows.append(row)
    return {"items": rows, "reference": reference.source if reference else None}


def path_suite(items: Sequence[EvaluatedMotion]) -> dict:
    """How closely items with a path follow it."""
    rows = []
    for item in items:
        if item.path is None:
            continue
        points, roles, _ = _points(item.motion)
        result = path_following.path_following(points, roles, item.path)
        rows.append({
            "name": item.name,
            "mean_position_deviation": float(result.position_deviation.mean()),
            "max_position_deviation": float(result.position_deviation.max()),
            "mean_heading_deviation": float(result.heading_deviation.mean()),
            "trajectory": points[:, roles.index["root"]][:, [0, 2]].tolist(),
            "path": np.asarray(item.path).tolist(),
        })
    return {"items": rows}


def longrun_suite(items: Sequence[EvaluatedMotion], reference: RealReference | None) -> dict:
    """Energy over time and stability against real motion of the same emotion."""
    rows = []
    for item in items:
        if item.motion.duration < ENERGY_WINDOW_SECONDS:
            continue
        energy = _energy(item.motion)
        # The emotion intended in each window, and the real energy band of that emotion.
        n = round(ENERGY_WINDOW_SECONDS * item.motion.fps)
        centres = np.minimum((np.arange(len(energy)) + 0.5) * n, len(item.intended) - 1)
        window_labels = [item.labels[k] for k in item.intended[centres.astype(int)].argmax(-1)]
        label = item.labels[int(item.intended.mean(0).argmax())]
        real = reference.energy if reference is not None else {}
        ref_level = float(np.median(real[label])) if len(real.get(label, [])) else None
        report = stability.stability_report(
            item.motion.global_positions(), item.motion.fps, _bone_parents(item.motion),
            reference_energy=ref_level, window_s=ENERGY_WINDOW_SECONDS,
            root_index=item.motion.skeleton.index(resolve_roles(item.motion.skeleton)
                                                  .names["root"]),
        )
        row = {
            "name": item.name, "label": label, "energy": energy.tolist(),
            "window_labels": window_labels,
            "stable": bool(report.stable), "collapsed_at": report.collapse_time,
            "exploded_at": report.explosion_time,
        }
        bands = {k: np.percentile(v, [5, 95]) for k, v in real.items() if len(v)}
        if all(k in bands for k in window_labels):
            lo = np.array([bands[k][0] for k in window_labels])
            hi = np.array([bands[k][1] for k in window_labels])
            row["real_energy_band"] = {k: [float(a), float(b)] for k, (a, b) in bands.items()}
            row["share_in_real_band"] = float(((energy >= lo) & (energy <= hi)).mean())
        rows.append(row)
    return {"items": rows, "reference": reference.source if reference else None}


def quality_suite(items: Sequence[EvaluatedMotion], reference: RealReference | None) -> dict:
    """Foot skating and ground penetration per item, and skating relative to real motion."""
    rows = []
    for item in items:
        points, roles, _ = _points(item.motion)
        skate = feet.foot_skating(points, roles, item.motion.fps)
        depth = feet.ground_penetration(points, roles)
        rows.append({
            "name": item.name, "skate_speed": float(skate.mean_speed),
            "skate_ratio": float(skate.ratio), "penetration_max": float(depth.max),
            "jerk": float(smoothness.jerk(points, item.motion.fps).mean())
            if item.motion.num_frames > 3 else None,
        })
    mean_skate = float(np.mean([r["skate_speed"] for r in rows])) if rows else None
    jerks = [r["jerk"] for r in rows if r["jerk"] is not None]
    mean_jerk = float(np.mean(jerks)) if jerks else None
    real = reference.skate if reference is not None else None
    real_jerk = reference.jerk if reference is not None else None
    return {
        "items": rows, "mean_skate_speed": mean_skate, "real_skate_speed": real,
        "skate_vs_real": mean_skate / real if mean_skate is not None and real else None,
        "mean_jerk": mean_jerk, "real_jerk": real_jerk,
        "jerk_vs_real": mean_jerk / real_jerk if mean_jerk is not None and real_jerk else None,
        "reference": reference.source if reference else None,
    }


def affect_suite(items: Sequence[EvaluatedMotion], reference: RealReference | None) -> dict:
    """Affective realism and diversity per emotion (see the module docstring)."""
    by_label: dict[str, list[tuple[str, np.ndarray]]] = {}
    for item in items:
        label = item.labels[int(item.intended.mean(0).argmax())]
        by_label.setdefault(label, []).append((item.name, affect_features(item.motion)))
    rows = []
    for label, members in by_label.items():
        frames = np.concatenate([f for _, f in members])
        row: dict = {"label": label, "items": [n for n, _ in members], "frames": len(frames)}
        real = reference.held_out.get(label) if reference is not None else None
        train = reference.train.get(label) if reference is not None else None
        if real is not None and len(real) >= 2 and len(frames) >= 2:
            row["frechet_to_real"] = distributions.frechet_distance(frames, real)
            if train is not None and len(train) >= 2:
                row["frechet_real_train_to_real"] = distributions.frechet_distance(train, real)
        if len(members) >= 2:
            row["diversity"] = distributions.diversity(np.stack([f.mean(0) for _, f in members]))
        rows.append(row)
    return {"labels": rows, "reference": reference.source if reference else None}


#: The data sets whose locomotion test clips the ``table1`` suite evaluates, by their name in
#: its tables.
TABLE1_SETS: dict[str, str] = {"dataset 1": "bandai-namco-1",
                               "dataset 2": "bandai-namco-2-locomotion"}
#: Name of the pooled windows of every data set in the ``table1`` suite's tables.
BOTH_SETS = "both"
#: Frame rates of the ``table1`` suite, and the one of its errors by horizon.
TABLE1_RATES: tuple[float, ...] = (10.0, 30.0)
HORIZON_FPS = 10.0


def table1_baselines(predictor: Predictor) -> list[Predictor]:
    """The predictors a Table 1 subject is shown beside: QuaterNet and zero velocity.

    The paper's baseline (the registry's ``quaternet``) and holding the last frame
    (:class:`~emotive.eval.table1.ZeroVelocity`), less any named as ``predictor`` is.
    """
    # Deferred: the registry's loaders import the models, which the motion suites do not need.
    from emotive.models.registry import get_model  # noqa: PLC0415

    baselines = [get_model("quaternet").load("predictor"), ZeroVelocity()]
    return [b for b in baselines if b.name != predictor.name]


def table1_test_sets() -> tuple[dict[str, list], dict[str, str]]:
    """The locomotion test clips of each of :data:`TABLE1_SETS` that is installed.

    Returns:
        ``(set name -> clips, set name -> why it is missing)``.

    Raises:
        DataError: none of the data sets is installed.
    """
    sets, missing = {}, {}
    for name, dataset in TABLE1_SETS.items():
        try:
            sets[name] = split_clips(load_clips(dataset, locomotion=True))["test"]
        except DataError as exc:
            missing[name] = str(exc)
    if not sets:
        raise DataError(f"the table1 suite needs the test clips of "
                        f"{', '.join(TABLE1_SETS.values())}: {'; '.join(missing.values())}")
    return sets, missing


def table1_runs(predictors: Sequence[Predictor], sets: dict[str, list], fps: float
                ) -> dict[str, Table1Result]:
    """:func:`~emotive.eval.table1.table1` on each set of clips, and on all pooled.

    Every style is a label (:data:`~emotive.data.emotion.ALL_LABELS`): the four emotions alone
    leave two dataset-1 test clips long enough for the paper's 6-second windows.

    Returns:
        Set name -> result, then :data:`BOTH_SETS` -> the windows of every set pooled
        (:func:`~emotive.eval.table1.merge_results`) when there are several.
    """
    runs = {name: table1(predictors, clips, fps=fps, labels=ALL_LABELS)
            for name, clips in sets.items()}
    if len(runs) > 1:
        runs[BOTH_SETS] = merge_results(list(runs.values()))
    return runs


def _table1_markdown(runs: dict[str, Table1Result]) -> str:
    """One row per predictor, one column per set: pose error ± std, rotation error."""
    first = next(iter(runs.values()))
    header = ["predictor", *(f"{name} ({r.windows} windows)" for name, r in runs.items())]
    lines = ["| " + " | ".join(header) + " |", "| --- |" + " --- |" * len(runs)]
    for s in first.scores:
        cells = [f"{o.pose:.3f} ± {o.pose_std:.3f}, {o.rotation:.1f}°"
                 for o in (r[s.name].overall for r in runs.values())]
        lines.append(f"| {s.name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _frame_ranges(frames: np.ndarray) -> str:
    """Sorted frame numbers as runs, e.g. ``3-7, 13, 15-17``."""
    runs: list[list[int]] = []
    for f in frames.tolist():
        if runs and f == runs[-1][-1] + 1:
            runs[-1].append(f)
        else:
            runs.append([f])
    return ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else f"{r[0]}" for r in runs)


def _horizon_verdict(run: Table1Result, name: str) -> str:
    """At which of every predicted frame ``name`` beats zero velocity, in words."""
    zero = ZeroVelocity().name
    if name == zero or zero not in {s.name for s in run.scores}:
        return ""
    every = by_horizon(run, range(1, run.predicted_frames + 1))
    wins = every.beats(name, zero)
    if not len(wins):
        return f"{name} beats zero velocity at no horizon (of frames 1-{run.predicted_frames})."
    return (f"{name} beats zero velocity at {len(wins)} of the {run.predicted_frames} horizons "
            f"(frames ahead {_frame_ranges(wins)}).")


def table1_suite(predictor: Predictor, rates: Sequence[float] = TABLE1_RATES,
                 horizon_fps: float | None = HORIZON_FPS) -> dict:
    """The ``table1`` suite: ``predictor`` beside its baselines, per data set and pooled.

    Args:
        predictor: the model judged (named in the tables by its ``name``).
        rates: frame rates of the protocol (1.8 s primer, 4.2 s predicted at each).
        horizon_fps: the rate, one of ``rates``, of the errors by horizon; ``None``: none.

    Returns:
        JSON-ready: ``markdown`` (the tables), ``results`` (rate -> set -> the
        :meth:`~emotive.eval.table1.Table1Result.to_dict` of its run), ``horizon`` (set -> the
        :meth:`~emotive.eval.horizon.HorizonErrors.to_dict` at ``horizon_fps``), ``reference``
        (what was evaluated) and ``unavailable`` (set -> why it is missing).

    Raises:
        DataError: neither data set is installed.
        ValueError: ``horizon_fps`` is not one of ``rates``.
    """
    if horizon_fps is not None and horizon_fps not in rates:
        raise ValueError(f"horizon_fps={horizon_fps} is not one of the rates {list(rates)}")
    sets, missing = table1_test_sets()
    predictors = [predictor, *table1_baselines(predictor)]
    by_rate = {f"{fps:g} fps": table1_runs(predictors, sets, fps) for fps in rates}
    parts = ["Pose error relative to the bounding-box diagonal (mean ± standard deviation over "
             "windows) and geodesic rotation error, on the locomotion test clips of each data "
             "set, all styles; 1.8 s primer, 4.2 s predicted, a window every second."]
    parts += [f"At {key}:\n\n{_table1_markdown(runs)}" for key, runs in by_rate.items()]
    horizon = {}
    if horizon_fps is not None:
        for name, run in by_rate[f"{horizon_fps:g} fps"].items():
            errors = by_horizon(run)
            horizon[name] = errors.to_dict()
            parts.append(f"Pose error by horizon, {name}, {horizon_fps:g} fps ({run.windows} "
                         f"windows):\n\n{errors.to_markdown()}\n\n"
                         f"{_horizon_verdict(run, predictor.name)}".rstrip())
    parts += [f"{name} is not installed: {why}" for name, why in missing.items()]
    return {
        "markdown": "\n\n".join(parts),
        "results": {key: {name: r.to_dict() for name, r in runs.items()}
                    for key, runs in by_rate.items()},
        "horizon": horizon,
        "reference": "locomotion test clips, all styles: " + ", ".join(
            f"{name} {TABLE1_SETS[name]} ({len(clips)} clips)" for name, clips in sets.items())
        + "; 1.8 s primer, 4.2 s predicted, a window every second",
        "unavailable": missing,
    }
