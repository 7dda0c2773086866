"""Statistics of perceptual studies: thin, typed wrappers over SciPy, statsmodels and pingouin.

Each function validates its input, calls a maintained implementation, and returns a small frozen
dataclass. How the papers in ``shared/papers`` use each test:

* :func:`anderson_darling_ksamp` -- Randhavane et al. (emotive gaits), Table 3: per gait, the
  2-sample test of intended against perceived emotion probabilities, and a k-sample test across
  users (k = number of users). Their negative statistics and "> 0.25" p-values are consistent
  with SciPy's normalized statistic and its p-value capped at 0.25.
* :func:`~emotive.eval.anova.mixed_anova` -- Carreno-Medrano et al. (end-effector
  trajectories), Tables 1-2: two-way mixed ANOVA with intended emotion as the within-subject
  factor and representation (or generation source) as the between-subject factor,
  Greenhouse-Geisser correction "if necessary", and eta-squared effect sizes.
* :func:`~emotive.eval.agreement.rater_outliers` -- the same paper, section 7.1.2: raters whose
  agreement coefficient lies outside Tukey's fences of their group are dropped before the ANOVA.
* :func:`mann_whitney_u` -- Alemi et al. (FCRBM): recorded against generated movements, for
  valence and arousal ratings separately.
* :func:`~emotive.eval.agreement.cronbach_alpha` -- Alemi et al.: inter-rater reliability with
  raters as the items.
* :func:`~emotive.eval.agreement.fleiss_kappa` -- agreement of many raters on categorical
  (forced-choice) answers.

This module holds the sample comparisons (Anderson-Darling, Mann-Whitney U), the errors and the
input checks shared with :mod:`emotive.eval.anova` and :mod:`emotive.eval.agreement`. SciPy,
statsmodels, pingouin and pandas are imported inside the functions; pingouin, statsmodels and
pandas come with ``pip install 'emotive[eval]'``.
"""

from __future__ import annotations

import importlib
import inspect
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from emotive.errors import EmotiveError

__all__ = [
    "AndersonDarlingResult",
    "MannWhitneyResult",
    "MissingDependencyError",
    "StatsInputError",
    "anderson_darling_ksamp",
    "as_finite_1d",
    "as_finite_2d",
    "mann_whitney_u",
    "require",
]


_INSTALL_HINT = "pip install 'emotive[eval]'"


class StatsInputError(EmotiveError, ValueError):
    """Study data a statistic cannot be computed on; the message names the input and the fix."""


class MissingDependencyError(EmotiveError, ImportError):
    """An optional statistics library (pingouin, statsmodels, pandas) is not installed."""


