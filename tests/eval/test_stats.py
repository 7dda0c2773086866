"""Study statistics against published values and closed forms computed here by hand."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys

import numpy as np
import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("pingouin")
pytest.importorskip("statsmodels")

from scipy import stats as sps  # noqa: E402

from emotive.eval.stats import (  # noqa: E402
    MissingDependencyError,
    StatsInputError,
    anderson_darling_ksamp,
    cronbach_alpha,
    fleiss_kappa,
    mann_whitney_u,
    mixed_anova,
    rater_outliers,
)

# ---------------------------------------------------------------------------------------------
# Anderson-Darling: Scholz and Stephens (1987), JASA 82(399), section 5 example: smoothness of
# paper measured in four laboratories (data from Lehmann, 1975). Published: A2_kN = 8.3559 (not
# adjusted for ties), A2_akN = 8.3926 (adjusted, midrank), sigma_N = 1.2038, standardized
# 4.449 and 4.480, asymptotic p-values 0.0023 and 0.0022.

LAB_1 = [38.7, 41.5, 43.8, 44.5, 45.5, 46.0, 47.7, 58.0]
LAB_2 = [39.2, 39.3, 39.7, 41.4, 41.8, 42.9, 43.3, 45.8]
LAB_3 = [34.0, 35.0, 39.0, 40.0, 43.0, 43.0, 44.0, 45.0]
LAB_4 = [34.0, 34.8, 34.8, 35.4, 37.2, 37.8, 41.2, 42.8]


@pytest.mark.parametrize(
    ("variant", "a2", "p_published"), [("right", 8.3559, 0.0023), ("midrank", 8.3926, 0.0022)]
)
def test_anderson_darling_matches_scholz_stephens_example(
    variant: str, a2: float, p_published: float
) -> None:
    res = anderson_darling_ksamp([LAB_1, LAB_2, LAB_3, LAB_4], variant=variant)
    k = 4
    expected = (a2 - (k - 1)) / 1.2038  # the paper's standardization (A2 - (k - 1)) / sigma
    assert res.statistic == pytest.approx(expected, abs=1e-3)
    assert res.p_value == pytest.approx(p_published, abs=1e-4)
    assert not res.p_value_bounded
    assert res.sizes == (8, 8, 8, 8)


def test_anderson_darling_identical_samples_give_capped_p_and_shift_gives_small_p() -> None:
    intended = [0.0, 0.1, 0.2, 0.7]
    same = anderson_darling_ksamp([intended, intended])
    assert same.statistic < 0.0
    assert same.p_value == 0.25 and same.p_value_bounded
    base = np.linspace(0.0, 1.0, 15)
    shifted = anderson_darling_ksamp([base, base + 2.0])
    assert shifted.p_value <= 0.001 and shifted.p_value_bounded


def test_anderson_darling_permutation_p_value_is_seeded_and_not_bounded() -> None:
    a = anderson_darling_ksamp([LAB_1, LAB_4], n_resamples=499, seed=3)
    b = anderson_darling_ksamp([LAB_1, LAB_4], n_resamples=499, seed=3)
    assert a == b
    assert not a.p_value_bounded
    assert 0.0 < a.p_value < 0.01  # LAB_1 lies above LAB_4 almost entirely
    same = anderson_darling_ksamp([LAB_2, LAB_2], n_resamples=199, seed=0)
    assert same.p_value > 0.25 and not same.p_value_bounded


@pytest.mark.parametrize(
    ("samples", "match"),
    [
        ([[1.0, 2.0]], "k >= 2"),
        ([[1.0, 2.0], []], "at least 1"),
        ([[1.0, np.nan], [2.0, 3.0]], "NaN"),
        ([[[1.0, 2.0]], [2.0, 3.0]], "1-D"),
        ([[1.0, 1.0], [1.0]], "identical"),
        (np.array([1.0, 2.0, 3.0]), "single 1-D array"),
    ],
)
def test_anderson_darling_rejects_bad_samples(samples: object, match: str) -> None:
    with pytest.raises(StatsInputError, match=match):
        anderson_darling_ksamp(samples)  # type: ignore[arg-type]


def test_anderson_darling_rejects_bad_options() -> None:
    with pytest.raises(ValueError, match="variant"):
        anderson_darling_ksamp([LAB_1, LAB_2], variant="discrete")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="n_resamples"):
        anderson_darling_ksamp([LAB_1, LAB_2], n_resamples=0)


# ---------------------------------------------------------------------------------------------
# Mixed ANOVA: a 2 (between) x 3 (within) design with 3 subjects per group, checked against the
# sums of squares, F tests, effect sizes, Greenhouse-Geisser epsilon and Mauchly's W computed
# below with NumPy from their textbook definitions.

# Y[g, s, l]: group g, subject s in that group, level l of the within factor.
Y = np.array(
    [
        [[3.0, 5.0, 12.0], [4.0, 4.0, 5.0], [2.0, 6.0, 9.0]],
        [[5.0, 5.0, 2.0], [6.0, 9.0, 8.0], [4.0, 6.0, 3.0]],
    ]
)


DESIGN = {"dv": "rating", "within": "emotion", "between": "source", "subject": "participant"}


def _long(y: np.ndarray) -> pd.DataFrame:
    rows = [
        {"participant": f"p{g}{s}", "emotion": f"e{lvl}", "source": f"g{g}", "rating": y[g, s, lvl]}
        for g in range(y.shape[0])
        for s in range(y.shape[1])
        for lvl in range(y.shape[2])
    ]
    return pd.DataFrame(rows)


def _hand_mixed_anova(y: np.ndarray) -> dict[str, float]:
    """Sums of squares and tests of a balanced mixed design from their definitions."""
    n_g, n_s, n_l = y.shape
    n_subj = n_g * n_s
    grand = y.mean()
    ss_total = ((y - grand) ** 2).sum()
    ss_between = n_s * n_l * ((y.mean(axis=(1, 2)) - grand) ** 2).sum()
    ss_subjects = n_l * ((y.mean(axis=2) - grand) ** 2).sum()
    ss_within = n_subj * ((y.mean(axis=(0, 1)) - grand) ** 2).sum()
    ss_cells = n_s * ((y.mean(axis=1) - grand) ** 2).sum()
    ss_inter = ss_cells - ss_between - ss_within
    ss_err_b = ss_subjects - ss_between
    ss_err_w = ss_total - ss_subjects - ss_within - ss_inter
    df_b, df_w, df_i = n_g - 1, n_l - 1, (n_g - 1) * (n_l - 1)
    df_eb, df_ew = n_subj - n_g, (n_l - 1) * (n_subj - n_g)
    f_b = (ss_between / df_b) / (ss_err_b / df_eb)
    f_w = (ss_within / df_w) / (ss_err_w / df_ew)
    f_i = (ss_inter / df_i) / (ss_err_w / df_ew)
    # Pooled within-group covariance of the repeated measures, double-centred: S* = H S H.
    resid = (y - y.mean(axis=1, keepdims=True)).reshape(n_subj, n_l)
    cov = resid.T @ resid / (n_subj - n_g)
    h = np.eye(n_l) - np.full((n_l, n_l), 1.0 / n_l)
    s_star = h @ cov @ h
    eps = np.trace(s_star) ** 2 / ((n_l - 1) * np.trace(s_star @ s_star))
    # Mauchly's W on orthonormal contrasts C (columns orthogonal to the unit vector).
    c = np.linalg.qr(np.column_stack([np.ones(n_l), np.eye(n_l)[:, : n_l - 1]]))[0][:, 1:]
    m = c.T @ cov @ c
    w = np.linalg.det(m) / (np.trace(m) / (n_l - 1)) ** (n_l - 1)
    return {
        "ss_between": ss_between, "ss_within": ss_within, "ss_inter": ss_inter,
        "ss_err_b": ss_err_b, "ss_err_w": ss_err_w,
        "df_b": df_b, "df_w": df_w, "df_i": df_i, "df_eb": df_eb, "df_ew": df_ew,
        "f_b": f_b, "f_w": f_w, "f_i": f_i,
        "p_b": sps.f.sf(f_b, df_b, df_eb), "p_w": sps.f.sf(f_w, df_w, df_ew),
        "p_i": sps.f.sf(f_i, df_i, df_ew),
        "p_w_gg": sps.f.sf(f_w, eps * df_w, eps * df_ew),
        "p_i_gg": sps.f.sf(f_i, eps * df_i, eps * df_ew),
        "eps": eps, "w": w,
    }  # fmt: skip


def test_mixed_anova_matches_hand_computed_sums_of_squares_and_tests() -> None:
    hand = _hand_mixed_anova(Y)
    res = mixed_anova(_long(Y), **DESIGN)
    assert (res.n_subjects, res.n_groups, res.n_levels) == (6, 2, 3)
    ss_err = hand["ss_err_b"] + hand["ss_err_w"]
    for eff, key, df_err, ss_own_err in [
        (res.between, "b", "df_eb", hand["ss_err_b"]),
        (res.within, "w", "df_ew", hand["ss_err_w"]),
        (res.interaction, "i", "df_ew", hand["ss_err_w"]),
    ]:
        ss = hand[{"b": "ss_between", "w": "ss_within", "i": "ss_inter"}[key]]
        assert eff.ss == pytest.approx(ss, rel=1e-10)
        assert (eff.df1, eff.df2) == (hand[f"df_{key}"], hand[df_err])
        assert eff.f == pytest.approx(hand[f"f_{key}"], rel=1e-10)
        assert eff.p_unc == pytest.approx(hand[f"p_{key}"], rel=1e-8)
        assert eff.partial_eta_sq == pytest.approx(ss / (ss + ss_own_err), rel=1e-10)
        assert eff.generalized_eta_sq == pytest.approx(ss / (ss + ss_err), rel=1e-10)
    assert res.between.source == "source" and res.within.source == "emotion"
    assert res.between.p_gg == res.between.p_unc and res.between.eps == 1.0


def test_mixed_anova_greenhouse_geisser_epsilon_and_mauchly_match_closed_forms() -> None:
    hand = _hand_mixed_anova(Y)
    res = mixed_anova(_long(Y), **DESIGN)
    assert 0.5 <= hand["eps"] < 0.9  # bounds 1 / (k - 1) <= eps <= 1, clearly corrected here
    assert res.epsilon == pytest.approx(hand["eps"], rel=1e-8)
    assert res.within.eps == res.interaction.eps == res.epsilon
    assert res.within.p_gg == pytest.approx(hand["p_w_gg"], rel=1e-8)
    assert res.interaction.p_gg == pytest.approx(hand["p_i_gg"], rel=1e-8)
    assert res.within.p_gg > res.within.p_unc
    assert res.sphericity_w == pytest.approx(hand["w"], rel=1e-8)
    assert 0.0 < res.sphericity_p <= 1.0


def test_mixed_anova_partial_eta_squared_is_the_convention_of_carreno_medrano_tables() -> None:
    # Table 1 (between factor, F(1, 188)) and Table 2 (F(2, 67)) of Carreno-Medrano et al.
    for f_value, df1, df2, eta in [(54.308, 1, 188, 0.224), (2.477, 1, 188, 0.013),
                                    (29.732, 1, 188, 0.136), (4.424, 2, 67, 0.117)]:  # fmt: skip
        assert f_value * df1 / (f_value * df1 + df2) == pytest.approx(eta, abs=6e-4)
    res = mixed_anova(_long(Y), **DESIGN)
    for eff in (res.between, res.within, res.interaction):
        identity = eff.f * eff.df1 / (eff.f * eff.df1 + eff.df2)
        assert eff.partial_eta_sq == pytest.approx(identity, rel=1e-10)


def test_mixed_anova_two_levels_needs_no_correction() -> None:
    res = mixed_anova(_long(Y[:, :, :2]), **DESIGN)
    assert res.epsilon == 1.0
    assert res.within.p_gg == res.within.p_unc
    assert math.isnan(res.sphericity_w) and not res.sphericity_violated


def test_mixed_anova_rejects_bad_designs() -> None:
    good = _long(Y)
    with pytest.raises(StatsInputError, match="no column"):
        mixed_anova(good.drop(columns="rating"), **DESIGN)
    with pytest.raises(StatsInputError, match="NaN"):
        mixed_anova(good.assign(rating=good["rating"].where(good.index != 4)), **DESIGN)
    with pytest.raises(StatsInputError, match="average the repeated"):
        mixed_anova(pd.concat([good, good.iloc[[0]]]), **DESIGN)
    with pytest.raises(StatsInputError, match="incomplete"):
        mixed_anova(good.iloc[1:], **DESIGN)
    moved = good.copy()
    moved.loc[0, "source"] = "g1"
    with pytest.raises(StatsInputError, match="more than one level"):
        mixed_anova(moved, **DESIGN)
    with pytest.raises(StatsInputError, match="at least 2 levels"):
        mixed_anova(good[good["source"] == "g0"], **DESIGN)
    with pytest.raises(StatsInputError, match="DataFrame"):
        mixed_anova(good.to_numpy(), **DESIGN)  # type: ignore[arg-type]
    with pytest.raises(StatsInputError, match="one within"):
        mixed_anova(good, **{**DESIGN, "within": ["emotion", "source"]})  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# Mann-Whitney U


def _exact_u_null(n_x: int, n_y: int) -> np.ndarray:
    """U of the first sample for every assignment of ranks 1..n_x+n_y (no ties)."""
    ranks = range(1, n_x + n_y + 1)
    return np.array(
        [sum(c) - n_x * (n_x + 1) / 2 for c in itertools.combinations(ranks, n_x)], dtype=float
    )


def test_mann_whitney_tortoise_and_hare_example() -> None:
    # Wikipedia, "Mann-Whitney U test", illustration: finishing order T H H H H H T T T T T H.
    # Counting pairs in which a tortoise finishes before a hare gives U_T = 11, U_H = 25.
    tortoise = [1, 7, 8, 9, 10, 11]
    hare = [2, 3, 4, 5, 6, 12]
    res = mann_whitney_u(tortoise, hare)
    assert res.statistic == 25.0  # pairs with tortoise time > hare time (finishing later)
    assert res.u_y == 11.0
    null = _exact_u_null(6, 6)
    assert null.size == math.comb(12, 6)
    p_exact = min(1.0, 2.0 * np.mean(null >= res.statistic))
    assert res.p_value == pytest.approx(p_exact, rel=1e-12)
    assert res.rank_biserial == pytest.approx(2 * 25 / 36 - 1)


def test_mann_whitney_complete_separation_exact_p() -> None:
    res = mann_whitney_u([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])
    assert res.statistic == 0.0 and res.u_y == 9.0
    assert res.p_value == pytest.approx(2 / math.comb(6, 3))
    assert res.rank_biserial == -1.0
    one_sided = mann_whitney_u([1.0, 2.0, 3.0], [4.0, 5.0, 6.0], alternative="less")
    assert one_sided.p_value == pytest.approx(1 / math.comb(6, 3))


def test_mann_whitney_ties_use_tie_corrected_normal_approximation() -> None:
    x, y = [1.0, 2.0, 3.0, 5.0], [2.0, 4.0, 6.0]
    res = mann_whitney_u(x, y)
    u_hand = sum(1.0 if a > b else 0.5 if a == b else 0.0 for a in x for b in y)
    assert res.statistic == u_hand == 3.5
    n1, n2, n = 4, 3, 7
    ties = 2**3 - 2  # the value 2.0 appears twice
    sigma = math.sqrt(n1 * n2 / 12 * ((n + 1) - ties / (n * (n - 1))))
    z = (abs(u_hand - n1 * n2 / 2) - 0.5) / sigma
    assert res.p_value == pytest.approx(2 * sps.norm.sf(z), rel=1e-10)


@pytest.mark.parametrize(
    ("x", "y", "match"),
    [
        ([], [1.0], "at least 1"),
        ([1.0, np.nan], [1.0], "NaN"),
        ([[1.0, 2.0]], [1.0], "1-D"),
        ([2.0, 2.0], [2.0], "identical"),
        (["a"], [1.0], "numbers"),
    ],
)
def test_mann_whitney_rejects_bad_samples(x: object, y: object, match: str) -> None:
    with pytest.raises(StatsInputError, match=match):
        mann_whitney_u(x, y)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="alternative"):
        mann_whitney_u([1.0], [2.0], alternative="bigger")  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# Cronbach's alpha

RATINGS = np.array(
    [
        [2.0, 3.0, 3.0, 2.0],
        [4.0, 4.0, 5.0, 4.0],
        [3.0, 3.0, 2.0, 3.0],
        [5.0, 4.0, 5.0, 5.0],
        [1.0, 2.0, 1.0, 2.0],
        [3.0, 4.0, 4.0, 3.0],
    ]
)


def test_cronbach_alpha_matches_closed_form_and_feldt_interval() -> None:
    n, k = RATINGS.shape
    item_var = RATINGS.var(axis=0, ddof=1).sum()
    total_var = RATINGS.sum(axis=1).var(ddof=1)
    alpha = k / (k - 1) * (1 - item_var / total_var)
    res = cronbach_alpha(RATINGS)
    assert res.alpha == pytest.approx(alpha, rel=1e-12)
    assert (res.n_cases, res.n_items) == (6, 4)
    df1, df2 = n - 1, (n - 1) * (k - 1)
    lower = 1 - (1 - alpha) * sps.f.ppf(0.975, df1, df2)
    upper = 1 - (1 - alpha) * sps.f.ppf(0.025, df1, df2)
    assert res.ci_low == pytest.approx(lower, abs=6e-4)  # pingouin rounds to 3 decimals
    assert res.ci_high == pytest.approx(upper, abs=6e-4)


def test_cronbach_alpha_identical_items_is_one_and_reversed_item_lowers_it() -> None:
    column = RATINGS[:, :1]
    assert cronbach_alpha(np.hstack([column, column, column])).alpha == pytest.approx(1.0)
    reversed_rater = RATINGS.copy()
    reversed_rater[:, 0] = 6.0 - reversed_rater[:, 0]
    assert cronbach_alpha(reversed_rater).alpha < cronbach_alpha(RATINGS).alpha


@pytest.mark.parametrize(
    ("ratings", "match"),
    [
        (RATINGS[:, :1], "at least 2 rows and 2 columns"),
        (RATINGS[0], "2-D"),
        (np.where(RATINGS == 5.0, np.nan, RATINGS), "NaN"),
        (np.ones((4, 3)), "zero variance"),
    ],
)
def test_cronbach_alpha_rejects_bad_input(ratings: np.ndarray, match: str) -> None:
    with pytest.raises(StatsInputError, match=match):
        cronbach_alpha(ratings)


def test_cronbach_alpha_rejects_bad_ci() -> None:
    with pytest.raises(StatsInputError, match="ci"):
        cronbach_alpha(RATINGS, ci=95)


# ---------------------------------------------------------------------------------------------
# Fleiss' kappa

# Wikipedia, "Fleiss' kappa", worked example: 10 subjects, 14 raters, 5 categories;
# P_bar = 0.378, P_e = 0.213, kappa = 0.210.
WIKI_COUNTS = np.array(
    [
        [0, 0, 0, 0, 14], [0, 2, 6, 4, 2], [0, 0, 3, 5, 6], [0, 3, 9, 2, 0], [2, 2, 8, 1, 1],
        [7, 7, 0, 0, 0], [3, 2, 6, 3, 0], [2, 5, 3, 2, 2], [6, 5, 2, 1, 0], [0, 2, 2, 3, 7],
    ]
)  # fmt: skip

# Fleiss (1971), Psychological Bulletin 76(5), Table 1: 30 patients, 6 psychiatrists, 5
# diagnoses (1 depression, 2 personality disorder, 3 schizophrenia, 4 neurosis, 5 other), as
# raw ratings in R's irr::diagnoses. Published kappa = 0.430 (irr::kappam.fleiss: 0.4302445).
DIAGNOSES = np.array(
    [
        [4, 4, 4, 4, 4, 4], [2, 2, 2, 5, 5, 5], [2, 3, 3, 3, 3, 5], [5, 5, 5, 5, 5, 5],
        [2, 2, 2, 4, 4, 4], [1, 1, 3, 3, 3, 3], [3, 3, 3, 3, 5, 5], [1, 1, 3, 3, 3, 4],
        [1, 1, 4, 4, 4, 4], [5, 5, 5, 5, 5, 5], [1, 4, 4, 4, 4, 4], [1, 2, 4, 4, 4, 4],
        [2, 2, 2, 3, 3, 3], [1, 4, 4, 4, 4, 4], [2, 2, 4, 4, 4, 5], [3, 3, 3, 3, 3, 5],
        [1, 1, 1, 4, 5, 5], [1, 1, 1, 1, 1, 2], [2, 2, 4, 4, 4, 4], [1, 3, 3, 5, 5, 5],
        [5, 5, 5, 5, 5, 5], [2, 4, 4, 4, 4, 4], [2, 2, 4, 5, 5, 5], [1, 1, 4, 4, 4, 4],
        [1, 4, 4, 4, 4, 5], [2, 2, 2, 2, 2, 4], [1, 1, 1, 1, 5, 5], [2, 2, 4, 4, 4, 4],
        [1, 3, 3, 3, 3, 3], [5, 5, 5, 5, 5, 5],
    ]
)  # fmt: skip


def test_fleiss_kappa_wikipedia_worked_example() -> None:
    res = fleiss_kappa(WIKI_COUNTS, counts=True)
    assert res.kappa == pytest.approx(0.210, abs=5e-4)
    assert (res.n_subjects, res.n_raters, res.n_categories) == (10, 14, 5)
    n = 14
    p_bar = np.mean(((WIKI_COUNTS**2).sum(axis=1) - n) / (n * (n - 1)))
    p_e = ((WIKI_COUNTS.sum(axis=0) / WIKI_COUNTS.sum()) ** 2).sum()
    assert p_bar == pytest.approx(0.378, abs=5e-4) and p_e == pytest.approx(0.213, abs=5e-4)
    assert res.kappa == pytest.approx((p_bar - p_e) / (1 - p_e), rel=1e-12)
    randolph = fleiss_kappa(WIKI_COUNTS, counts=True, method="randolph")
    assert randolph.kappa == pytest.approx((p_bar - 1 / 5) / (1 - 1 / 5), rel=1e-12)


def test_fleiss_kappa_fleiss_1971_psychiatric_diagnoses() -> None:
    counts = np.stack([(DIAGNOSES == c).sum(axis=1) for c in range(1, 6)], axis=1)
    np.testing.assert_array_equal(counts.sum(axis=0), [26, 26, 30, 55, 43])  # transcription
    res = fleiss_kappa(DIAGNOSES)
    assert res.kappa == pytest.approx(0.430, abs=5e-4)
    assert res.kappa == pytest.approx(0.4302445, abs=1e-7)
    assert (res.n_subjects, res.n_raters, res.n_categories) == (30, 6, 5)
    assert fleiss_kappa(counts, counts=True).kappa == pytest.approx(res.kappa, rel=1e-12)
    labels = np.array(["dep", "pers", "schiz", "neur", "other"])[DIAGNOSES - 1]
    assert fleiss_kappa(labels).kappa == pytest.approx(res.kappa, rel=1e-12)


def test_fleiss_kappa_perfect_agreement_is_one() -> None:
    ratings = np.repeat(np.array([[0], [1], [2], [1]]), 5, axis=1)
    assert fleiss_kappa(ratings).kappa == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("data", "counts", "match"),
    [
        (np.array([[2, 1], [1, 1]]), True, "same number of raters"),
        (np.array([[3, -1], [1, 1]]), True, "non-negative integer"),
        (np.array([[1.5, 0.5], [1, 1]]), True, "non-negative integer"),
        (np.array([1, 2, 3]), False, "2-D"),
        (np.array([[1.0, np.nan], [1.0, 2.0]]), False, "NaN"),
        (np.array([[1, 1], [1, 1]]), False, "single category"),
        (np.array([[1], [2]]), False, "2 raters"),
    ],
)
def test_fleiss_kappa_rejects_bad_input(data: np.ndarray, counts: bool, match: str) -> None:
    with pytest.raises(StatsInputError, match=match):
        fleiss_kappa(data, counts=counts)


# ---------------------------------------------------------------------------------------------
# Rater outliers


def _panel(seed: int = 1, n_stimuli: int = 20, n_raters: int = 8) -> np.ndarray:
    """Raters who see the same latent stimulus values plus their own noise."""
    rng = np.random.default_rng(seed)
    latent = rng.normal(size=n_stimuli)
    return latent[:, None] + rng.normal(scale=0.5, size=(n_stimuli, n_raters))


def _loo_corr(ratings: np.ndarray, rank: bool) -> np.ndarray:
    """Leave-one-out correlation computed here with NumPy (ranks by double argsort, no ties)."""
    out = []
    for j in range(ratings.shape[1]):
        own = ratings[:, j]
        others = np.delete(ratings, j, axis=1).mean(axis=1)
        if rank:
            own, others = own.argsort().argsort(), others.argsort().argsort()
        out.append(np.corrcoef(own, others)[0, 1])
    return np.array(out)


def test_rater_outliers_tukey_flags_random_and_reversed_raters() -> None:
    ratings = _panel()
    ratings[:, 3] = np.random.default_rng(3).normal(size=20)  # careless: unrelated answers
    ratings[:, 6] = -ratings[:, 6]  # reversed the scale
    res = rater_outliers(ratings)
    agreement = _loo_corr(ratings, rank=True)
    np.testing.assert_allclose(res.agreement, agreement, rtol=1e-12)
    q1, q3 = np.percentile(agreement, [25, 75])
    assert res.lower == pytest.approx(q1 - 1.5 * (q3 - q1))
    assert res.upper == np.inf
    np.testing.assert_array_equal(res.outlier_indices, [3, 6])


def test_rater_outliers_mad_threshold_and_pearson_rules() -> None:
    ratings = _panel(seed=2)
    ratings[:, 0] = np.random.default_rng(9).normal(size=20)
    pearson = _loo_corr(ratings, rank=False)
    res = rater_outliers(ratings, correlation="pearson", rule="mad", k=3.0)
    np.testing.assert_allclose(res.agreement, pearson, rtol=1e-12)
    med = np.median(pearson)
    mad = 1.482602218505602 * np.median(np.abs(pearson - med))  # 1 / Phi^-1(3/4)
    assert res.lower == pytest.approx(med - 3.0 * mad, rel=1e-9)
    np.testing.assert_array_equal(res.outlier_indices, [0])
    fixed = rater_outliers(ratings, correlation="pearson", rule="threshold", threshold=0.5)
    np.testing.assert_array_equal(fixed.outliers, pearson < 0.5)


def test_rater_outliers_two_sided_and_constant_rater() -> None:
    ratings = _panel(seed=4)
    res = rater_outliers(ratings, two_sided=True, k=0.0)  # fences at the quartiles themselves
    q1, q3 = np.percentile(res.agreement, [25, 75])
    np.testing.assert_array_equal(res.outliers, (res.agreement < q1) | (res.agreement > q3))
    assert res.outliers.sum() >= 2
    ratings[:, 2] = 3.0  # always the same answer
    const = rater_outliers(ratings)
    assert np.isnan(const.agreement[2]) and const.outliers[2]
    assert np.all(np.isfinite(np.delete(const.agreement, 2)))


@pytest.mark.parametrize(
    ("ratings", "kwargs", "match"),
    [
        (np.ones((10, 2)), {}, "at least 3 rows and 3 columns"),
        (np.full((10, 4), np.nan), {}, "NaN"),
        (None, {"rule": "threshold"}, "threshold"),
        (None, {"k": -1.0}, "k must be"),
        (None, {"rule": "iqr"}, "rule"),
        (None, {"rule": "threshold", "threshold": 0.2, "two_sided": True}, "two_sided"),
        (np.column_stack([np.arange(5.0), np.ones((5, 3))]), {}, "undefined"),
    ],
)
def test_rater_outliers_rejects_bad_input(
    ratings: np.ndarray | None, kwargs: dict[str, object], match: str
) -> None:
    data = _panel() if ratings is None else ratings
    with pytest.raises(StatsInputError, match=match):
        rater_outliers(data, **kwargs)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------------------
# Optional dependencies


def test_missing_optional_library_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "pingouin", None)
    with pytest.raises(MissingDependencyError, match=r"pip install 'emotive\[eval\]'") as info:
        cronbach_alpha(RATINGS)
    assert isinstance(info.value, ImportError)
    monkeypatch.setitem(sys.modules, "statsmodels.stats.inter_rater", None)
    with pytest.raises(ImportError, match="statsmodels"):
        fleiss_kappa(WIKI_COUNTS, counts=True)


def test_importing_the_module_loads_no_heavy_library() -> None:
    code = (
        "import sys, emotive.eval.stats\n"
        "heavy = [m for m in ('pandas', 'pingouin', 'statsmodels', 'scipy.stats') "
        "if m in sys.modules]\n"
        "print(','.join(heavy))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == ""
