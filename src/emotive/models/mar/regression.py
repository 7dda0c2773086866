"""Local mixtures of autoregressive models and the timing prediction (paper sections 5.1-5.4).

For one input frame and its neighbours in each class ``j`` (:mod:`emotive.models.mar.search`),
every degree of freedom ``d`` gets, per class and per output style ``o``, the ridge fit
``y_t = u_t^T beta``, ``u_t = [x_{t-1}, y_{t-1}, x_t, 1]``, on the neighbours' pairs: ``x`` an
example frame (and its predecessor) of class ``j``, ``y`` the track of style ``o`` at the same
canonical times. Degrees of freedom are standardized with the database's mean and spread
``sigma_d`` first; ``lambda`` is the paper's, in the data's own units (radians of the
exponential maps, leg lengths of the root steps), so on the standardized degree of freedom
``d`` the penalty is ``lambda / sigma_d^2`` (the slopes of one degree of freedom on itself do
not change with its scale, its squared residuals scale by ``1 / sigma_d^2``). The ridge acts on
the slopes of the regressors centred on the neighbours (the intercept is free, see
:func:`ridge_ar`).

Speed: :func:`predict` solves the ``c * o * D`` ridge systems of one frame at once in closed
form (:func:`ridge_ar3`: centred 3x3 Gram matrices, the input regressors shared by the output
styles, the adjugate for the inverse) and sums the timing distance part by part instead of
concatenating feature vectors; ``tests/models/mar/test_mar_regression.py`` checks it against
the straightforward form (one :func:`ridge_ar` solve per system).

Bias (5.3): when ``x_t`` leaves ``mu +- kappa sigma`` of the neighbours' ``x_t``, the overshoot
``dx`` is taken off ``x_t`` and ``x_{t-1}``, ``rho dx`` off ``y_{t-1}``, and ``rho dx`` is added to
the prediction. Mixture (5.2): ``lambda_j ~ exp(-D_j / (delta min D))`` with ``D_j`` the mean
distance of class ``j``'s neighbours; the output is the expectation ``sum_j lambda_j u^T beta_j``.
Styles (5.4): the outputs of the styles are blended with the user's weights.

Timing (5.1): each neighbour's output frames per input frame is its own rate (canonical frames
per frame) times the output track's frames per canonical frame; these are interpolated with a
Gaussian kernel on the paper's four-part distance (input pose, input velocity, output pose,
output velocity), whose width is the mean distance of the neighbours (our choice; the paper
gives none), and mixed with the same ``lambda_j``.

Legend: ``c`` classes, ``o`` output styles, ``K`` neighbours, ``D`` pose dimensions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emotive.models.mar.database import MARDatabase
from emotive.models.mar.search import Neighbours

#: Regression methods: the paper's mixture and the simpler local models of its section 7.4.
METHODS = ("mar", "ar", "knn", "nn")


@dataclass(frozen=True)
class Prediction:
    """One output frame before decoding.

    Attributes:
        pose: ``(D,)`` standardized output pose.
        advance: output frames per input frame at this frame.
        mixture: ``(c,)`` mixture weight of each searched class.
    """

    pose: np.ndarray
    advance: float
    mixture: np.ndarray


def mixture_weights(distances: np.ndarray, delta: float) -> np.ndarray:
    """Equation 4: ``(c,)`` weights of mean distances ``(c,)``, summing to one.

    Equation 4: ``(c,)`` weights ``~ exp(-D_j / (delta min D))`` of mean distances ``(c,)``,
    summing to one.
    """
    d = np.asarray(distances, dtype=np.float64)
    low = max(float(d.min()), 1e-12)
    logits = -(d - d.min()) / (delta * low)
    w = np.exp(logits)
    return w / w.sum()


def track_rows(db: MARDatabase, classes: np.ndarray, tau: np.ndarray,
               standard: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tracks of ``classes`` at canonical times ``tau`` (same shape ``(...)``).

    Args:
        db: the database.
        classes: class of each lookup, shape ``(...)``.
        tau: canonical time of each lookup, shape ``(...)``.
        standard: pose vectors standardized (:func:`standardize`).

    Returns:
        Pose vectors ``(..., D)``, frames per canonical frame ``(...)`` and contacts
        ``(..., 2)``, interpolated linearly.
    """
    start = db.track_start[classes]
    length = db.track_start[classes + 1] - start
    t = np.clip(tau, 0.0, length - 1)
    lo = np.floor(t).astype(np.int64)
    hi = np.minimum(lo + 1, length - 1)
    a = t - lo
    r0, r1 = start + lo, start + hi
    rows = db.standard_tracks() if standard else db.track_pose
    pose = (1.0 - a)[..., None] * rows[r0] + a[..., None] * rows[r1]
    rate = (1.0 - a) * db.track_rate[r0] + a * db.track_rate[r1]
    contact = (1.0 - a)[..., None] * db.track_contacts[r0] + a[..., None] * db.track_contacts[r1]
    return pose, rate, contact


