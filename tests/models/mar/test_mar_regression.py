"""Mixture weights, ridge fits and the bias term."""

from __future__ import annotations

import numpy as np
import pytest

from emotive.models.mar.regression import mixture_weights, predict, ridge_ar


def test_mixture_weights_follow_equation_4():
    d = np.array([1.0, 1.5, 3.0])
    w = mixture_weights(d, 0.7)
    expected = np.exp(-d / (0.7 * 1.0))
    np.testing.assert_allclose(w, expected / expected.sum())
    assert w.sum() == pytest.approx(1.0)


def test_ridge_recovers_a_linear_map_and_shrinks_with_lambda(rng):
    u = np.concatenate((rng.normal(size=(3, 200, 3)), np.ones((3, 200, 1))), -1)
    beta = np.array([0.5, -1.0, 2.0, 0.3])
    y = u @ beta
    np.testing.assert_allclose(ridge_ar(u, y, 1e-9), np.broadcast_to(beta, (3, 4)), atol=1e-6)
    shrunk = ridge_ar(u, y, 1e3)
    assert np.all(np.linalg.norm(shrunk, axis=-1) < np.linalg.norm(beta))


def _neighbours(db, search, action, style, frame_offset=0):
    cls = db.classes_where(action, style)
    window = db.points[db.window_index()[search.class_frames[cls[0]][10 + frame_offset]]]
    return search.brute_force(window.astype(np.float64), cls), cls


def test_the_bias_carries_a_share_rho_of_an_out_of_range_input(mar_db, mar_search):
    db = mar_db
    nb, _ = _neighbours(db, mar_search, "walk", "neutral")
    frames = nb.frames[0]
    x = ((db.vectors[frames] - db.mean) / db.std).mean(0)
    styles = np.array([db.styles.index("proud")])
    d = int(np.argmax(db.std * (db.std != 1.0)))

    def far(offset: float, rho: float, bias: bool = True) -> float:
        shifted = x.copy()
        shifted[d] += offset
        # A stream whose output already follows the input's bias by rho.
        y_prev = x.copy()
        y_prev[d] += rho * offset
        return predict(db, nb, shifted, shifted, y_prev, styles, np.ones(1), rho=rho,
                       bias=bias).pose[d]

    for rho in (0.0, 0.3, 0.7, 1.0):
        # Both inputs lie beyond mu + kappa sigma: the model sees the same clamped input and
        # only the share rho of the extra 30 standard units reaches the output.
        assert far(80.0, rho) - far(50.0, rho) == pytest.approx(rho * 30.0, abs=1e-6)
    assert abs(far(80.0, 0.7, False) - far(50.0, 0.7, False) - 21.0) > 1e-3


def test_style_weights_blend_the_outputs_linearly(mar_db, mar_search):
    db = mar_db
    nb, _ = _neighbours(db, mar_search, "walk", "neutral")
    x = (db.vectors[nb.frames[0, 0]] - db.mean) / db.std
    both = np.array([db.styles.index("proud"), db.styles.index("sad")])
    a = predict(db, nb, x, x, x, both[:1], np.ones(1)).pose
    b = predict(db, nb, x, x, x, both[1:], np.ones(1)).pose
    mix = predict(db, nb, x, x, x, both, np.array([0.25, 0.75])).pose
    np.testing.assert_allclose(mix, 0.25 * a + 0.75 * b, atol=1e-9)


def test_the_ridge_shrinks_towards_the_neighbours_mean_not_towards_zero(rng):
    """Regression: the ridge penalized the intercept of uncentred regressors, pulling every
    local model towards the database's mean pose (zero in standardized units)."""
    u = np.concatenate((5.0 + 0.1 * rng.normal(size=(40, 3)), np.ones((40, 1))), -1)
    y = 7.0 + u[:, :3] @ np.array([0.5, 0.2, -0.1])
    beta = ridge_ar(u, y, 1e6)
    # All slopes shrunk away: the prediction at the neighbours' mean is their mean output.
    np.testing.assert_allclose(beta[:3], 0.0, atol=1e-4)
    assert u.mean(0) @ beta == pytest.approx(y.mean(), abs=1e-6)


