"""Sample comparisons (Anderson-Darling, Mann-Whitney U) against published values and closed
forms computed here by hand; the statistics modules import no heavy library."""

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

from emotive.eval.stats import StatsInputError, anderson_darling_ksamp, mann_whitney_u  # noqa: E402

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
# Optional dependencies


def test_importing_the_modules_loads_no_heavy_library() -> None:
    code = (
        "import sys, emotive.eval.stats, emotive.eval.anova, emotive.eval.agreement\n"
        "heavy = [m for m in ('pandas', 'pingouin', 'statsmodels', 'scipy.stats') "
        "if m in sys.modules]\n"
        "print(','.join(heavy))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == ""


def test_anderson_darling_without_a_p_value_is_an_input_error():
    with pytest.raises(StatsInputError, match="too degenerate"):
        anderson_darling_ksamp([[1.0]] * 10 + [[5.0]] * 10)