def ridge_ar(u: np.ndarray, y: np.ndarray, ridge: float) -> np.ndarray:
    """Ridge fits of ``y = u^T beta``, batched, the last regressor being the constant 1.

    The penalty ``lambda |beta|^2`` applies to the slopes of the centred regressors (the
    neighbours' means taken off); the intercept is not penalized. Penalizing it, or fitting
    uncentred regressors, would pull every prediction towards the zero of the standardized
    pose (the database's mean pose) instead of shrinking the local model towards the mean
    of the neighbours' outputs.

    Args:
        u: ``(..., K, 4)`` regressors, ``u[..., 3] == 1``.
        y: ``(..., K)`` targets.
        ridge: ``lambda``.

    Returns:
        ``(..., 4)`` coefficients (slopes, then the intercept).
    """
    x = u[..., :-1]
    mx = x.mean(-2, keepdims=True)
    my = y.mean(-1, keepdims=True)
    xc, yc = x - mx, y - my
    xt = np.swapaxes(xc, -1, -2)
    a = xt @ xc + ridge * np.eye(x.shape[-1])
    slopes = np.linalg.solve(a, xt @ yc[..., None])[..., 0]
    intercept = my[..., 0] - (mx[..., 0, :] * slopes).sum(-1)
    return np.concatenate((slopes, intercept[..., None]), -1)


def standardize(db: MARDatabase, vectors: np.ndarray) -> np.ndarray:
    """Pose vectors ``(..., D)`` in units of the database spread."""
    return (vectors - db.mean) / db.std


