"""Mixed ANOVA against sums of squares and tests computed here by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("pingouin")
pytest.importorskip("statsmodels")

from scipy import stats as sps  # noqa: E402

from emotive.eval.anova import mixed_anova  # noqa: E402
from emotive.eval.stats import StatsInputError  # noqa: E402

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
