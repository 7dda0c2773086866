"""Agreement of raters in perceptual studies, through pingouin and statsmodels.

* :func:`cronbach_alpha` -- Alemi et al.: inter-rater reliability with raters as the items.
* :func:`fleiss_kappa` -- agreement of many raters on categorical (forced-choice) answers.
* :func:`rater_outliers` -- Carreno-Medrano et al., section 7.1.2: raters whose agreement
  coefficient lies outside Tukey's fences of their group are dropped before the ANOVA.

Errors and optional dependencies as in :mod:`emotive.eval.stats`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from emotive.eval.stats import StatsInputError, as_finite_2d, require

__all__ = [
    "CronbachAlphaResult",
    "FleissKappaResult",
    "RaterOutlierResult",
    "cronbach_alpha",
    "fleiss_kappa",
    "rater_outliers",
]


@dataclass(frozen=True)
class CronbachAlphaResult:
    """Result of :func:`cronbach_alpha`.

    Attributes:
        alpha: ``k / (k - 1) * (1 - sum(item variances) / variance(total score))``; at most 1,
            negative when items covary negatively.
        ci_low: lower bound of the confidence interval (Feldt, 1965), rounded to 3 decimals by
            pingouin.
        ci_high: upper bound, rounded likewise.
        n_cases: number of rated cases (rows).
        n_items: number of items (columns).
    """

    alpha: float
    ci_low: float
    ci_high: float
    n_cases: int
    n_items: int


def cronbach_alpha(ratings: ArrayLike, *, ci: float = 0.95) -> CronbachAlphaResult:
    """Cronbach's alpha, the internal consistency of items (or of raters).

    Wraps :func:`pingouin.cronbach_alpha`. For inter-rater reliability as in Alemi et al.
    (alpha = 0.89 for valence, 0.98 for arousal), the raters are the items: rows are the rated
    clips and columns the raters.

    Args:
        ratings: shape ``(n_cases, n_items)``, n_cases >= 2, n_items >= 2, finite; e.g.
            ``(n_stimuli, n_raters)``.
        ci: confidence level of the interval, in (0, 1).

    Returns:
        Alpha and its confidence interval.

    Raises:
        StatsInputError: wrong shape, NaN, ``ci`` outside (0, 1), or a total score with zero
            variance.
        MissingDependencyError: pingouin or pandas is not installed.
    """
    arr = as_finite_2d(ratings, "ratings", "(n_cases, n_items)", 2, 2)
    if not 0.0 < ci < 1.0:
        raise StatsInputError(f"ci must be a confidence level in (0, 1), got {ci}")
    if np.var(arr.sum(axis=1)) == 0.0:
        raise StatsInputError(
            "the total score (row sums of ratings) has zero variance, so alpha is undefined; "
            "check that the rows are different cases"
        )
    pd = require("pandas")
    pg = require("pingouin")
    alpha, interval = pg.cronbach_alpha(data=pd.DataFrame(arr), ci=ci)
    return CronbachAlphaResult(
        alpha=float(alpha),
        ci_low=float(interval[0]),
        ci_high=float(interval[1]),
        n_cases=int(arr.shape[0]),
        n_items=int(arr.shape[1]),
    )


@dataclass(frozen=True)
class FleissKappaResult:
    """Result of :func:`fleiss_kappa`.

    Attributes:
        kappa: ``(P_bar - P_e) / (1 - P_e)``: observed agreement beyond chance, 1 for perfect
            agreement, <= 0 for agreement at or below chance.
        n_subjects: number of rated subjects (rows).
        n_raters: number of ratings per subject.
        n_categories: number of categories (columns of the count table).
        method: ``"fleiss"`` (chance from the observed category margins) or ``"randolph"``
            (uniform chance, free-marginal kappa).
    """

    kappa: float
    n_subjects: int
    n_raters: int
    n_categories: int
    method: str


def fleiss_kappa(
    data: ArrayLike,
    *,
    counts: bool = False,
    method: Literal["fleiss", "randolph"] = "fleiss",
) -> FleissKappaResult:
    """Fleiss' kappa, the agreement of several raters on nominal categories.

    Wraps :func:`statsmodels.stats.inter_rater.fleiss_kappa` (and
    :func:`~statsmodels.stats.inter_rater.aggregate_raters` for raw ratings). Suited to
    forced-choice answers such as "which of the 5 emotions is conveyed?".

    Args:
        data: with ``counts=False`` (default), raw ratings of shape ``(n_subjects, n_raters)``
            holding category labels (numbers or strings); every subject is rated by every rater.
            With ``counts=True``, a count table of shape ``(n_subjects, n_categories)`` whose
            entry ``[i, j]`` is the number of raters who put subject ``i`` in category ``j``;
            every row must sum to the same number of raters.
        counts: whether ``data`` is a count table instead of raw ratings.
        method: ``"fleiss"`` or ``"randolph"``.

    Returns:
        Kappa and the size of the rating design.

    Raises:
        StatsInputError: wrong shape, missing values, fewer than 2 subjects or 2 raters,
            negative or non-integer counts, unequal numbers of raters per subject, or a single
            category (kappa undefined), or an unknown ``method``.
        MissingDependencyError: statsmodels is not installed.
    """
    if method not in ("fleiss", "randolph"):
        raise StatsInputError(f"method must be 'fleiss' or 'randolph', got {method!r}")
    inter_rater = require("statsmodels.stats.inter_rater")
    if counts:
        table = as_finite_2d(data, "data", "(n_subjects, n_categories) counts", 2, 2)
        if np.any(table < 0) or np.any(table != np.round(table)):
            raise StatsInputError("data must hold non-negative integer counts when counts=True")
        per_row = table.sum(axis=1)
        if np.any(per_row != per_row[0]):
            raise StatsInputError(
                "every row of the count table must sum to the same number of raters, got row "
                f"sums {sorted(set(per_row.tolist()))}; Fleiss' kappa needs a constant number "
                "of ratings per subject"
            )
        n_raters = int(per_row[0])
    else:
        raw = np.asarray(data)
        if raw.ndim != 2:
            raise StatsInputError(
                f"data must be 2-D (n_subjects, n_raters) ratings, got shape {raw.shape}; pass "
                "counts=True for a count table"
            )
        if raw.dtype.kind == "O" and any(v is None for v in raw.ravel()):
            raise StatsInputError("data contains None; every rater must rate every subject")
        if raw.dtype.kind in "fc" and not np.all(np.isfinite(raw)):
            raise StatsInputError("data contains NaN or inf; every rater must rate every subject")
        table = inter_rater.aggregate_raters(raw)[0]
        n_raters = int(raw.shape[1])
    if table.shape[0] < 2 or n_raters < 2:
        raise StatsInputError(
            f"Fleiss' kappa needs at least 2 subjects and 2 raters, got {table.shape[0]} subjects "
            f"and {n_raters} raters"
        )
    used = np.count_nonzero(table.sum(axis=0)) if method == "fleiss" else table.shape[1]
    if used < 2:
        raise StatsInputError(
            "all ratings fall in a single category, so chance agreement is 1 and kappa is undefined"
        )
    kappa = inter_rater.fleiss_kappa(table, method=method)
    return FleissKappaResult(
        kappa=float(kappa),
        n_subjects=int(table.shape[0]),
        n_raters=n_raters,
        n_categories=int(table.shape[1]),
        method=method,
    )


@dataclass(frozen=True)
class RaterOutlierResult:
    """Result of :func:`rater_outliers`.

    Attributes:
        agreement: shape ``(n_raters,)``, each rater's correlation with the mean of the other
            raters; NaN for a rater whose ratings are constant.
        outliers: shape ``(n_raters,)``, bool, True for flagged raters.
        lower: lower fence; raters below it are flagged.
        upper: upper fence (``inf`` unless ``two_sided``).
        rule: ``"tukey"``, ``"mad"`` or ``"threshold"``.
    """

    agreement: np.ndarray
    outliers: np.ndarray
    lower: float
    upper: float
    rule: str

    @property
    def outlier_indices(self) -> np.ndarray:
        """Column indices of the flagged raters, shape ``(n_outliers,)``."""
        return np.flatnonzero(self.outliers)


def rater_outliers(
    ratings: ArrayLike,
    *,
    correlation: Literal["spearman", "pearson"] = "spearman",
    rule: Literal["tukey", "mad", "threshold"] = "tukey",
    k: float | None = None,
    threshold: float | None = None,
    two_sided: bool = False,
) -> RaterOutlierResult:
    """Flag raters who agree far less with the others than the rest of their group.

    Agreement coefficient of rater ``j``: the ``correlation`` (Spearman by default, for ordinal
    Likert ratings) between rater ``j``'s ratings and the mean rating of the other raters over
    the same stimuli (leave-one-out). Rules:

    * ``"tukey"`` (default; Carreno-Medrano et al., eq. 3, after Feng et al.): flag agreement
      below ``Q1 - k * (Q3 - Q1)``, k = 1.5 by default, quartiles by linear interpolation
      (:func:`numpy.percentile`).
    * ``"mad"``: flag agreement below ``median - k * MAD``, MAD scaled by 1.4826 to match the
      standard deviation of normal data, k = 3 by default. With MAD = 0 every rater below the
      median is flagged.
    * ``"threshold"``: flag agreement below the fixed ``threshold`` (e.g. 0.0 for raters who do
      not correlate positively with the consensus).

    The paper's interval is two-sided; unusually high agreement is no sign of careless rating,
    so only low agreement is flagged unless ``two_sided`` (then also above ``Q3 + k * IQR`` or
    ``median + k * MAD``). Raters with constant ratings (e.g. always the same answer) have an
    undefined correlation, reported as NaN, and are always flagged. Run the function once per
    group of raters who saw the same stimuli.

    Args:
        ratings: shape ``(n_stimuli, n_raters)``, n_stimuli >= 3, n_raters >= 3, finite.
        correlation: ``"spearman"`` or ``"pearson"``.
        rule: ``"tukey"``, ``"mad"`` or ``"threshold"``.
        k: fence multiplier for ``"tukey"`` and ``"mad"``, >= 0.
        threshold: the fixed cut-off, required for ``rule="threshold"`` and only used there.
        two_sided: also flag agreement above the upper fence (not with ``"threshold"``).

    Returns:
        The agreement of each rater, the flags and the fences.

    Raises:
        StatsInputError: wrong shape, NaN, fewer than 3 stimuli or raters, a bad ``k`` or
            ``threshold``, or constant mean ratings of the others (agreement undefined).
    """
    arr = as_finite_2d(ratings, "ratings", "(n_stimuli, n_raters)", 3, 3)
    if rule not in ("tukey", "mad", "threshold"):
        raise StatsInputError(f"rule must be 'tukey', 'mad' or 'threshold', got {rule!r}")
    if correlation not in ("spearman", "pearson"):
        raise StatsInputError(f"correlation must be 'spearman' or 'pearson', got {correlation!r}")
    if rule == "threshold":
        if threshold is None or not np.isfinite(threshold):
            raise StatsInputError("rule='threshold' needs a finite threshold, e.g. threshold=0.0")
        if two_sided:
            raise StatsInputError("two_sided applies to rule='tukey' or 'mad', not 'threshold'")
    k_value = (1.5 if rule == "tukey" else 3.0) if k is None else float(k)
    if not (np.isfinite(k_value) and k_value >= 0.0):
        raise StatsInputError(f"k must be a finite number >= 0, got {k}")
    stats = require("scipy.stats")
    corr = stats.spearmanr if correlation == "spearman" else stats.pearsonr
    n_raters = arr.shape[1]
    agreement = np.full(n_raters, np.nan)
    for j in range(n_raters):
        own = arr[:, j]
        others = np.delete(arr, j, axis=1).mean(axis=1)
        if np.all(own == own[0]):
            continue
        if np.all(others == others[0]):
            raise StatsInputError(
                f"the mean rating of the raters other than rater {j} is the same for every "
                "stimulus, so agreement with it is undefined; use stimuli that differ"
            )
        agreement[j] = float(corr(own, others).statistic)
    finite = agreement[np.isfinite(agreement)]
    upper = float("inf")
    if threshold is not None and rule == "threshold":
        lower = float(threshold)
    elif finite.size == 0:
        lower = float("nan")
    elif rule == "tukey":
        q1, q3 = np.percentile(finite, [25.0, 75.0])
        lower = float(q1 - k_value * (q3 - q1))
        if two_sided:
            upper = float(q3 + k_value * (q3 - q1))
    else:
        center = float(np.median(finite))
        spread = float(stats.median_abs_deviation(finite, scale="normal"))
        lower = center - k_value * spread
        if two_sided:
            upper = center + k_value * spread
    outliers = ~np.isfinite(agreement) | (agreement < lower) | (agreement > upper)
    return RaterOutlierResult(
        agreement=agreement, outliers=outliers, lower=lower, upper=upper, rule=rule
    )