def ridge_ar3(x1: np.ndarray, x2: np.ndarray, x3: np.ndarray, y: np.ndarray, ridge: float,
              q1: np.ndarray, q2: np.ndarray, q3: np.ndarray) -> np.ndarray:
    """:func:`ridge_ar` with three regressors and the prediction at a query, in closed form.

    Every argument broadcasts over a leading batch shape ``(...)`` and has the neighbours on
    axis ``-2`` and the degrees of freedom on axis ``-1``: ``(..., K, D)`` regressors ``x1,
    x2, x3`` and targets ``y``; ``(..., 1, D)`` query ``q1, q2, q3``. Regressors shared by
    several batch entries (the input frames, the same for every output style) are passed
    once and broadcast. The 3x3 ridge systems of the centred regressors are solved by the
    adjugate (they are symmetric and, for ``ridge > 0``, positive definite), all degrees of
    freedom at once.

    Returns:
        ``(..., D)`` predictions ``[q1, q2, q3, 1]^T beta`` (the same as
        ``ridge_ar(u, y, ridge)`` applied to the query).
    """
    m1, m2, m3 = x1.mean(-2), x2.mean(-2), x3.mean(-2)
    my = y.mean(-2)
    a1 = x1 - m1[..., None, :]
    a2 = x2 - m2[..., None, :]
    a3 = x3 - m3[..., None, :]
    g11 = (a1 * a1).sum(-2) + ridge
    g22 = (a2 * a2).sum(-2) + ridge
    g33 = (a3 * a3).sum(-2) + ridge
    g12 = (a1 * a2).sum(-2)
    g13 = (a1 * a3).sum(-2)
    g23 = (a2 * a3).sum(-2)
    # Centred regressors sum to zero over the neighbours, so y need not be centred.
    r1, r2, r3 = (a1 * y).sum(-2), (a2 * y).sum(-2), (a3 * y).sum(-2)
    c11 = g22 * g33 - g23 * g23
    c12 = g13 * g23 - g12 * g33
    c13 = g12 * g23 - g13 * g22
    c22 = g11 * g33 - g13 * g13
    c23 = g12 * g13 - g11 * g23
    c33 = g11 * g22 - g12 * g12
    det = g11 * c11 + g12 * c12 + g13 * c13
    inv = 1.0 / det
    b1 = (c11 * r1 + c12 * r2 + c13 * r3) * inv
    b2 = (c12 * r1 + c22 * r2 + c23 * r3) * inv
    b3 = (c13 * r1 + c23 * r2 + c33 * r3) * inv
    return (my + b1 * (q1[..., 0, :] - m1) + b2 * (q2[..., 0, :] - m2)
            + b3 * (q3[..., 0, :] - m3))


def _pairs(db: MARDatabase, frames: np.ndarray, styles: np.ndarray) -> tuple[np.ndarray, ...]:
    """Standardized training pairs of neighbours ``frames`` for output ``styles``.

    Standardized training pairs of neighbours ``frames`` ``(c, K)`` for output ``styles``:
    inputs ``x_t, x_{t-1}`` ``(c, K, D)``, outputs ``y_t, y_{t-1}`` ``(c, o, K, D)``, the
    output tracks' frames per canonical frame ``(c, o, K)``.
    """
    prev = db.prev[frames]
    out_cls = np.moveaxis(db.output_classes()[db.frame_class[frames]][..., styles], -1, 1)
    both = np.stack((frames, prev))
    tau = np.broadcast_to(db.tau[both][:, :, None], (2, *out_cls.shape))
    y, rate, _ = track_rows(db, np.broadcast_to(out_cls, tau.shape), tau, standard=True)
    x = (db.vectors[both] - db.mean) / db.std
    return x[0], x[1], y[0], y[1], rate[0]


