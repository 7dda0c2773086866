"""Two-way mixed ANOVA of perceptual studies, through pingouin.

Carreno-Medrano et al. (end-effector trajectories), Tables 1-2: intended emotion as the
within-subject factor and representation (or generation source) as the between-subject factor,
Greenhouse-Geisser correction "if necessary", and eta-squared effect sizes. Errors and optional
dependencies as in :mod:`emotive.eval.stats`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.eval.stats import StatsInputError, require

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "AnovaEffect",
    "MixedAnovaResult",
    "mixed_anova",
]


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
    pd = require("pandas")
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
    pg = require("pingouin")
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
