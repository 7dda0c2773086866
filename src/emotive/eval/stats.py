"""Statistics of perceptual studies: thin, typed wrappers over SciPy, statsmodels and pingouin.

Each function validates its input, calls a maintained implementation, and returns a small frozen
dataclass. How the papers in ``shared/papers`` use each test:

* :func:`anderson_darling_ksamp` -- Randhavane et al. (emotive gaits), Table 3: per gait, the
  2-sample test of intended against perceived emotion probabilities, and a k-sample test across
  users (k = number of users). Their negative statistics and "> 0.25" p-values are consistent
  with SciPy's normalized statistic and its p-value capped at 0.25.
* :func:`mixed_anova` -- Carreno-Medrano et al. (end-effector trajectories), Tables 1-2: two-way
  mixed ANOVA with intended emotion as the within-subject factor and representation (or generation
  source) as the between-subject factor, Greenhouse-Geisser correction "if necessary", and
  eta-squared effect sizes.
* :func:`rater_outliers` -- the same paper, section 7.1.2: raters whose agreement coefficient lies
  outside Tukey's fences of their group are dropped before the ANOVA.
* :func:`mann_whitney_u` -- Alemi et al. (FCRBM): recorded against generated movements, for
  valence and arousal ratings separately.
* :func:`cronbach_alpha` -- Alemi et al.: inter-rater reliability with raters as the items.
* :func:`fleiss_kappa` -- agreement of many raters on categorical (forced-choice) answers.

SciPy, statsmodels, pingouin and pandas are imported inside the functions; pingouin, statsmodels
and pandas come with ``pip install 'emotive[eval]'``.
"""

from __future__ import annotations

import importlib
import inspect
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from emotive.errors import EmotiveError

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "AndersonDarlingResult",
    "AnovaEffect",
    "CronbachAlphaResult",
    "FleissKappaResult",
    "MannWhitneyResult",
    "MissingDependencyError",
    "MixedAnovaResult",
    "RaterOutlierResult",
    "StatsInputError",
    "anderson_darling_ksamp",
    "cronbach_alpha",
    "fleiss_kappa",
    "mann_whitney_u",
    "mixed_anova",
    "rater_outliers",
]

_INSTALL_HINT = "pip install 'emotive[eval]'"


class StatsInputError(EmotiveError, ValueError):
    """Study data a statistic cannot be computed on; the message names the input and the fix."""


class MissingDependencyError(EmotiveError, ImportError):
    """An optional statistics library (pingouin, statsmodels, pandas) is not installed."""