def require(module: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming the install command."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".", 1)[0]
        raise MissingDependencyError(
            f"emotive.eval.stats needs the optional package {top!r}, which is not installed; "
            f"install the evaluation extras with: {_INSTALL_HINT}"
        ) from exc


def as_finite_1d(values: ArrayLike, name: str, min_size: int) -> np.ndarray:
    """``values`` as a finite float vector of at least ``min_size`` elements."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise StatsInputError(f"{name} must hold numbers; convert it to floats first") from exc
    if arr.ndim != 1:
        raise StatsInputError(f"{name} must be 1-D, got shape {arr.shape}; flatten or select it")
    if arr.size < min_size:
        raise StatsInputError(
            f"{name} has {arr.size} value(s) but needs at least {min_size}; collect more ratings"
        )
    if not np.all(np.isfinite(arr)):
        raise StatsInputError(f"{name} contains NaN or inf; drop or impute those values first")
    return arr


def as_finite_2d(
    values: ArrayLike, name: str, shape_doc: str, min_rows: int, min_cols: int
) -> np.ndarray:
    """``values`` as a finite float matrix with at least ``min_rows`` x ``min_cols`` entries."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise StatsInputError(f"{name} must hold numbers; convert it to floats first") from exc
    if arr.ndim != 2:
        raise StatsInputError(f"{name} must be 2-D {shape_doc}, got shape {arr.shape}")
    if arr.shape[0] < min_rows or arr.shape[1] < min_cols:
        raise StatsInputError(
            f"{name} must be {shape_doc} with at least {min_rows} rows and {min_cols} columns, "
            f"got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise StatsInputError(
            f"{name} contains NaN or inf; drop the incomplete rows or columns first"
        )
    return arr


# --------------------------------------------------------------------------------------------
# Anderson-Darling k-sample test


@dataclass(frozen=True)
class AndersonDarlingResult:
    """Result of :func:`anderson_darling_ksamp`.

    Attributes:
        statistic: normalized k-sample statistic ``(A2 - (k - 1)) / sigma`` of Scholz and
            Stephens (1987); negative values are normal under the null hypothesis.
        p_value: p-value; interpolated from the tables of Scholz and Stephens unless
            ``n_resamples`` was given, in which case it is a permutation p-value.
        p_value_bounded: True when the interpolated p-value lies at the table's bound, so the
            true value is >= 0.25 (reported as ``p_value == 0.25``) or <= 0.001.
        variant: ``"midrank"``, ``"right"`` or ``"continuous"``.
        sizes: number of observations in each sample.
    """

    statistic: float
    p_value: float
    p_value_bounded: bool
    variant: str
    sizes: tuple[int, ...]


def anderson_darling_ksamp(
    samples: Sequence[ArrayLike],
    *,
    variant: Literal["midrank", "right", "continuous"] = "midrank",
    n_resamples: int | None = None,
    seed: int | None = None,
) -> AndersonDarlingResult:
    """k-sample Anderson-Darling test that all samples come from one distribution.

    Wraps :func:`scipy.stats.anderson_ksamp` (Scholz and Stephens, 1987). For the emotive-gaits
    evaluation, ``samples`` is ``[intended, perceived]`` with the l1-normalized emotion vectors
    of one gait (2-sample test), or one sample per user (k-sample test).

    Args:
        samples: k >= 2 one-dimensional samples, sample ``i`` of shape ``(n_i,)``, n_i >= 1,
            finite values.
        variant: ``"midrank"`` (default; valid with ties, e.g. Likert ratings or probability
            vectors with zeros), ``"right"`` (right-continuous empirical distribution, the
            discrete version) or ``"continuous"`` (no ties expected).
        n_resamples: when given, the p-value comes from this many random permutations instead of
            the interpolated table, which is bounded to [0.001, 0.25].
        seed: seed of the permutations; only used with ``n_resamples``.

    Returns:
        The statistic, p-value and whether the p-value hit the table's bound.

    Raises:
        StatsInputError: fewer than two samples, an empty, non-1-D or non-finite sample, all
            observations identical, an unknown ``variant``, or ``n_resamples < 1``.
        MissingDependencyError: SciPy is older than 1.17.
    """
    if isinstance(samples, np.ndarray) and samples.ndim == 1:
        raise StatsInputError(
            "samples must be a sequence of k >= 2 samples, got a single 1-D array; "
            "pass [sample_1, sample_2, ...]"
        )
    arrays = [as_finite_1d(s, f"samples[{i}]", 1) for i, s in enumerate(samples)]
    if len(arrays) < 2:
        raise StatsInputError(
            f"samples holds {len(arrays)} sample(s); the test compares k >= 2 samples"
        )
    pooled = np.concatenate(arrays)
    if np.all(pooled == pooled[0]):
        raise StatsInputError(
            "all observations in samples are identical; the test needs at least two distinct values"
        )
    if variant not in ("midrank", "right", "continuous"):
        raise StatsInputError(
            f"variant must be 'midrank', 'right' or 'continuous', got {variant!r}"
        )
    if n_resamples is not None and n_resamples < 1:
        raise StatsInputError(f"n_resamples must be >= 1 or None, got {n_resamples}")
    stats = require("scipy.stats")
    if "variant" not in inspect.signature(stats.anderson_ksamp).parameters:
        raise MissingDependencyError(
            "anderson_darling_ksamp needs SciPy >= 1.17 (the `variant` argument of "
            f"scipy.stats.anderson_ksamp); upgrade with: {_INSTALL_HINT}"
        )
    method = None
    if n_resamples is not None:
        method = stats.PermutationMethod(n_resamples=n_resamples, rng=np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"p-value (capped|floored)", category=UserWarning)
        try:
            res = stats.anderson_ksamp(arrays, variant=variant, method=method)
        except ValueError as exc:
            # SciPy's table interpolation fails on some degenerate inputs (e.g. every sample
            # holding one value, two distinct values in all): no p-value exists for them.
            raise StatsInputError(
                f"the Anderson-Darling test has no p-value for these samples ({exc}); they "
                "are too degenerate (e.g. each sample one repeated value)"
            ) from None
    p_value = float(res.pvalue)
    bounded = method is None and (p_value >= 0.25 or p_value <= 0.001)
    return AndersonDarlingResult(
        statistic=float(res.statistic),
        p_value=p_value,
        p_value_bounded=bounded,
        variant=variant,
        sizes=tuple(a.size for a in arrays),
    )


# --------------------------------------------------------------------------------------------
# Mann-Whitney U


@dataclass(frozen=True)
class MannWhitneyResult:
    """Result of :func:`mann_whitney_u`.

    Attributes:
        statistic: U of ``x``: the number of pairs ``(x_i, y_j)`` with ``x_i > y_j``, ties
            counting 1/2 (SciPy's convention).
        u_y: U of ``y``, ``n_x * n_y - statistic``. Some reports (e.g. SPSS) give
            ``min(statistic, u_y)``.
        p_value: p-value for ``alternative``.
        n_x: size of ``x``.
        n_y: size of ``y``.
        rank_biserial: ``2 * statistic / (n_x * n_y) - 1`` in [-1, 1], i.e.
            P(X > Y) - P(X < Y); positive when ``x`` tends to be larger.
        alternative: ``"two-sided"``, ``"less"`` or ``"greater"``.
    """

    statistic: float
    u_y: float
    p_value: float
    n_x: int
    n_y: int
    rank_biserial: float
    alternative: str


def mann_whitney_u(
    x: ArrayLike,
    y: ArrayLike,
    *,
    alternative: Literal["two-sided", "less", "greater"] = "two-sided",
    method: Literal["auto", "exact", "asymptotic"] = "auto",
    use_continuity: bool = True,
) -> MannWhitneyResult:
    """Mann-Whitney U test of two independent samples.

    Wraps :func:`scipy.stats.mannwhitneyu`, as used by Alemi et al. to compare ratings of recorded
    (``x``) and generated (``y``) movements (they report U, p, N1 = 150, N2 = 180).

    Args:
        x: first sample, shape ``(n_x,)``, n_x >= 1, finite.
        y: second sample, shape ``(n_y,)``, n_y >= 1, finite.
        alternative: ``"less"`` tests whether ``x`` is stochastically smaller than ``y``,
            ``"greater"`` whether it is larger.
        method: ``"exact"`` (no ties), ``"asymptotic"`` (normal approximation with tie
            correction) or ``"auto"`` (SciPy's choice: exact for small samples without ties).
        use_continuity: continuity correction of the asymptotic p-value.

    Returns:
        U of both samples, the p-value and the rank-biserial correlation.

    Raises:
        StatsInputError: empty, non-1-D or non-finite samples, or all values identical.
    """
    if alternative not in ("two-sided", "less", "greater"):
        raise StatsInputError(
            f"alternative must be 'two-sided', 'less' or 'greater', got {alternative!r}"
        )
    if method not in ("auto", "exact", "asymptotic"):
        raise StatsInputError(f"method must be 'auto', 'exact' or 'asymptotic', got {method!r}")
    xa = as_finite_1d(x, "x", 1)
    ya = as_finite_1d(y, "y", 1)
    pooled = np.concatenate([xa, ya])
    if np.all(pooled == pooled[0]):
        raise StatsInputError(
            "all values in x and y are identical; the test is undefined without variation"
        )
    stats = require("scipy.stats")
    res = stats.mannwhitneyu(
        xa, ya, alternative=alternative, method=method, use_continuity=use_continuity
    )
    u_x = float(res.statistic)
    n_pairs = xa.size * ya.size
    return MannWhitneyResult(
        statistic=u_x,
        u_y=float(n_pairs - u_x),
        p_value=float(res.pvalue),
        n_x=int(xa.size),
        n_y=int(ya.size),
        rank_biserial=float(2.0 * u_x / n_pairs - 1.0),
        alternative=alternative,
    )
