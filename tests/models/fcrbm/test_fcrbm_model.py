"""FCRBM conditionals, shapes, reductions to simpler models, updates and input checks."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

from emotive.models.fcrbm.config import CONTEXT_FEATURES, FCRBMConfig
from emotive.models.fcrbm.model import FCRBM, RBF_CENTRES, sliding_windows

B, N, D, H, C = 5, 3, 4, 6, 2


@pytest.fixture(params=CONTEXT_FEATURES)
def model(request) -> FCRBM:
    cfg = FCRBMConfig(
        visible=D, order=N, hidden=H, factors=7, factors_past_visible=8,
        factors_past_hidden=9, gibbs=4, init_std=0.3, seed=1, context_features=request.param,
    )  # fmt: skip
    m = FCRBM(cfg).double()
    with torch.no_grad():
        m.vis_bias.normal_(0, 0.5, generator=torch.Generator().manual_seed(2))
        m.hid_bias.normal_(0, 0.5, generator=torch.Generator().manual_seed(3))
    return m


@pytest.fixture
def batch() -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    v = torch.randn(B, D, generator=g, dtype=torch.float64)
    past = torch.randn(B, N, D, generator=g, dtype=torch.float64)
    context = 1 + 2 * torch.rand(B, C, generator=g, dtype=torch.float64)
    return v, past, context


def test_shapes_of_every_method(model: FCRBM, batch) -> None:
    v, past, z = batch
    a_hat, b_hat = model.dynamic_biases(past, z)
    assert a_hat.shape == (B, D) and b_hat.shape == (B, H)
    assert model.hidden_probabilities(v, past, z).shape == (B, H)
    assert model.visible_mean(torch.ones(B, H, dtype=v.dtype), past, z).shape == (B, D)
    assert model.free_energy(v, past, z).shape == (B,)
    grads, err = model.cd_gradients(v, past, z, generator=torch.Generator().manual_seed(0))
    assert {k: g.shape for k, g in grads.items()} == {
        k: p.shape for k, p in model.named_parameters()
    }
    assert err > 0
    assert model.generate(past, z, steps=7).shape == (B, 7, D)
    assert model.generate(past, z.expand(9, B, C)).shape == (B, 9, D)


def test_hidden_probabilities_in_open_unit_interval(model: FCRBM, batch) -> None:
    v, past, z = batch
    prob = model.hidden_probabilities(3 * v, past, z)
    assert torch.all(prob > 0) and torch.all(prob < 1)
    assert prob.std() > 0.05  # not all saturated the same way


def test_zero_factor_weights_give_static_gaussian_binary_rbm(model: FCRBM, batch) -> None:
    v, past, z = batch
    with torch.no_grad():
        for name in ("w_vis", "w_hid", "w_ctx", "a_past", "a_vis", "a_ctx",
                     "b_past", "b_hid", "b_ctx"):  # fmt: skip
            getattr(model, name).zero_()
    h = torch.bernoulli(torch.full((B, H), 0.5, dtype=v.dtype))
    torch.testing.assert_close(model.visible_mean(h, past, z), model.vis_bias.expand(B, D))
    torch.testing.assert_close(
        model.hidden_probabilities(v, past, z), torch.sigmoid(model.hid_bias).expand(B, H)
    )


def test_zero_interaction_factors_leave_rbm_with_dynamic_biases(model: FCRBM, batch) -> None:
    """Without the visible-hidden term, the conditional mean is the dynamic bias alone.

    The hand computation builds the full (unfactored) three-way tensors and contracts them.
    """
    v, past, z = batch
    with torch.no_grad():
        model.w_vis.zero_()
    p = past.reshape(B, N * D)
    tensor_a = torch.einsum("kf,if,lf->kil", model.a_past, model.a_vis, model.a_ctx)
    tensor_b = torch.einsum("kf,jf,lf->kjl", model.b_past, model.b_hid, model.b_ctx)
    phi = model.features(z)
    a_hat = model.vis_bias + torch.einsum("bk,kil,bl->bi", p, tensor_a, phi)
    b_hat = model.hid_bias + torch.einsum("bk,kjl,bl->bj", p, tensor_b, phi)
    h = torch.bernoulli(torch.full((B, H), 0.5, dtype=v.dtype))
    mean = model.visible_mean(h, past, z).detach()
    torch.testing.assert_close(mean, a_hat)
    torch.testing.assert_close(model.hidden_probabilities(v, past, z), torch.sigmoid(b_hat))
    assert not torch.allclose(mean, model.vis_bias.expand(B, D))  # the past matters


def test_fixed_context_reduces_to_crbm(model: FCRBM, batch) -> None:
    """At one context the FCRBM is a conditional RBM with weights ``Wv diag(φ(z) Wz) Whᵀ``."""
    v, past, _ = batch
    z = torch.tensor([[1.5, 2.5]], dtype=v.dtype).expand(B, C)
    w = model.w_vis @ torch.diag(model.features(z[0]) @ model.w_ctx) @ model.w_hid.T
    a_hat, b_hat = model.dynamic_biases(past, z)
    h = torch.bernoulli(torch.full((B, H), 0.5, dtype=v.dtype))
    torch.testing.assert_close(model.visible_mean(h, past, z), a_hat + h @ w.T)
    torch.testing.assert_close(model.hidden_probabilities(v, past, z), torch.sigmoid(b_hat + v @ w))


def test_free_energy_gradient_matches_conditionals(model: FCRBM, batch) -> None:
    """``∂F/∂v = v − E[v | p(h | v)]`` for Gaussian-binary units with unit variance."""
    v, past, z = batch
    v = v.clone().requires_grad_(True)
    (grad,) = torch.autograd.grad(model.free_energy(v, past, z).sum(), v)
    expected = v - model.visible_mean(model.hidden_probabilities(v, past, z), past, z)
    torch.testing.assert_close(grad, expected.detach())


def test_train_step_is_momentum_sgd_with_weight_decay_on_weights(model: FCRBM, batch) -> None:
    v, past, z = batch
    cfg = model.config
    grads, _ = model.cd_gradients(v, past, z, generator=torch.Generator().manual_seed(5))
    before = {k: p.detach().clone() for k, p in model.named_parameters()}
    model.train_step(v, past, z, generator=torch.Generator().manual_seed(5))
    for name, p in model.named_parameters():
        decay = 0.0 if name.endswith("bias") else cfg.weight_decay
        expected = before[name] - cfg.learning_rate * (grads[name] + decay * before[name])
        torch.testing.assert_close(p.detach(), expected)
    grads2, _ = model.cd_gradients(v, past, z, generator=torch.Generator().manual_seed(6))
    after = {k: p.detach().clone() for k, p in model.named_parameters()}
    model.train_step(v, past, z, generator=torch.Generator().manual_seed(6))
    name = "w_hid"
    step1 = after[name] - before[name]
    expected = (
        after[name]
        + cfg.momentum * step1
        - cfg.learning_rate * (grads2[name] + cfg.weight_decay * after[name])
    )
    torch.testing.assert_close(model.w_hid.detach(), expected)


def test_generation_is_reproducible_and_seed_dependent(model: FCRBM, batch) -> None:
    _, past, z = batch
    a = model.generate(past, z, steps=6, generator=torch.Generator().manual_seed(4))
    b = model.generate(past, z, steps=6, generator=torch.Generator().manual_seed(4))
    c = model.generate(past, z, steps=6, generator=torch.Generator().manual_seed(5))
    torch.testing.assert_close(a, b, rtol=0, atol=0)
    torch.testing.assert_close(model.generate(past, z, steps=6), model.generate(past, z, steps=6))
    assert not torch.allclose(a, c)


def test_generation_follows_a_per_frame_context(model: FCRBM, batch) -> None:
    _, past, z = batch
    steps = 5
    ctx = z.expand(steps, B, C).clone()
    ctx[3:] += 1.0
    gen = model.generate(past, ctx, generator=torch.Generator().manual_seed(0))
    same = model.generate(past, z, steps=steps, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(gen[:, :3], same[:, :3])
    assert not torch.allclose(gen[:, 3:], same[:, 3:])


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda m, v, p, z: m.hidden_probabilities(v[:, :2], p, z),
            r"v must have shape \('B', 4\)",
        ),
        (lambda m, v, p, z: m.hidden_probabilities(v, p[:, :2], z), r"past must have shape"),
        (lambda m, v, p, z: m.visible_mean(v, p, z), r"h must have shape \('B', 6\)"),
        (lambda m, v, p, z: m.free_energy(v, p, z[:, :1]), r"context must have shape"),
        (lambda m, v, p, z: m.free_energy(v[:2], p, z), "batch size"),
        (lambda m, v, p, z: m.dynamic_biases(p, z[:3]), "batch sizes differ"),
        (lambda m, v, p, z: m.train_step(v[None], p, z), "v must have shape"),
        (lambda m, v, p, z: m.generate(p, z), "steps is required"),
        (lambda m, v, p, z: m.generate(p, z.expand(3, B, C), steps=4), "steps=4"),
        (lambda m, v, p, z: m.generate(p, z[None, :2]), "context must have shape"),
        (lambda m, v, p, z: m.generate(p, z, steps=2, gibbs=0), "gibbs"),
    ],
)
def test_bad_shapes_raise_value_error(model: FCRBM, batch, call, message: str) -> None:
    v, past, z = batch
    with pytest.raises(ValueError, match=message):
        call(model, v, past, z)


def test_linear_features_are_the_context_and_rbf_adds_a_bump_per_grid_point(model, batch):
    _, _, z = batch
    phi = model.features(z)
    torch.testing.assert_close(phi[:, :C], z)
    if model.config.context_features == "linear":
        assert phi.shape == (B, C) and model.w_ctx.shape[0] == C
        return
    torch.testing.assert_close(phi, model.features(z.clamp(1, 3)))  # the batch is inside
    assert phi.shape == (B, C + 9) and model.w_ctx.shape[0] == C + 9
    centres = RBF_CENTRES.double()
    at_centres = model.features(centres)[:, C:]
    torch.testing.assert_close(torch.diagonal(at_centres), torch.ones(9, dtype=torch.float64))
    # (1, 1) and (1, 2) are one unit apart: exp(-1 / (2 s²)).
    expected = torch.exp(torch.tensor(-0.5 / model.config.rbf_width**2, dtype=torch.float64))
    torch.testing.assert_close(at_centres[0, 1], expected)
    # Beyond the grid the features go on linearly from the edge, by its last unit step.
    def at(v: float, a: float) -> torch.Tensor:
        return model.features(torch.tensor([[v, a]], dtype=torch.float64))[0]

    torch.testing.assert_close(at(3.5, 2.0), at(3, 2) + 0.5 * (at(3, 2) - at(2, 2)))
    torch.testing.assert_close(at(0.5, 3.25),
                               at(1, 3) + 0.5 * (at(1, 3) - at(2, 3))
                               + 0.25 * (at(1, 3) - at(1, 2)))
    torch.testing.assert_close(at(3.5, 2.0)[:C], torch.tensor([3.5, 2.0], dtype=torch.float64))


def test_rbf_features_give_each_grid_point_gates_of_its_own() -> None:
    """Linear gating blends two fixed matrices (rank 2 over the 9 grid points); the bumps make
    the gates at the grid points independent, so each point can have its own weights."""
    linear = FCRBM(FCRBMConfig(visible=D, hidden=H, context_features="linear"))
    rbf = FCRBM(FCRBMConfig(visible=D, hidden=H, context_features="rbf"))
    assert torch.linalg.matrix_rank(linear.features(RBF_CENTRES)) == 2
    assert torch.linalg.matrix_rank(rbf.features(RBF_CENTRES)) == 9


@pytest.mark.parametrize(("change", "message"), [
    ({"context_features": "cubic"}, "context_features must be one of"),
    ({"context_features": "rbf", "context": 3}, "needs context = 2"),
    ({"rbf_width": 0}, "rbf_width must be > 0"),
])
def test_bad_context_features_raise(change, message) -> None:
    with pytest.raises(ValueError, match=message):
        FCRBMConfig(visible=D, **change)


def test_sliding_windows() -> None:
    frames = torch.arange(12.0).reshape(6, 2)
    context = torch.arange(6.0)[:, None].expand(6, 2)
    v, past, z = sliding_windows(frames, context, order=2)
    assert v.shape == (4, 2) and past.shape == (4, 2, 2) and z.shape == (4, 2)
    torch.testing.assert_close(past[0], frames[0:2])
    torch.testing.assert_close(v[0], frames[2])
    torch.testing.assert_close(past[-1, -1], frames[-2])
    torch.testing.assert_close(z[0], context[2])
    with pytest.raises(ValueError, match="share T"):
        sliding_windows(frames, context[:5], order=2)
    with pytest.raises(ValueError, match="more than order"):
        sliding_windows(frames, context, order=6)


def test_single_gibbs_step_is_mean_field_from_previous_frame(model: FCRBM, batch) -> None:
    """With one iteration the frame is deterministic: ``E[v | p(h | v_{t-1})]``."""
    _, past, z = batch
    out = model.generate(past, z, steps=2, gibbs=1, generator=torch.Generator().manual_seed(0))
    first = model.visible_mean(model.hidden_probabilities(past[:, -1], past, z), past, z)
    torch.testing.assert_close(out[:, 0], first.detach())
    past2 = torch.cat([past[:, 1:], first[:, None].detach()], dim=1)
    second = model.visible_mean(model.hidden_probabilities(first, past2, z), past2, z)
    torch.testing.assert_close(out[:, 1], second.detach())


def test_multiplied_out_weights_follow_a_changing_context(model: FCRBM, batch) -> None:
    """Generation multiplies the factors out once per context: a context held, changed, and
    changed back gives the frames of the factored conditionals."""
    _, past, z = batch
    ctx = torch.stack([z, z, z + 0.7, z, z * 0.5])
    out = model.generate(past, ctx, gibbs=1, generator=torch.Generator().manual_seed(0))
    window = past
    for t, zt in enumerate(ctx):
        frame = model.visible_mean(model.hidden_probabilities(window[:, -1], window, zt),
                                   window, zt).detach()
        torch.testing.assert_close(out[:, t], frame)
        window = torch.cat([window[:, 1:], frame[:, None]], dim=1)


def _companion_by_hand(model: FCRBM, z: torch.Tensor) -> torch.Tensor:
    """The AR recursion's companion matrix built from the dynamic bias itself."""
    nd = N * D
    basis = torch.eye(nd, dtype=torch.float64).reshape(nd, N, D)
    zero = model.dynamic_biases(torch.zeros(1, N, D, dtype=torch.float64), z[None])[0]
    lin = model.dynamic_biases(basis, z.expand(nd, C))[0] - zero  # (nd, D): column per input
    comp = torch.zeros(nd, nd, dtype=torch.float64)
    comp[: nd - D, D:] = torch.eye(nd - D, dtype=torch.float64)
    comp[nd - D :] = lin.T
    return comp