def _require(module: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming the install command."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.split(".", 1)[0]
        raise MissingDependencyError(
            f"emotive.eval.stats needs the optional package {top!r}, which is not installed; "
            f"install the evaluation extras with: {_INSTALL_HINT}"
        ) from exc


def _as_finite_1d(values: ArrayLike, name: str, min_size: int) -> np.ndarray:
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


def _as_finite_2d(
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
    arrays = [_as_finite_1d(s, f"samples[{i}]", 1) for i, s in enumerate(samples)]
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
    stats = _require("scipy.stats")
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
        res = stats.anderson_ksamp(arrays, variant=variant, method=method)
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
# Mixed ANOVA


@dataclass(frozen=True)
class AnovaEffect:
    """One row of a mixed ANOVA table.

    Attributes:
        source: name of the factor, or ``"interaction"``.
        ss: sum of squares of the effect.
        df1: numerator degrees of freedom (uncorrected).
        df2: denominator degrees of freedom (uncorrected).
        f: F statistic.
        p_unc: p-value without sphericity correction.
        p_gg: Greenhouse-Geisser corrected p-value, ``F(eps * df1, eps * df2)``; equal to
            ``p_unc`` for the between-subject factor and when the within factor has 2 levels.
        eps: Greenhouse-Geisser epsilon used for ``p_gg`` (1.0 for the between factor).
        partial_eta_sq: ``ss / (ss + ss_error)`` with the effect's own error term; equals
            ``f * df1 / (f * df1 + df2)``.
        generalized_eta_sq: ``ss / (ss + ss_error_between + ss_error_within)`` (Olejnik and
            Algina, 2003; Bakeman, 2005), comparable across designs.
    """

    source: str
    ss: float
    df1: float
    df2: float
    f: float
    p_unc: float
    p_gg: float
    eps: float
    partial_eta_sq: float
    generalized_eta_sq: float


@dataclass(frozen=True)
class MixedAnovaResult:
    """Result of :func:`mixed_anova`.

    Attributes:
        between: main effect of the between-subject factor.
        within: main effect of the within-subject factor.
        interaction: between x within interaction.
        epsilon: Greenhouse-Geisser epsilon of the pooled within-group covariance matrix.
        sphericity_w: Mauchly's W; NaN when the within factor has 2 levels (sphericity holds) or
            when there are too few subjects to estimate it (``n_subjects - n_groups`` smaller
            than ``n_levels - 1``).
        sphericity_p: p-value of Mauchly's test (NaN where ``sphericity_w`` is NaN).
        n_subjects: number of subjects.
        n_groups: number of levels of the between factor.
        n_levels: number of levels of the within factor.
    """

    between: AnovaEffect
    within: AnovaEffect
    interaction: AnovaEffect
    epsilon: float
    sphericity_w: float
    sphericity_p: float
    n_subjects: int
    n_groups: int
    n_levels: int

    @property
    def sphericity_violated(self) -> bool:
        """Whether Mauchly's test rejects sphericity at the 5% level (then report ``p_gg``).

        False when the test is not available (``sphericity_p`` is NaN).
        """
        return bool(self.sphericity_p < 0.05)


def _check_mixed_design(
    data: pd.DataFrame, dv: str, within: str, between: str, subject: str
) -> None:
    """Raise :class:`StatsInputError` unless ``data`` is a complete, balanced mixed design."""
    pd = _require("pandas")
    if not isinstance(data, pd.DataFrame):
        raise StatsInputError(
            f"data must be a long-format pandas DataFrame, got {type(data).__name__}"
        )
    if not all(isinstance(c, str) for c in (dv, within, between, subject)):
        raise StatsInputError(
            "dv, within, between and subject must each name one column; this wrapper supports "
            "one within and one between factor (the design of Carreno-Medrano et al.)"
        )
    missing = [c for c in (dv, within, between, subject) if c not in data.columns]
    if missing:
        raise StatsInputError(
            f"data has no column(s) {missing}; available columns: {list(data.columns)}"
        )
    if len({dv, within, between, subject}) != 4:
        raise StatsInputError("dv, within, between and subject must name four distinct columns")
    if not pd.api.types.is_numeric_dtype(data[dv]):
        raise StatsInputError(f"column {dv!r} (dv) must be numeric, got dtype {data[dv].dtype}")
    if not np.all(np.isfinite(data[dv].to_numpy(dtype=float))):
        raise StatsInputError(
            f"column {dv!r} contains NaN or inf; drop the subjects with missing ratings first"
        )
    keys = data[[subject, within, between]]
    if keys.isna().any().any():
        raise StatsInputError(
            f"columns {subject!r}, {within!r} and {between!r} must not contain missing values"
        )
    groups_per_subject = data.groupby(subject, observed=True)[between].nunique()
    if (groups_per_subject > 1).any():
        bad = list(groups_per_subject.index[groups_per_subject > 1][:5])
        raise StatsInputError(
            f"subjects {bad} appear in more than one level of {between!r}; each subject must "
            "belong to exactly one between-subject group"
        )
    cells = data.groupby([subject, within], observed=True).size()
    if (cells > 1).any():
        raise StatsInputError(
            f"some subjects have several rows for one level of {within!r}; average the repeated "
            f"ratings per subject and level first (e.g. data.groupby([{subject!r}, {within!r}, "
            f"{between!r}], as_index=False)[{dv!r}].mean())"
        )
    n_levels = data[within].nunique()
    n_subjects = data[subject].nunique()
    if len(data) != n_levels * n_subjects:
        raise StatsInputError(
            f"the design is incomplete: {n_subjects} subjects x {n_levels} levels of {within!r} "
            f"need {n_levels * n_subjects} rows, got {len(data)}; drop subjects with missing "
            "levels"
        )
    if n_levels < 2:
        raise StatsInputError(f"the within factor {within!r} needs at least 2 levels")
    per_group = data.groupby(between, observed=True)[subject].nunique()
    if len(per_group) < 2:
        raise StatsInputError(f"the between factor {between!r} needs at least 2 levels")
    if (per_group < 2).any():
        raise StatsInputError(
            f"each level of {between!r} needs at least 2 subjects, got {per_group.to_dict()}"
        )


def mixed_anova(
    data: pd.DataFrame, dv: str, within: str, between: str, subject: str
) -> MixedAnovaResult:
    """Two-way mixed (split-plot) ANOVA with Greenhouse-Geisser correction and effect sizes.

    Wraps :func:`pingouin.mixed_anova`, the design of Carreno-Medrano et al. (Tables 1-2):
    one within-subject factor (intended emotion) and one between-subject factor (representation
    or generation source), one value per subject and level (their per-participant average
    accuracy, valence or arousal). pingouin supports one within and one between factor, which is
    what the paper needs; for two within factors and no between factor use
    :func:`pingouin.rm_anova` directly. Epsilon and Mauchly's test use the pooled within-group
    covariance matrix (as SPSS, afex and car do); the same epsilon corrects the within effect
    and the interaction.

    The paper reports corrected F tests "if necessary": report ``p_gg`` when
    :attr:`MixedAnovaResult.sphericity_violated`, or always, to be conservative. Its η² values for
    the between factor equal ``partial_eta_sq`` (e.g. F(1, 188) = 54.308 -> 0.224).

    Args:
        data: long-format table, one row per subject and level of ``within``; balanced within
            (every subject has every level) and complete. Groups may differ in size (pingouin
            then computes type II sums of squares).
        dv: column of the dependent variable (numeric, finite).
        within: column of the within-subject factor (>= 2 levels).
        between: column of the between-subject factor (>= 2 levels, >= 2 subjects each).
        subject: column of subject identifiers; a subject belongs to one group only.

    Returns:
        The three effects with uncorrected and corrected p-values, epsilon and Mauchly's test.

    Raises:
        StatsInputError: missing columns, NaN, repeated or missing cells, a subject in two
            groups, or a factor with fewer than 2 levels.
        MissingDependencyError: pingouin or pandas is not installed.
    """
    _check_mixed_design(data, dv, within, between, subject)
    pg = _require("pingouin")
    tables = {}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"The inplace keyword", category=Warning)
        for effsize in ("np2", "ng2"):
            tables[effsize] = pg.mixed_anova(
                data=data,
                dv=dv,
                within=within,
                between=between,
                subject=subject,
                correction=True,
                effsize=effsize,
            )
    aov, aov_g = tables["np2"], tables["ng2"]
    n_levels = int(data[within].nunique())
    n_subjects = int(data[subject].nunique())
    n_groups = int(data[between].nunique())
    eps = float(aov["eps"].iloc[1]) if n_levels > 2 else 1.0
    if n_levels > 2 and n_subjects - n_groups >= n_levels - 1:
        w_spher, p_spher = float(aov["W_spher"].iloc[1]), float(aov["p_spher"].iloc[1])
    else:
        w_spher, p_spher = float("nan"), float("nan")

    def effect(row: int, source: str) -> AnovaEffect:
        rec: dict[str, Any] = aov.iloc[row].to_dict()
        corrected = row > 0 and n_levels > 2
        return AnovaEffect(
            source=source,
            ss=float(rec["SS"]),
            df1=float(rec["DF1"]),
            df2=float(rec["DF2"]),
            f=float(rec["F"]),
            p_unc=float(rec["p_unc"]),
            p_gg=float(rec["p_GG_corr"]) if corrected else float(rec["p_unc"]),
            eps=eps if row > 0 else 1.0,
            partial_eta_sq=float(rec["np2"]),
            generalized_eta_sq=float(aov_g["ng2"].iloc[row]),
        )

    return MixedAnovaResult(
        between=effect(0, between),
        within=effect(1, within),
        interaction=effect(2, "interaction"),
        epsilon=eps,
        sphericity_w=w_spher,
        sphericity_p=p_spher,
        n_subjects=n_subjects,
        n_groups=n_groups,
        n_levels=n_levels,
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
    xa = _as_finite_1d(x, "x", 1)
    ya = _as_finite_1d(y, "y", 1)
    pooled = np.concatenate([xa, ya])
    if np.all(pooled == pooled[0]):
        raise StatsInputError(
            "all values in x and y are identical; the test is undefined without variation"
        )
    stats = _require("scipy.stats")
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


# --------------------------------------------------------------------------------------------
# Cronbach's alpha


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
    arr = _as_finite_2d(ratings, "ratings", "(n_cases, n_items)", 2, 2)
    if not 0.0 < ci < 1.0:
        raise StatsInputError(f"ci must be a confidence level in (0, 1), got {ci}")
    if np.var(arr.sum(axis=1)) == 0.0:
        raise StatsInputError(
            "the total score (row sums of ratings) has zero variance, so alpha is undefined; "
            "check that the rows are different cases"
        )
    pd = _require("pandas")
    pg = _require("pingouin")
    alpha, interval = pg.cronbach_alpha(data=pd.DataFrame(arr), ci=ci)
    return CronbachAlphaResult(
        alpha=float(alpha),
        ci_low=float(interval[0]),
        ci_high=float(interval[1]),
        n_cases=int(arr.shape[0]),
        n_items=int(arr.shape[1]),
    )


# --------------------------------------------------------------------------------------------
# Fleiss' kappa


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
    inter_rater = _require("statsmodels.stats.inter_rater")
    if counts:
        table = _as_finite_2d(data, "data", "(n_subjects, n_categories) counts", 2, 2)
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


# --------------------------------------------------------------------------------------------
# Rater outliers


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
    arr = _as_finite_2d(ratings, "ratings", "(n_stimuli, n_raters)", 3, 3)
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
    stats = _require("scipy.stats")
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
