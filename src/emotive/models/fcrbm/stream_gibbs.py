"""One Gibbs-sampled FCRBM frame for many agents at once, agents grouped by context.

The sampling is :meth:`FCRBM.generate <emotive.models.fcrbm.model.FCRBM.generate>`'s, one
frame at a time: each agent's chain starts from its previous frame and runs ``gibbs``
alternating iterations (sampled binary hidden units, mean-field visible units), the last
hidden step mean-field, so the output frame carries no sampling noise.

What differs is how the visible-hidden weights ``W_v diag(z W_z) W_h^T`` of each context are
held. ``generate`` multiplies them out per agent at every new context
(:meth:`~emotive.models.fcrbm.model.FCRBM.context_weights`, ``D F H`` products each) and then
takes one batched vector-matrix product per agent and half-step, which reads every agent's own
``(D, H)`` matrix (0.22 MB at 55 visible and 1000 hidden units) from memory each time. A live
stream steps agents frame by frame, and many of them share a context (one per label the user
picked), so:

* :class:`ContextWeights` keeps the weights of each distinct context while an agent uses it,
  and builds new ones from a basis: the weights are linear in the gating features ``g``, so
  with ``W_k`` the weights at the ``k``-th unit feature vector (``context_weights`` of the
  identity, once), the weights at ``g`` are ``sum_k g_k W_k``: ``G D H`` products per context
  instead of ``D F H`` (11 instead of 600 per entry for the committed model).
* :func:`gibbs_frame` sorts the agents by context, multiplies each group that shares a context
  by its one matrix (a dense matrix product), and the agents alone at their context by their
  own matrices in one batched product, as ``generate`` does (their matrices stacked once and
  kept while they stay the same).

The hidden samples are ``u < p`` for uniforms ``u`` passed in (the same distribution as
``torch.bernoulli(p)``), so that the caller can draw each agent's noise from its own generator
and an agent's motion does not depend on which other agents share its batch.

Legend: ``B`` agents, ``N`` order (past frames), ``D`` visible units, ``H`` hidden units,
``S`` Gibbs iterations.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from emotive.models.fcrbm.model import FCRBM

#: A run of agents in batch order: ``(lo, hi, up, down)``, the weights ``(D, H)`` and
#: ``(H, D)`` of one shared context or ``(n, D, H)`` and ``(n, H, D)`` of lone agents.
Span = tuple[int, int, Tensor, Tensor]


class ContextWeights:
    """The visible-hidden weights of the contexts in use, computed once per context.

    Args:
        network: the trained network.
    """

    @torch.no_grad()
    def __init__(self, network: FCRBM) -> None:
        self.network = network
        ref = network.vis_bias
        width = network.features(torch.zeros(1, network.config.context, dtype=ref.dtype,
                                             device=ref.device)).shape[-1]
        # (G, D * H): row k holds the weights at the k-th unit gating feature vector.
        self._basis = network.context_weights(
            torch.eye(width, dtype=ref.dtype, device=ref.device)).reshape(width, -1)
        self._cache: dict[tuple[float, ...], tuple[Tensor, Tensor]] = {}
        empty = torch.zeros(0)
        self._lone: tuple[tuple[tuple[float, ...], ...], Tensor, Tensor] = ((), empty, empty)

    def __len__(self) -> int:
        return len(self._cache)

    @torch.no_grad()
    def weights(self, context: Tensor) -> Tensor:
        """``(B, D, H)`` visible-hidden weights at ``(B, C)`` contexts (the model's scale).

        Equal to :meth:`~emotive.models.fcrbm.model.FCRBM.context_weights` of their gating
        features, up to rounding.
        """
        c = self.network.config
        return (self.network.features(context) @ self._basis).reshape(-1, c.visible, c.hidden)

    @torch.no_grad()
    def plan(self, context: np.ndarray) -> tuple[np.ndarray, list[Span]]:
        """The agents sorted by context, and the weights of each run of them.

        Weights of contexts not seen before are computed in one batch; those of contexts no
        agent has any more are dropped, so the cache never outgrows the batch. Agents sharing
        a context come first, one run per context with its ``(D, H)`` and ``(H, D)`` weights;
        the agents alone at their context follow as one run with their weights stacked,
        ``(n, D, H)`` and ``(n, H, D)`` (kept while those agents and contexts stay the same).

        Args:
            context: ``(B, C)`` context of every agent (the model's scale).

        Returns:
            The ``(B,)`` batch order and ``(lo, hi, up, down)`` per run (positions in that
            order).
        """
        members: dict[tuple[float, ...], list[int]] = {}
        for k, row in enumerate(np.asarray(context, dtype=np.float64).tolist()):
            members.setdefault(tuple(row), []).append(k)
        missing = [key for key in members if key not in self._cache]
        if missing:
            ref = self.network.vis_bias
            up = self.weights(torch.tensor(missing, dtype=ref.dtype, device=ref.device))
            for key, weights in zip(missing, up, strict=True):
                self._cache[key] = (weights, weights.T.contiguous())
        self._cache = {key: self._cache[key] for key in members}
        shared = [key for key, rows in members.items() if len(rows) > 1]
        lone = tuple(key for key, rows in members.items() if len(rows) == 1)
        order = np.concatenate([members[key] for key in (*shared, *lone)])
        spans, lo = [], 0
        for key in shared:
            spans.append((lo, lo + len(members[key]), *self._cache[key]))
            lo += len(members[key])
        if lone:
            if self._lone[0] != lone:
                self._lone = (lone, torch.stack([self._cache[key][0] for key in lone]),
                              torch.stack([self._cache[key][1] for key in lone]))
            spans.append((lo, len(order), self._lone[1], self._lone[2]))
        return order, spans


def _times(x: Tensor, spans: list[Span], which: int) -> Tensor:
    """``(B, out)`` rows of ``x`` ``(B, in)`` times their group's ``up`` (0) or ``down`` (1)."""
    parts = []
    for lo, hi, *weights in spans:
        w = weights[which]
        parts.append(x[lo:hi] @ w if w.ndim == 2 else torch.bmm(x[lo:hi, None], w)[:, 0])
    return torch.cat(parts)


@torch.no_grad()
def gibbs_frame(network: FCRBM, weights: ContextWeights, window: Tensor, context: np.ndarray,
                uniforms: Tensor) -> Tensor:
    """The next frame of every agent.

    Args:
        network: the trained network.
        weights: the cache of its context weights (kept between frames).
        window: ``(B, N, D)`` each agent's past frames in time order.
        context: ``(B, C)`` each agent's context for the new frame (the model's scale).
        uniforms: ``(S - 1, B, H)`` uniform noise in ``[0, 1)`` of the sampled hidden steps.

    Returns:
        ``(B, D)`` the new standardized frames.
    """
    z = torch.as_tensor(np.asarray(context), dtype=window.dtype, device=window.device)
    a_hat, b_hat = network.dynamic_biases(window, z)
    order, spans = weights.plan(context)
    index = torch.as_tensor(order)
    a_hat, b_hat, v = a_hat[index], b_hat[index], window[index, -1]
    noise = uniforms[:, index]
    steps = noise.shape[0] + 1
    for it in range(steps):
        prob = torch.sigmoid(b_hat + _times(v, spans, 0))
        h = prob if it == steps - 1 else (noise[it] < prob).to(prob.dtype)
        v = a_hat + _times(h, spans, 1)
    out = torch.empty_like(v)
    out[index] = v
    return out