def test_companion_matrix_is_the_linear_part_of_the_dynamics(model: FCRBM, batch) -> None:
    _, _, context = batch
    comp = model.ar_companion(context)
    for k in range(B):
        torch.testing.assert_close(comp[k], _companion_by_hand(model, context[k]))


def test_limiting_the_radius_scales_every_eigenvalue_at_every_context(model: FCRBM, batch) -> None:
    _, _, context = batch
    with torch.no_grad():
        model.a_past.mul_(20.0)  # far beyond stability
    before = torch.linalg.eigvals(model.ar_companion(context))
    rho = model.limit_ar_radius(context, 0.9)
    assert rho == pytest.approx(float(before.abs().amax()), rel=1e-6)
    after = torch.linalg.eigvals(model.ar_companion(context))
    assert float(after.abs().amax()) == pytest.approx(0.9, rel=1e-6)
    # Every eigenvalue is multiplied by the same factor 0.9 / rho (sorted by modulus).
    ratio = after.abs().sort(-1).values / before.abs().sort(-1).values
    torch.testing.assert_close(ratio, torch.full_like(ratio, 0.9 / rho), rtol=1e-6, atol=1e-6)


def test_stable_model_is_left_alone(model: FCRBM, batch) -> None:
    _, _, context = batch
    with torch.no_grad():
        model.a_past.mul_(1e-3)
    state = {k: v.clone() for k, v in model.state_dict().items()}
    assert model.limit_ar_radius(context, 0.999) < 0.999
    for k, v in model.state_dict().items():
        torch.testing.assert_close(v, state[k])