def test_the_classic_local_models_use_the_pooled_nearest_frames(mar_db, mar_search):
    db = mar_db
    nb, _ = _neighbours(db, mar_search, "walk", "neutral")
    every = mar_search.brute_force(
        db.points[db.window_index()[mar_search.class_frames[nb.classes[0]][10]]].astype(float),
        db.classes_where("walk"))
    x = (db.vectors[every.frames[0, 0]] - db.mean) / db.std
    styles = np.array([db.styles.index("proud")])
    nn = predict(db, every, x, x, x, styles, np.ones(1), method="nn")
    best = np.unravel_index(np.argmin(every.distances), every.distances.shape)
    assert nn.mixture[best[0]] > 0 and nn.mixture.sum() == pytest.approx(1.0)
    assert np.all(nn.mixture[np.arange(len(nn.mixture)) != best[0]] < 1.0)


def test_the_closed_form_ridge_equals_a_batched_solve(rng):
    """``ridge_ar3`` (adjugate of the centred 3x3 Gram matrices, regressors broadcast over
    the output styles) against :func:`ridge_ar` (one ``np.linalg.solve`` per system)."""
    from emotive.models.mar.regression import ridge_ar3

    c, o, k, d = 3, 2, 12, 5
    x1 = rng.normal(size=(c, 1, k, d)) + 3.0
    x3 = x1 + 0.3 * rng.normal(size=(c, 1, k, d))
    x2 = rng.normal(size=(c, o, k, d)) - 2.0
    y = 0.5 * x1 - x2 + 0.2 * x3 + 0.1 * rng.normal(size=(c, o, k, d))
    q1, q2, q3 = (rng.normal(size=s) for s in ((c, 1, 1, d), (c, o, 1, d), (c, 1, 1, d)))
    for ridge in (0.1, 5.0):
        fast = ridge_ar3(x1, x2, x3, y, ridge, q1, q2, q3)
        u = np.stack(np.broadcast_arrays(x1, x2, x3, np.ones_like(x2)), -1)
        beta = ridge_ar(np.moveaxis(u, -2, -3), np.moveaxis(y, -1, -2), ridge)
        query = np.stack(np.broadcast_arrays(q1[..., 0, :], q2[..., 0, :], q3[..., 0, :],
                                             np.ones((c, o, d))), -1)
        np.testing.assert_allclose(fast, (query * beta).sum(-1), rtol=1e-10, atol=1e-10)


