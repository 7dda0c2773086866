"""Factored Conditional Restricted Boltzmann Machine (Taylor and Hinton 2009).

The model of Alemi, Li and Pasquier (2015), "Affect-expressive movement generation with
factored conditional restricted Boltzmann machines": Gaussian visible units ``v_t`` (one frame
of standardized motion, unit variance), binary hidden units ``h_t``, the past ``N`` frames
``v_<t`` and a real-valued context ``z_t`` (valence and arousal, paper values 1..3; never 0,
because every interaction is multiplicative in ``z``). Three factored three-way interactions,
each gated by the context:

* visible-hidden-context (``w_vis``, ``w_hid``, ``w_ctx``), the undirected term of the energy;
* past-to-visible (``a_past``, ``a_vis``, ``a_ctx``), the dynamic visible bias ``â``;
* past-to-hidden (``b_past``, ``b_hid``, ``b_ctx``), the dynamic hidden bias ``b̂``.

Energy (paper equation 1)::

    E(v, h | v_<t, z) = ½ Σ_i (v_i − â_i)² − Σ_f (v·Wv)_f (h·Wh)_f (z·Wz)_f − Σ_j b̂_j h_j
    â = a + ((p·Ap) ⊙ (z·Az))·Avᵀ        b̂ = b + ((p·Bp) ⊙ (z·Bz))·Bhᵀ

with ``p`` the flattened past. Training is contrastive divergence (CD-k): the gradient is that
of the free-energy difference ``F(v_data) − F(v_k)`` with the negative sample held fixed, taken
by autograd (it is the exact CD estimator: the free energy marginalises the hidden units), then
applied by hand as momentum SGD with L2 weight decay on the weights (not on the biases), as in
Taylor's code. Generation runs alternating Gibbs sampling per frame: sampled binary hidden
units, mean-field (noise-free) visible units, and hidden probabilities in the last step.

**Deviation (optional): no past-to-visible term.** With ``visible_autoregression=False`` the
past-to-visible factors are left out: ``â = a``, the hidden units carry all the dynamics, and
a generated frame is the static bias plus a weighted sum of hidden units in ``[0, 1]``, so it
is bounded by construction whatever the context. With the term, the linear part's gain is
proportional to the context (``A(z)`` has no context-free part) and on the Bandai Namco walks
its spectral radius grew past 1 at the higher valence/arousal values (1.1 at (2, 2), 1.8 at
(3, 3)): every sequence diverged there, and scaling it back below 1 damped the gait to a still
pose.

**Deviation (optional): radial context features.** In the paper every factor's gate is linear
in the context, ``z·Wz``, so the weights at any valence/arousal are a blend of ``C = 2`` fixed
matrices, and styles at different points can only differ by how much of each they get. With
``context_features="rbf"`` the gates see ``φ(z)``: the context followed by a Gaussian bump per
point of the paper's 1-3 grid (:meth:`FCRBM.features`), so each region of the plane can have
weights of its own; between grid points the bumps blend, and beyond the grid the features
extrapolate linearly from the edge.

Legend: ``B`` batch, ``T`` frames, ``N`` order (past frames), ``D`` visible units, ``H`` hidden
units, ``F`` factors, ``C`` context size, ``G`` gating features (:func:`context_width`). A
past window ``(B, N, D)`` is in time order: index ``-1`` is the frame just before the current
one.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import Tensor, nn

from emotive.models.fcrbm.config import FCRBMConfig

__all__ = ["FCRBM", "sliding_windows"]


#: ``(K, 2)`` centres of the ``"rbf"`` features: the paper's valence/arousal grid, 1-3 by 1.
RBF_CENTRES = torch.tensor([[v, a] for v in (1.0, 2.0, 3.0) for a in (1.0, 2.0, 3.0)])


def _grid_features(context: Tensor, width: float) -> Tensor:
    """``(..., C + K)``: the context and its Gaussian bump around each of :data:`RBF_CENTRES`."""
    centres = RBF_CENTRES.to(dtype=context.dtype, device=context.device)
    dist2 = ((context[..., None, :] - centres) ** 2).sum(-1)
    return torch.cat([context, torch.exp(-dist2 / (2 * width**2))], dim=-1)


def context_width(config: FCRBMConfig) -> int:
    """Rows of the context factor matrices: ``C``, or ``C + K`` with ``"rbf"`` features."""
    return config.context + (len(RBF_CENTRES) if config.context_features == "rbf" else 0)


_AUTOREGRESSIVE = ("a_past", "a_vis", "a_ctx")
_WEIGHTS = ("w_vis", "w_hid", "w_ctx", *_AUTOREGRESSIVE, "b_past", "b_hid", "b_ctx")
_BIASES = ("vis_bias", "hid_bias")


class FCRBM(nn.Module):
    """Factored Conditional RBM with Gaussian visible and binary hidden units.

    Args:
        config: sizes and training settings.

    Attributes:
        vis_bias: ``(D,)`` static visible bias ``a``.
        hid_bias: ``(H,)`` static hidden bias ``b``.
        w_vis, w_hid, w_ctx: ``(D, F)``, ``(H, F)``, ``(G, F)``, visible-hidden-context factors.
        a_past, a_vis, a_ctx: ``(N*D, Fa)``, ``(D, Fa)``, ``(G, Fa)``, past-to-visible factors
            (absent without ``config.visible_autoregression``).
        b_past, b_hid, b_ctx: ``(N*D, Fb)``, ``(H, Fb)``, ``(G, Fb)``, past-to-hidden factors.

    ``G`` is :func:`context_width`: ``C``, or ``C + K`` with ``"rbf"`` context features.
    """

    def __init__(self, config: FCRBMConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        gen = torch.Generator().manual_seed(c.seed)
        past = c.order * c.visible
        width = context_width(c)
        shapes = {
            "w_vis": (c.visible, c.factors),
            "w_hid": (c.hidden, c.factors),
            "w_ctx": (width, c.factors),
            "a_past": (past, c.factors_past_visible),
            "a_vis": (c.visible, c.factors_past_visible),
            "a_ctx": (width, c.factors_past_visible),
            "b_past": (past, c.factors_past_hidden),
            "b_hid": (c.hidden, c.factors_past_hidden),
            "b_ctx": (width, c.factors_past_hidden),
        }
        self.weight_names = tuple(
            n for n in _WEIGHTS if c.visible_autoregression or n not in _AUTOREGRESSIVE
        )
        for name, shape in shapes.items():
            if name not in self.weight_names:
                continue
            self.register_parameter(
                name, nn.Parameter(torch.randn(shape, generator=gen) * c.init_std)
            )
        self.vis_bias = nn.Parameter(torch.zeros(c.visible))
        self.hid_bias = nn.Parameter(torch.zeros(c.hidden))
        self._velocity: dict[str, Tensor] = {}

    # ------------------------------------------------------------------ checks and conversion

    def _tensor(self, x: Any, name: str, shape: tuple[int | None, ...]) -> Tensor:
        """``x`` as a tensor of the model's dtype and device, checked against ``shape``."""
        ref = self.vis_bias
        t = torch.as_tensor(x, dtype=ref.dtype, device=ref.device)
        expected = tuple("B" if s is None else s for s in shape)
        if t.ndim != len(shape) or any(
            s is not None and t.shape[i] != s for i, s in enumerate(shape)
        ):
            raise ValueError(f"{name} must have shape {expected}, got {tuple(t.shape)}")
        return t

    def _inputs(self, past: Any, context: Any) -> tuple[Tensor, Tensor]:
        c = self.config
        p = self._tensor(past, "past", (None, c.order, c.visible))
        z = self._tensor(context, "context", (None, c.context))
        if p.shape[0] != z.shape[0]:
            raise ValueError(f"past and context batch sizes differ: {p.shape[0]} != {z.shape[0]}")
        return p, self.features(z)

    def features(self, context: Tensor) -> Tensor:
        """``(..., G)`` gating features of a ``(..., C)`` context.

        ``"linear"``: the context itself, so every factor's gate is linear in it (the paper's
        model; the weights at any context are a blend of ``C`` fixed matrices). ``"rbf"``: the
        context followed by ``exp(-|z - c_k|² / (2 w²))`` for each centre ``c_k`` of
        :data:`RBF_CENTRES` (``w`` = ``config.rbf_width``), so each valence/arousal region can
        have weights of its own. Beyond the grid (1-3) the features go on linearly from the
        edge, along each axis by the edge's last unit step: ``φ(z) = φ(ẑ) + Σ_d |z_d - ẑ_d|
        (φ(ẑ) - φ(ẑ - s_d e_d))`` with ``ẑ`` the context clamped to the grid and ``s_d`` the
        side it left by. The gates are linear in ``φ``, so at arousal 3.5 the weights are
        those at 3 plus half their change from 2 to 3: exaggeration by extrapolating the
        difference, as the paper's linear gates do everywhere.
        """
        if self.config.context_features == "linear":
            return context
        low, high = float(RBF_CENTRES.min()), float(RBF_CENTRES.max())
        inside = context.clamp(low, high)
        width = self.config.rbf_width
        edge = _grid_features(inside, width)
        beyond = context - inside
        phi = edge
        for axis in range(context.shape[-1]):
            outward = torch.sign(beyond[..., axis])
            back = inside.clone()
            back[..., axis] -= outward
            step = edge - _grid_features(back, width)
            phi = phi + (beyond[..., axis] * outward)[..., None] * step
        return phi

    def _check_batch(self, x: Tensor, name: str, batch: int) -> None:
        if x.shape[0] != batch:
            raise ValueError(f"{name} batch size {x.shape[0]} != past batch size {batch}")

    # ------------------------------------------------------------------ conditionals

    def dynamic_biases(self, past: Any, context: Any) -> tuple[Tensor, Tensor]:
        """Visible and hidden biases given the past frames and the context.

        Args:
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frame.

        Returns:
            ``â`` of shape ``(B, D)`` and ``b̂`` of shape ``(B, H)``.
        """
        p, z = self._inputs(past, context)
        return self._biases(p.reshape(p.shape[0], -1), z)

    def _biases(self, p: Tensor, z: Tensor) -> tuple[Tensor, Tensor]:
        if self.config.visible_autoregression:
            a_hat = self.vis_bias + ((p @ self.a_past) * (z @ self.a_ctx)) @ self.a_vis.T
        else:
            a_hat = self.vis_bias.expand(p.shape[0], -1)
        b_hat = self.hid_bias + ((p @ self.b_past) * (z @ self.b_ctx)) @ self.b_hid.T
        return a_hat, b_hat

    def _hidden_input(self, v: Tensor, zf: Tensor, b_hat: Tensor) -> Tensor:
        return b_hat + ((v @ self.w_vis) * zf) @ self.w_hid.T

    def _visible_mean(self, h: Tensor, zf: Tensor, a_hat: Tensor) -> Tensor:
        return a_hat + ((h @ self.w_hid) * zf) @ self.w_vis.T

    def hidden_probabilities(self, v: Any, past: Any, context: Any) -> Tensor:
        """``p(h_j = 1 | v, v_<t, z)``.

        Args:
            v: ``(B, D)`` current frames.
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frames.

        Returns:
            ``(B, H)`` probabilities in ``(0, 1)``.
        """
        p, z = self._inputs(past, context)
        vt = self._tensor(v, "v", (None, self.config.visible))
        self._check_batch(vt, "v", p.shape[0])
        _, b_hat = self._biases(p.reshape(p.shape[0], -1), z)
        return torch.sigmoid(self._hidden_input(vt, z @ self.w_ctx, b_hat))

    def visible_mean(self, h: Any, past: Any, context: Any) -> Tensor:
        """Mean of the unit-variance Gaussian ``p(v | h, v_<t, z)``.

        Args:
            h: ``(B, H)`` hidden states or probabilities.
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frames.

        Returns:
            ``(B, D)`` visible means.
        """
        p, z = self._inputs(past, context)
        ht = self._tensor(h, "h", (None, self.config.hidden))
        self._check_batch(ht, "h", p.shape[0])
        a_hat, _ = self._biases(p.reshape(p.shape[0], -1), z)
        return self._visible_mean(ht, z @ self.w_ctx, a_hat)

    def free_energy(self, v: Any, past: Any, context: Any) -> Tensor:
        """Free energy ``F(v | v_<t, z) = −log Σ_h exp(−E)`` up to a constant.

        Args:
            v: ``(B, D)`` current frames.
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frames.

        Returns:
            ``(B,)`` free energies.
        """
        p, z = self._inputs(past, context)
        vt = self._tensor(v, "v", (None, self.config.visible))
        self._check_batch(vt, "v", p.shape[0])
        a_hat, b_hat = self._biases(p.reshape(p.shape[0], -1), z)
        return self._free_energy(vt, z @ self.w_ctx, a_hat, b_hat)

    def _free_energy(self, v: Tensor, zf: Tensor, a_hat: Tensor, b_hat: Tensor) -> Tensor:
        quadratic = 0.5 * ((v - a_hat) ** 2).sum(-1)
        return quadratic - nn.functional.softplus(self._hidden_input(v, zf, b_hat)).sum(-1)

    # ------------------------------------------------------------------ training

    def cd_gradients(
        self,
        v: Any,
        past: Any,
        context: Any,
        generator: torch.Generator | None = None,
    ) -> tuple[dict[str, Tensor], float]:
        """CD-k estimate of the gradient of the mean negative log-likelihood.

        The chain starts from sampled hidden states of the data; the visible units are
        reconstructed mean-field (noise-free, as in Taylor's code, which lowers the variance of
        the estimate on unit-variance data); the ``k``-th reconstruction is the negative sample.

        Args:
            v: ``(B, D)`` current frames.
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frames.
            generator: random generator of the hidden samples (``None``: torch's global one).

        Returns:
            The gradient of every parameter by name (descend it), and the mean squared error of
            the first reconstruction (per value).
        """
        p, z = self._inputs(past, context)
        vt = self._tensor(v, "v", (None, self.config.visible))
        self._check_batch(vt, "v", p.shape[0])
        p = p.reshape(p.shape[0], -1)
        with torch.no_grad():
            a_hat, b_hat = self._biases(p, z)
            zf = z @ self.w_ctx
            prob = torch.sigmoid(self._hidden_input(vt, zf, b_hat))
            h = torch.bernoulli(prob, generator=generator)
            recon_error = math.nan
            for step in range(self.config.cd_steps):
                neg = self._visible_mean(h, zf, a_hat)
                if step == 0:
                    recon_error = float(((neg - vt) ** 2).mean())
                if step + 1 < self.config.cd_steps:
                    prob = torch.sigmoid(self._hidden_input(neg, zf, b_hat))
                    h = torch.bernoulli(prob, generator=generator)
        with torch.enable_grad():
            a_hat, b_hat = self._biases(p, z)
            zf = z @ self.w_ctx
            loss = (
                self._free_energy(vt, zf, a_hat, b_hat) - self._free_energy(neg, zf, a_hat, b_hat)
            ).mean()
            names = [*self.weight_names, *_BIASES]
            grads = torch.autograd.grad(loss, [getattr(self, n) for n in names])
        return dict(zip(names, grads, strict=True)), recon_error

    def train_step(
        self,
        v: Any,
        past: Any,
        context: Any,
        generator: torch.Generator | None = None,
    ) -> float:
        """One CD-k update with momentum and weight decay, applied in place.

        ``velocity = momentum · velocity − lr · (grad + weight_decay · weight)``, then
        ``param += velocity`` (no decay on the biases).

        Args:
            v: ``(B, D)`` current frames.
            past: ``(B, N, D)`` past frames in time order.
            context: ``(B, C)`` context of the current frames.
            generator: random generator of the hidden samples.

        Returns:
            The mean squared reconstruction error of the batch before the update.
        """
        c = self.config
        grads, recon_error = self.cd_gradients(v, past, context, generator)
        with torch.no_grad():
            for name, grad in grads.items():
                param = getattr(self, name)
                step = grad + c.weight_decay * param if name in self.weight_names else grad
                vel = self._velocity.get(name)
                vel = (
                    -c.learning_rate * step
                    if vel is None
                    else c.momentum * vel - (c.learning_rate * step)
                )
                self._velocity[name] = vel
                param.add_(vel)
        return recon_error

    # ------------------------------------------------------------------ stability

    @torch.no_grad()
    def ar_companion(self, context: Any) -> Tensor:
        """Companion matrices of the linear autoregressive part at given contexts.

        The dynamic visible bias is linear in the past: ``â = a + Σ_k A_k(z) v_{t-k}`` with
        ``A_k(z) = Av diag(z·Az) Ap_kᵀ`` for lag ``k = 1..N``. The companion matrix of that
        recursion has the lags' blocks in its last block row and the shift in the others.

        Args:
            context: ``(B, C)`` contexts.

        Returns:
            ``(B, N*D, N*D)`` companion matrices acting on the flattened past (time order);
            without ``config.visible_autoregression`` the lags' blocks are zero.
        """
        c = self.config
        z = self.features(self._tensor(context, "context", (None, c.context)))
        nd = c.order * c.visible
        comp = torch.zeros(z.shape[0], nd, nd, dtype=z.dtype, device=z.device)
        comp[:, : nd - c.visible, c.visible :] = torch.eye(nd - c.visible)
        if not c.visible_autoregression:
            return comp
        blocks = torch.einsum("pf,bf,df->bdp", self.a_past, z @ self.a_ctx, self.a_vis)
        comp[:, nd - c.visible :, :] = blocks
        return comp

    @torch.no_grad()
    def ar_spectral_radius(self, context: Any) -> Tensor:
        """``(B,)`` spectral radius of :meth:`ar_companion` at each context.

        Below 1, the linear part of the dynamics is stable there. Without
        ``config.visible_autoregression`` the companion is a pure shift: 0 everywhere.
        """
        if not self.config.visible_autoregression:
            z = self._tensor(context, "context", (None, self.config.context))
            return torch.zeros(z.shape[0], dtype=z.dtype, device=z.device)
        return torch.linalg.eigvals(self.ar_companion(context).double()).abs().amax(-1).float()

    @torch.no_grad()
    def limit_ar_radius(self, contexts: Any, radius: float) -> float:
        """Scale the autoregressive weights to a spectral radius of at most ``radius``.

        Scale the autoregressive weights so that their spectral radius is at most
        ``radius`` at every given context; return the largest radius before scaling.

        Multiplying lag ``k``'s weights by ``s^k`` multiplies every eigenvalue of the companion
        matrix by ``s`` exactly, at every context at once (the context gating is shared by
        all lags), so one scaling with ``s = radius / max radius`` suffices. The hidden units'
        contribution to the next frame is bounded (sigmoid outputs), so a stable linear part
        bounds the whole generated sequence.

        Args:
            contexts: ``(B, C)`` contexts that must be stable.
            radius: the bound, in ``(0, 1]``.
        """
        rho = float(self.ar_spectral_radius(contexts).max())
        if rho > radius:
            c = self.config
            lags = torch.arange(c.order, 0, -1, dtype=self.a_past.dtype, device=self.a_past.device)
            scale = (radius / rho) ** lags
            scale = scale.repeat_interleave(c.visible)[:, None]
            self.a_past.mul_(scale)
            if "a_past" in self._velocity:  # momentum lives in the same coordinates
                self._velocity["a_past"] = self._velocity["a_past"] * scale
        return rho

    # ------------------------------------------------------------------ generation

    @torch.no_grad()
    def generate(
        self,
        past: Any,
        context: Any,
        steps: int | None = None,
        gibbs: int | None = None,
        generator: torch.Generator | None = None,
    ) -> Tensor:
        """Generate frames autoregressively, the context possibly changing every frame.

        Each frame starts its chain from the previous frame, runs ``gibbs`` alternating
        iterations (sampled hidden units, mean-field visible units) and ends with a mean-field
        step (hidden probabilities), which removes the sampling noise from the output frame.
        The three-way weights are multiplied out at each new context
        (:meth:`context_weights`).

        Args:
            past: ``(B, N, D)`` seed frames in time order.
            context: ``(T, B, C)`` one context per generated frame, or ``(B, C)`` for all.
            steps: ``T``; required with a ``(B, C)`` context, else must match it.
            gibbs: Gibbs iterations per frame (default ``config.gibbs``).
            generator: random generator (default: seeded with ``config.seed``), so the same
                generator state gives the same frames.

        Returns:
            ``(B, T, D)`` generated frames.
        """
        c = self.config
        p = self._tensor(past, "past", (None, c.order, c.visible))
        batch = p.shape[0]
        z = torch.as_tensor(context, dtype=p.dtype, device=p.device)
        if z.ndim == 2:
            z = self._tensor(z, "context", (batch, c.context))
            if steps is None:
                raise ValueError("steps is required when context has shape (B, C)")
            z = z.expand(steps, batch, c.context)
        else:
            z = self._tensor(z, "context", (None, batch, c.context))
            if steps is not None and steps != z.shape[0]:
                raise ValueError(f"steps={steps} != {z.shape[0]} frames of context (T, B, C)")
        if z.shape[0] < 1:
            raise ValueError("generate needs at least one step")
        z = self.features(z)
        n_gibbs = c.gibbs if gibbs is None else gibbs
        if n_gibbs < 1:
            raise ValueError(f"gibbs must be >= 1, got {n_gibbs}")
        gen = (
            generator
            if generator is not None
            else torch.Generator(device=p.device).manual_seed(c.seed)
        )
        window = p.clone()
        out = torch.empty(batch, z.shape[0], c.visible, dtype=p.dtype, device=p.device)
        up = down = None
        for t in range(z.shape[0]):
            a_hat, b_hat = self._biases(window.reshape(batch, -1), z[t])
            if up is None or not torch.equal(z[t], z[t - 1]):
                up = self.context_weights(z[t])
                # Row vectors times both layouts: torch's batched matrix-vector product is
                # several times slower than its batched vector-matrix product.
                down = up.transpose(1, 2).contiguous()
            v = window[:, -1]
            for it in range(n_gibbs):
                prob = torch.sigmoid(b_hat + torch.bmm(v[:, None], up)[:, 0])
                h = prob if it == n_gibbs - 1 else torch.bernoulli(prob, generator=gen)
                v = a_hat + torch.bmm(h[:, None], down)[:, 0]
            out[:, t] = v
            window = torch.cat([window[:, 1:], v[:, None]], dim=1)
        return out

    def context_weights(self, context: Tensor) -> Tensor:
        """``(B, D, H)`` visible-hidden weights at a context's gating features.

        ``(B, D, H)`` visible-hidden weights at a context's gating features (``(B, G)``,
        :meth:`features`): ``W_v diag(z W_z) W_h^T``.

        Generation multiplies by these instead of through the factors: ``D H`` products per
        agent and Gibbs half-step instead of ``F (D + H)`` (11 x fewer at 55 visible, 1000
        hidden and 600 factors), paid for with ``D F H`` once per change of context and with
        memory: generation holds two copies, ``2 B D H`` floats (0.44 MB per agent at those
        sizes).

        Args:
            context: ``(B, G)`` gating features.
        """
        zf = context @ self.w_ctx
        return torch.einsum("df,bf,hf->bdh", self.w_vis, zf, self.w_hid)


def sliding_windows(frames: Any, context: Any, order: int) -> tuple[Tensor, Tensor, Tensor]:
    """Cut one sequence into training examples ``(v_t, v_<t, z_t)``.

    Args:
        frames: ``(T, D)`` standardized frames.
        context: ``(T, C)`` per-frame context.
        order: ``N`` past frames per example.

    Returns:
        ``v`` ``(T−N, D)``, ``past`` ``(T−N, N, D)`` and ``context`` ``(T−N, C)``.
    """
    x = torch.as_tensor(frames)
    z = torch.as_tensor(context, dtype=x.dtype)
    if x.ndim != 2 or z.ndim != 2 or x.shape[0] != z.shape[0]:
        raise ValueError(
            f"frames (T, D) and context (T, C) must share T, got {tuple(x.shape)} and "
            f"{tuple(z.shape)}"
        )
    if order < 1 or x.shape[0] <= order:
        raise ValueError(f"need order >= 1 and more than order={order} frames, got {x.shape[0]}")
    past = x.unfold(0, order, 1)[:-1].transpose(1, 2)
    return x[order:], past, z[order:]
