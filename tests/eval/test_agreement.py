"""Rater agreement statistics against published values and closed forms computed here by hand."""

from __future__ import annotations

import sys

import numpy as np
import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("pingouin")
pytest.importorskip("statsmodels")

from scipy import stats as sps  # noqa: E402

from emotive.eval.agreement import cronbach_alpha, fleiss_kappa, rater_outliers  # noqa: E402
from emotive.eval.stats import MissingDependencyError, StatsInputError  # noqa: E402

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