def _reference_predict(db, nb, x_t, x_prev, y_prev, styles, style_weights, rho, bias,
                       method):
    """The straightforward form of :func:`predict`: standardized copies of every pair,
    ``u_t`` stacked per degree of freedom, one solve per ridge system and the timing
    features concatenated."""
    from emotive.models.mar.regression import mixture_weights, standardize, track_rows

    cfg = db.config
    mean_d = nb.distances.mean(1)
    if method == "mar":
        lam = mixture_weights(mean_d, cfg.delta)
        active = np.flatnonzero(lam >= cfg.min_weight)
        lam_a = lam[active] / lam[active].sum()
        frames, dist = nb.frames[active], nb.distances[active]
    else:
        order = np.argsort(nb.distances, axis=None, kind="stable")
        flat_f, flat_d = nb.frames.reshape(-1)[order], nb.distances.reshape(-1)[order]
        _, first = np.unique(flat_f, return_index=True)
        pick = np.sort(first)[:nb.frames.shape[1]]
        frames, dist = flat_f[pick][None], flat_d[pick][None]
        lam_a = np.ones(1)
    prev = db.prev[frames]
    out_cls = np.moveaxis(db.output_classes()[db.frame_class[frames]][..., styles], -1, 1)
    tau = np.broadcast_to(db.tau[frames][:, None], out_cls.shape)
    tau_prev = np.broadcast_to(db.tau[prev][:, None], tau.shape)
    y_t, out_rate, _ = track_rows(db, out_cls, tau)
    y_p, _, _ = track_rows(db, out_cls, tau_prev)
    y_t, y_p = standardize(db, y_t), standardize(db, y_p)
    xs_t = standardize(db, db.vectors[frames].astype(np.float64))
    xs_p = standardize(db, db.vectors[prev].astype(np.float64))
    kernel = np.exp(-0.5 * (dist / np.maximum(dist.mean(1, keepdims=True), 1e-12)) ** 2)
    kernel /= kernel.sum(1, keepdims=True)
    if method == "nn":
        pose_co = y_t[:, :, 0]
    elif method == "knn" or y_prev is None:
        pose_co = np.einsum("ck,cokd->cod", kernel, y_t)
    else:
        mu, sigma = xs_t.mean(1), xs_t.std(1)
        lo, hi = mu - cfg.kappa * sigma, mu + cfg.kappa * sigma
        dx = np.where(x_t > hi, x_t - hi, np.where(x_t < lo, x_t - lo, 0.0)) if bias \
            else np.zeros_like(mu)
        # The paper's ridge, in the data's own units (not standardized).
        def raw(v):
            return v * db.std + db.mean

        u = np.stack(np.broadcast_arrays(
            raw(xs_p)[:, None], raw(y_p), raw(xs_t)[:, None], np.ones(y_t.shape)), -1)
        beta = ridge_ar(np.moveaxis(u, 2, 3), np.moveaxis(raw(y_t), 2, 3), cfg.ridge)
        query = np.stack(np.broadcast_arrays(
            raw(x_prev - dx)[:, None], raw(y_prev - rho * dx)[:, None], raw(x_t - dx)[:, None],
            np.ones((len(frames), 1, len(x_t)))), -1)
        pose_co = standardize(db, (query * beta).sum(-1)) + rho * dx[:, None]
    advance_k = db.rate[frames][:, None] * out_rate
    step_ref = y_prev if y_prev is not None else pose_co
    q_feat = np.concatenate((np.broadcast_to(x_t, pose_co.shape),
                             np.broadcast_to(x_t - x_prev, pose_co.shape), pose_co,
                             pose_co - step_ref), -1)
    n_feat = np.concatenate((np.broadcast_to(xs_t[:, None], y_t.shape),
                             np.broadcast_to((xs_t - xs_p)[:, None], y_t.shape), y_t,
                             y_t - y_p), -1)
    tk = min(cfg.timing_k, frames.shape[1])
    tdist = np.sqrt(((n_feat[:, :, :tk] - q_feat[:, :, None]) ** 2).mean(-1))
    g = np.exp(-0.5 * (tdist / np.maximum(tdist.mean(-1, keepdims=True), 1e-12)) ** 2)
    advance_co = (g * advance_k[:, :, :tk]).sum(-1) / g.sum(-1)
    pose = np.einsum("c,o,cod->d", lam_a, style_weights, pose_co)
    return pose, float(np.einsum("c,o,co->", lam_a, style_weights, advance_co))


@pytest.mark.parametrize("method", ["mar", "ar", "knn", "nn"])
def test_predict_equals_the_straightforward_reference(mar_db, mar_search, rng, method):
    db = mar_db
    cls = db.classes_where("walk")
    idx = db.window_index()
    styles = np.array([db.styles.index("proud"), db.styles.index("sad")])
    sw = np.array([0.3, 0.7])
    for trial in range(4):
        frame = rng.choice(np.flatnonzero(np.isin(db.frame_class, cls)))
        window = db.points[idx[frame]].astype(np.float64) + rng.normal(0, 0.02, (3, 21, 3))
        nb = mar_search.brute_force(window, cls)
        x_t = (db.vectors[frame] - db.mean) / db.std + rng.normal(0, 0.3, db.mean.shape)
        # Some degrees of freedom far outside the neighbours' range (the bias acts there).
        x_t[rng.choice(len(x_t), 3, replace=False)] += 20.0
        x_prev = x_t + rng.normal(0, 0.1, x_t.shape)
        y_prev = None if trial == 0 else x_t + rng.normal(0, 0.5, x_t.shape)
        for bias in (True, False):
            got = predict(db, nb, x_t, x_prev, y_prev, styles, sw, rho=0.6, bias=bias,
                          method=method)
            pose, advance = _reference_predict(db, nb, x_t, x_prev, y_prev, styles, sw, 0.6,
                                               bias, method)
            np.testing.assert_allclose(got.pose, pose, rtol=1e-9, atol=1e-9)
            assert got.advance == pytest.approx(advance, rel=1e-9)