def test_limiting_the_radius_rescales_the_momentum_with_the_weights(model: FCRBM, batch) -> None:
    v, past, context = batch
    model = FCRBM(replace(model.config, init_std=0.3))
    model.train_step(v, past, context, torch.Generator().manual_seed(0))
    before = model._velocity["a_past"].clone()
    rho = model.limit_ar_radius(context, 0.5)
    assert rho > 0.5
    ratio = model._velocity["a_past"] / before
    lags = ratio[:, 0].reshape(model.config.order, model.config.visible)
    # Every lag's momentum is scaled like its weights: by s^k, s = 0.5 / rho, k = N..1.
    expected = (0.5 / rho) ** torch.arange(model.config.order, 0, -1, dtype=torch.float32)
    torch.testing.assert_close(lags, expected[:, None].expand_as(lags), rtol=1e-4, atol=1e-6)


@pytest.fixture
def model_without_ar(model: FCRBM) -> FCRBM:
    m = FCRBM(replace(model.config, visible_autoregression=False)).double()
    with torch.no_grad():
        m.vis_bias.copy_(model.vis_bias)
        m.hid_bias.copy_(model.hid_bias)
    return m


def test_without_visible_autoregression_the_visible_bias_is_static(model_without_ar, batch):
    v, past, z = batch
    m = model_without_ar
    names = {n for n, _ in m.named_parameters()}
    assert not names & {"a_past", "a_vis", "a_ctx"}
    a_hat, b_hat = m.dynamic_biases(past, z)
    assert torch.equal(a_hat, m.vis_bias.expand(B, D))
    _, b_other = m.dynamic_biases(past + 1.0, z)
    assert not torch.allclose(b_hat, b_other)  # the past still drives the hidden units
    grads, _ = m.cd_gradients(v, past, z, generator=torch.Generator().manual_seed(0))
    assert set(grads) == names
    before = {n: p.clone() for n, p in m.named_parameters()}
    m.train_step(v, past, z, generator=torch.Generator().manual_seed(0))
    assert all(not torch.equal(p, before[n]) for n, p in m.named_parameters())
    assert float(m.ar_spectral_radius(z).max()) == 0.0
    assert m.limit_ar_radius(z, 0.5) == 0.0


def test_without_visible_autoregression_generation_is_bounded(model_without_ar, batch) -> None:
    _, past, z = batch
    m = model_without_ar
    with torch.no_grad():
        for p in m.parameters():
            p.mul_(4.0)  # far larger weights than training leaves
    out = m.generate(100.0 * past, 3.5 * torch.ones_like(z), steps=300)
    # v = a + ((h Wh) * zf) Wvᵀ with h in [0, 1]: every frame within the sum of magnitudes.
    zf = m.features(3.5 * torch.ones_like(z)) @ m.w_ctx
    bound = ((m.w_hid.abs().sum(0) * zf.abs()) @ m.w_vis.abs().T)
    assert torch.all((out - m.vis_bias).abs() <= bound[:, None] + 1e-9)
