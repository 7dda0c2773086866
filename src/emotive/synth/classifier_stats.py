"""Held-out metrics of one classifier and paired comparisons of two training arms.

Used by :mod:`emotive.synth.classifier_study` (does the main paper's augmented data set,
Bhattacharya et al. 2020, section 5.2, help emotion recognition?). Every number is measured
on real held-out clips in the classifier's evaluation windows (4 s, 1 s hop; a shorter clip
is one window, :func:`emotive.eval.classifier_training.measure`).

Per data set (:func:`held_out`): window accuracy, balanced accuracy (mean recall over the
labels present), macro-F1 over the labels present in that data set's truth (per label
``2 TP / (2 TP + FP + FN)`` over windows; dataset 2 holds only neutral, so there it is the
neutral F1), the expected calibration error (10 bins, calibrated probabilities) and the
share of unsure windows over every test window of the data set (labelled or not), plus each
labelled window's truth and prediction for the paired tests.

Paired tests of arm B against arm A (:func:`compare`), both trained with the same seeds:

* per metric over the seeds: the paired t-test (:func:`scipy.stats.ttest_rel`) and the
  Wilcoxon signed-rank test (:func:`scipy.stats.wilcoxon`); with 3 seeds the smallest
  two-sided Wilcoxon p is 0.25, so it can never reject: it is reported, not relied on;
* on the windows, pooled over seeds (the same window judged by both arms of a seed):
  McNemar's exact test (:func:`statsmodels.stats.contingency_tables.mcnemar`) on the
  discordant pairs;
* a paired bootstrap by clip (:func:`scipy.stats.bootstrap`, percentile interval): clips are
  resampled, each carrying its windows of every seed, and the statistic is the difference of
  the pooled window accuracies. Windows of one clip are not independent, so this interval is
  the honest one; McNemar treats windows as independent and is optimistic.

Warnings of the tests (a constant difference, ties) are kept in the result, not raised.

Legend: ``K`` windows, ``C`` labels, ``S`` seeds.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from emotive.eval.classifier import EmotionClassifier
from emotive.eval.classifier_training import ClipFeatures, _eval_windows, measure
from emotive.eval.stats import require

#: Metrics compared per data set, as :func:`held_out` names them.
METRICS = ("window_accuracy", "balanced_accuracy", "macro_f1", "ece", "unsure_rate")


def macro_f1(confusion: np.ndarray) -> float:
    """Mean F1 over the labels present in the truth of a ``(C, C)`` confusion (rows: truth)."""
    c = np.asarray(confusion, dtype=np.float64)
    tp = np.diag(c)
    present = c.sum(1) > 0
    if not present.any():
        return math.nan
    f1 = 2 * tp / np.maximum(c.sum(0) + c.sum(1), 1e-12)
    return float(f1[present].mean())


def held_out(model: EmotionClassifier, items: Sequence[ClipFeatures]) -> dict[str, Any]:
    """The metrics of ``model`` on held-out clips (module docstring).

    Returns:
        :data:`METRICS`, ``"windows"`` and ``"clips"`` (labelled), ``"all_windows"``, and
        ``"per_window"``: ``{"clip": [...], "truth": [...], "predicted": [...]}`` over the
        labelled windows, clip by clip.
    """
    result = measure(model, items)
    clip, truth, predicted = [], [], []
    for item in items:
        if item.label >= 0:
            p = model.outputs(_eval_windows(item, model.config))["probabilities"].argmax(-1)
            clip += [item.name] * len(p)
            truth += [item.label] * len(p)
            predicted += p.tolist()
    return {
        "window_accuracy": result["window_accuracy"],
        "balanced_accuracy": result["balanced_accuracy"],
        "macro_f1": macro_f1(np.array(result["confusion"])),
        "ece": result["ece"],
        "unsure_rate": result["unsure_rate"],
        "windows": result["windows"], "clips": result["clips"],
        "all_windows": result["all_windows"],
        "per_window": {"clip": clip, "truth": truth, "predicted": predicted},
    }


def _quiet(run: Callable[[], Any]) -> tuple[Any, list[str]]:
    """``run()`` and the text of the warnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = run()
    return value, sorted({str(w.message).splitlines()[0] for w in caught})


def _number(value: Any) -> float:
    v = float(value)
    return v if math.isfinite(v) else math.nan


def seed_tests(a: Sequence[float], b: Sequence[float]) -> dict[str, Any]:
    """Paired t-test and Wilcoxon test of per-seed values ``b`` against ``a``.

    Returns:
        ``{"difference_mean", "difference_sd", "t_test": {"statistic", "p", "notes"},
        "wilcoxon": {...}}``; ``p`` is NaN where a test is undefined (fewer than 2 seeds, or
        every difference the same), and 1 for Wilcoxon when every difference is 0.
    """
    from scipy import stats  # noqa: PLC0415 (SciPy is loaded only to compare)

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    keep = np.isfinite(a) & np.isfinite(b)
    d = b[keep] - a[keep]
    out: dict[str, Any] = {
        "seeds": int(keep.sum()),
        "difference_mean": float(d.mean()) if len(d) else math.nan,
        "difference_sd": float(d.std(ddof=1)) if len(d) > 1 else math.nan,
    }
    nan = {"statistic": math.nan, "p": math.nan}
    if len(d) < 2 or np.ptp(d) == 0:
        why = "fewer than 2 seeds" if len(d) < 2 else "every seed's difference is the same"
        out["t_test"] = {**nan, "notes": [why]}
    else:
        t, notes = _quiet(lambda: stats.ttest_rel(b[keep], a[keep]))
        out["t_test"] = {"statistic": _number(t.statistic), "p": _number(t.pvalue),
                         "notes": notes}
    if not len(d) or not d.any():
        out["wilcoxon"] = {"statistic": math.nan, "p": 1.0 if len(d) else math.nan,
                           "notes": ["every difference is 0" if len(d) else "no seeds"]}
    else:
        w, notes = _quiet(lambda: stats.wilcoxon(d))
        out["wilcoxon"] = {"statistic": _number(w.statistic), "p": _number(w.pvalue),
                           "notes": notes}
    return out