def predict(
    db: MARDatabase,
    nb: Neighbours,
    x_t: np.ndarray,
    x_prev: np.ndarray,
    y_prev: np.ndarray | None,
    styles: np.ndarray,
    style_weights: np.ndarray,
    *,
    rho: float | None = None,
    bias: bool = True,
    method: str = "mar",
) -> Prediction:
    """The output frame of one input frame.

    Args:
        db: the database.
        nb: the input window's neighbours; every searched class must have a track in each of
            ``styles`` (see :meth:`MARDatabase.output_classes`).
        x_t: ``(D,)`` standardized input pose.
        x_prev: ``(D,)`` the previous input pose (``x_t`` at the first frame).
        y_prev: ``(D,)`` the previous output pose, or None at the first frame (then the
            output is the kernel interpolation of the neighbours).
        styles: ``(o,)`` indices into :attr:`MARDatabase.styles`.
        style_weights: ``(o,)`` non-negative weights summing to one.
        rho: output share of the bias (``config.rho`` when None).
        bias: use the bias of section 5.3.
        method: ``"mar"`` (mixture of the classes' local models) or a classic local model
            of paper 7.4 on the ``K`` nearest frames of all searched classes pooled: ``"ar"``
            (one local autoregressive model), ``"knn"`` (their kernel interpolation) or
            ``"nn"`` (the nearest frame).

    Returns:
        The standardized output pose, its timing and the mixture weights.
    """
    cfg = db.config
    rho = cfg.rho if rho is None else rho
    mean_d = nb.distances.mean(1)
    if method == "mar":
        lam = mixture_weights(mean_d, cfg.delta)
        active = np.flatnonzero(lam >= cfg.min_weight)
        lam_a = lam[active] / lam[active].sum()
        frames, dist = nb.frames[active], nb.distances[active]
    else:
        # The classic local models (paper 7.4) know no classes: the K nearest frames of the
        # database (of all searched classes together), each with its own group's track.
        k_all = nb.frames.shape[1]
        order = np.argsort(nb.distances, axis=None, kind="stable")
        flat_f, flat_d = nb.frames.reshape(-1)[order], nb.distances.reshape(-1)[order]
        _, first = np.unique(flat_f, return_index=True)
        pick = np.sort(first)[:k_all]
        frames, dist = flat_f[pick][None], flat_d[pick][None]
        lam_a = np.ones(1)
        slot = {int(c): i for i, c in enumerate(nb.classes)}
        owner = [slot[int(c)] for c in db.frame_class[frames[0]]]
        lam = np.bincount(owner, minlength=len(mean_d)) / len(owner)
    xs_t, xs_p, y_t, y_p, out_rate = _pairs(db, frames, styles)

    k = frames.shape[1]
    if method == "nn":
        pose_co = y_t[:, :, 0]
    elif method == "knn" or y_prev is None:
        kernel = np.exp(-0.5 * (dist / np.maximum(dist.mean(1, keepdims=True), 1e-12)) ** 2)
        kernel /= kernel.sum(1, keepdims=True)
        pose_co = np.einsum("ck,cokd->cod", kernel, y_t)
    else:
        if bias:
            mu, sigma = xs_t.mean(1), xs_t.std(1)
            lo, hi = mu - cfg.kappa * sigma, mu + cfg.kappa * sigma
            dx = np.where(x_t > hi, x_t - hi, np.where(x_t < lo, x_t - lo, 0.0))
        else:
            dx = np.zeros((len(frames), len(x_t)))
        q1 = (x_prev - dx)[:, None, None]
        q2 = (y_prev - rho * dx)[:, None, None]
        q3 = (x_t - dx)[:, None, None]
        pose_co = ridge_ar3(xs_p[:, None], y_p, xs_t[:, None], y_t, cfg.ridge / db.std**2,
                            q1, q2, q3) \
            + rho * dx[:, None]

    # Timing (5.1): Gaussian kernel on the four-part distance (input pose and velocity,
    # output pose and velocity) between the query and each neighbour, summed part by part.
    tk = min(cfg.timing_k, k)
    dim = len(x_t)
    ex_t, ex_p, ey_t, ey_p = xs_t[:, :tk], xs_p[:, :tk], y_t[:, :, :tk], y_p[:, :, :tk]
    d_in = (((ex_t - x_t) ** 2).sum(-1)
            + ((ex_t - ex_p - (x_t - x_prev)) ** 2).sum(-1))
    step = pose_co - (y_prev if y_prev is not None else pose_co)
    d_out = (((ey_t - pose_co[:, :, None]) ** 2).sum(-1)
             + ((ey_t - ey_p - step[:, :, None]) ** 2).sum(-1))
    tdist = np.sqrt((d_in[:, None] + d_out) / (4 * dim))
    g = np.exp(-0.5 * (tdist / np.maximum(tdist.mean(-1, keepdims=True), 1e-12)) ** 2)
    advance_k = db.rate[frames][:, None, :tk] * out_rate[:, :, :tk]
    advance_co = (g * advance_k).sum(-1) / g.sum(-1)

    sw = np.asarray(style_weights, dtype=np.float64)
    pose = np.einsum("c,o,cod->d", lam_a, sw, pose_co)
    advance = float(np.einsum("c,o,co->", lam_a, sw, advance_co))
    if method == "mar":
        mixture = np.zeros(len(lam))
        mixture[active] = lam_a
    else:
        mixture = lam
    return Prediction(pose, advance, mixture)