def mcnemar_windows(a: Sequence[bool], b: Sequence[bool]) -> dict[str, Any]:
    """McNemar's exact test on paired window outcomes (``True``: right) of arms A and B.

    Returns:
        ``{"windows", "both_right", "only_a_right", "only_b_right", "both_wrong", "p"}``.
    """
    mcnemar = require("statsmodels.stats.contingency_tables").mcnemar
    a, b = np.asarray(a, dtype=bool), np.asarray(b, dtype=bool)
    table = np.array([[np.sum(a & b), np.sum(a & ~b)], [np.sum(~a & b), np.sum(~a & ~b)]])
    out = {"windows": len(a), "both_right": int(table[0, 0]), "only_a_right": int(table[0, 1]),
           "only_b_right": int(table[1, 0]), "both_wrong": int(table[1, 1])}
    if table[0, 1] + table[1, 0] == 0:
        return {**out, "p": 1.0}
    return {**out, "p": _number(mcnemar(table, exact=True).pvalue)}


def clip_bootstrap(clips: Sequence[str], a: Sequence[bool], b: Sequence[bool],
                   resamples: int, seed: int = 0, level: float = 0.95) -> dict[str, Any]:
    """Paired bootstrap by clip of the window accuracy difference B - A (module docstring).

    Args:
        clips: ``(K,)`` the clip of every window (windows of every seed).
        a: ``(K,)`` whether arm A judged each window right.
        b: ``(K,)`` whether arm B did.
        resamples: bootstrap resamples.
        seed: the resampling's seed.
        level: confidence level of the interval.

    Returns:
        ``{"clips", "difference", "low", "high", "level", "notes"}``.
    """
    from scipy import stats  # noqa: PLC0415 (SciPy is loaded only to compare)

    names = sorted(set(clips))
    index = np.array([names.index(c) for c in clips], dtype=np.int64)
    diff = np.bincount(index, np.asarray(b, float) - np.asarray(a, float), len(names))
    count = np.bincount(index, minlength=len(names)).astype(np.float64)
    estimate = float(diff.sum() / count.sum()) if count.sum() else math.nan
    out = {"clips": len(names), "difference": estimate, "level": level}
    if len(names) < 2 or np.ptp(diff / np.maximum(count, 1)) == 0:
        return {**out, "low": estimate, "high": estimate,
                "notes": ["every clip's difference is the same: no spread to resample"]}

    def statistic(d: np.ndarray, n: np.ndarray) -> float:
        return float(d.sum() / n.sum())

    res, notes = _quiet(lambda: stats.bootstrap(
        (diff, count), statistic, paired=True, vectorized=False, n_resamples=resamples,
        confidence_level=level, method="percentile", rng=np.random.default_rng(seed)))
    return {**out, "low": _number(res.confidence_interval.low),
            "high": _number(res.confidence_interval.high), "notes": notes}


def compare(runs_a: Sequence[dict], runs_b: Sequence[dict], resamples: int) -> dict[str, Any]:
    """Paired comparison of arm B with arm A on one data set, seed by seed.

    Args:
        runs_a: :func:`held_out` results of arm A, seed by seed.
        runs_b: those of arm B, in the same seed order.
        resamples: bootstrap resamples.

    Returns:
        ``{metric: seed_tests(...)}`` for :data:`METRICS`, ``"mcnemar"`` and
        ``"clip_bootstrap"`` on the windows pooled over seeds.

    Raises:
        ValueError: the arms were judged on different windows.
    """
    out: dict[str, Any] = {m: seed_tests([r[m] for r in runs_a], [r[m] for r in runs_b])
                           for m in METRICS}
    clips, right_a, right_b = [], [], []
    for ra, rb in zip(runs_a, runs_b, strict=True):
        wa, wb = ra["per_window"], rb["per_window"]
        if wa["clip"] != wb["clip"] or wa["truth"] != wb["truth"]:
            raise ValueError("the two arms were measured on different held-out windows")
        clips += wa["clip"]
        right_a += [p == t for p, t in zip(wa["predicted"], wa["truth"], strict=True)]
        right_b += [p == t for p, t in zip(wb["predicted"], wb["truth"], strict=True)]
    out["mcnemar"] = mcnemar_windows(right_a, right_b)
    out["clip_bootstrap"] = clip_bootstrap(clips, right_a, right_b, resamples)
    return out
