"""Local Grid Bootstrap (Monbet & Marteau; paper section 5.2) of one closed observed sequence.

The observed sequence ``x`` is treated as closed (frame ``N - 1`` is followed by frame 0), so
every observation has an image one step ahead and a generated chain can run for any length.
The state of order ``p`` at frame ``i`` is ``Y_i = (x_i, x_{i-1}, ..., x_{i-p+1})``.

One step from the generated state ``Y``:

1. **Neighbourhood.** The observed states within radius ``r`` of ``Y``. The radius follows
   the paper's rule of keeping between ``k_min = 50`` and ``k_max = 100`` observed states:
   ``r = clip(r0, d_kmin(Y), d_kmax(Y))``, where ``d_k(Y)`` is the distance from ``Y`` to its
   ``k``-th nearest observed state and ``r0`` is the median, over the observed states, of the
   distance to their ``(k_min + k_max) / 2``-th nearest neighbour. Where the data has typical
   density the neighbourhood is a fixed sphere; in sparse or dense places it stretches or
   shrinks so that it keeps 50 to 100 states.
2. **Image.** The observations one step ahead of those states, ``x_{i+1}``.
3. **Hyper-grid.** Centred on the barycentre of the images, spanning their extent along each
   dimension (half-width: the largest deviation from the barycentre), 3 subdivisions per
   dimension (``3^D`` cells, of which only the occupied ones can be drawn).
4. **Probabilities.** A Gaussian local density kernel on the states:
   ``w_i = exp(-|Y_i - Y|^2 / (2 h^2))`` with ``h = sigma / 3`` and ``sigma = 2 r`` the
   neighbourhood's diameter (the paper's ``h = sigma / 3`` for a 3-subdivision grid). A cell's
   probability is the sum of the weights of the neighbours whose image falls in it, normalized:
   cells many nearby observed trajectories go through are likely.
5. **Next observation.** A cell is drawn, and the barycentre of the images in it is the next
   observation ``x_hat``; the state shifts to ``(x_hat, x_{t}, ..., x_{t-p+2})``.

With ``carry > 0`` (an extension, off by default), the next observation keeps a part of the
current state's offset from the drawn cell:
``x_hat = mean(images) + carry * (x_t - mean(their predecessors))``. The plain barycentre pulls
every step to the middle of the data; where an observed sequence holds a long still stretch
(standing while waving) the chain falls into its middle and, the stretch's exit transitions
lying on its rim, never leaves. ``carry = 1`` follows the cell's mean step instead, which
keeps the chain moving through such stretches.

Drawing a neighbour with probability proportional to ``w_i`` and taking its image's cell draws
the cell with exactly those probabilities; the drawn neighbour's image is also the observation
reported for the step (callers take the root motion from it).

Distances are computed on standardized dimensions (each scaled by its observed standard
deviation) so that a process mixing positions and velocities weighs them alike.

Legend: ``N`` observations, ``D`` dimensions of an observation, ``p`` order, ``E`` passenger
dimensions, ``n`` generated steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from emotive.errors import EmotiveError

#: The paper keeps between 50 and 100 observed states in a neighbourhood.
K_MIN = 50
K_MAX = 100
#: Subdivisions of the hyper-grid along each dimension.
SUBDIVISIONS = 3


class LGBError(EmotiveError):
    """Input the Local Grid Bootstrap cannot use: NaN, wrong shapes, bad parameters."""


class TooLittleDataError(LGBError):
    """Too few observations to keep the neighbourhood the bootstrap needs.

    Args:
        what: what lacks data (e.g. ``"emotion sad"``).
        have: observations (frames) available.
        need: observations (frames) needed.
        why: the reason for the minimum.
    """

    def __init__(self, what: str, have: int, need: int, why: str) -> None:
        self.have = have
        self.need = need
        super().__init__(f"{what} has {have} frames but at least {need} are needed ({why})")


class LGBSample(NamedTuple):
    """What :meth:`LocalGridBootstrap.sample` returns.

    Attributes:
        states: ``(n, D)`` generated observations.
        index: ``(n,)`` index of the observation drawn at each step (the image of the drawn
            neighbour; it lies in the drawn cell).
        passengers: ``(n, E)`` barycentre of the passengers of the drawn cell's observations,
            or None when the bootstrap was fitted without passengers.
    """

    states: np.ndarray
    index: np.ndarray
    passengers: np.ndarray | None


def check_finite(name: str, values: np.ndarray) -> None:
    """Raise :class:`LGBError` naming the frames of ``values`` (``(N, ...)``) holding NaN/inf."""
    bad = ~np.isfinite(values.reshape(len(values), -1)).all(1)
    if bad.any():
        frames = np.flatnonzero(bad)
        shown = ", ".join(map(str, frames[:5])) + (" ..." if len(frames) > 5 else "")
        raise LGBError(f"{name}: NaN or infinite values at {len(frames)} frames ({shown}); "
                       "remove or repair those frames")


def min_observations(order: int, k_max: int = K_MAX) -> int:
    """Fewest observations :meth:`LocalGridBootstrap.fit` accepts: twice the largest
    neighbourhood (so that a neighbourhood stays local) plus the order."""
    return 2 * k_max + order


@dataclass(eq=False)
class LocalGridBootstrap:
    """Local Grid Bootstrap of one process (see the module docstring for the procedure).

    Args:
        order: ``p``, observations per state.
        k_min: fewest observed states in a neighbourhood.
        k_max: most observed states in a neighbourhood.
        bandwidth: kernel bandwidth ``h`` as a fraction of the neighbourhood's diameter
            (the paper's ``1 / 3``).
        carry: fraction of the current offset from the drawn cell kept (0: the paper's
            barycentre; see the module docstring).
    """

    order: int = 1
    k_min: int = K_MIN
    k_max: int = K_MAX
    bandwidth: float = 1.0 / SUBDIVISIONS
    carry: float = 0.0

    def __post_init__(self) -> None:
        if (self.order < 1 or not 1 <= self.k_min <= self.k_max or self.bandwidth <= 0
                or not 0.0 <= self.carry <= 1.0):
            raise LGBError(f"need order >= 1, 1 <= k_min <= k_max, bandwidth > 0 and carry in "
                           f"[0, 1], got order={self.order}, k_min={self.k_min}, "
                           f"k_max={self.k_max}, bandwidth={self.bandwidth}, carry={self.carry}")
        self._tree = None

    def fit(
        self, observed: np.ndarray, passengers: np.ndarray | None = None, name: str = "process"
    ) -> LocalGridBootstrap:
        """Index the states of a closed observed sequence.

        Args:
            observed: ``(N, D)`` observations, the last followed by the first.
            passengers: ``(N, E)`` values carried along (averaged over the drawn cell like the
                states, but not part of them), or None.
            name: what the sequence is, for error messages.

        Returns:
            ``self``.

        Raises:
            LGBError: wrong shapes or NaN/infinite values.
            TooLittleDataError: fewer than :func:`min_observations` observations.
        """
        from scipy.spatial import cKDTree

        x = np.asarray(observed, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] < 1:
            raise LGBError(f"{name}: observations must have shape (N, D), got {x.shape}")
        check_finite(name, x)
        need = min_observations(self.order, self.k_max)
        if len(x) < need:
            raise TooLittleDataError(
                name, len(x), need,
                f"twice the {self.k_max} states of the largest neighbourhood plus the order "
                f"{self.order}",
            )
        if passengers is not None:
            passengers = np.asarray(passengers, dtype=np.float64).reshape(len(x), -1)
            check_finite(f"{name} passengers", passengers)
        scale = x.std(0)
        # A constant dimension carries no information on where the process is.
        scale[scale < 1e-12] = 1.0
        self.mean_, self.scale_ = x.mean(0), scale
        self.observed_ = x
        self.passengers_ = passengers
        z = (x - self.mean_) / scale
        self.z_ = z
        n, p = len(x), self.order
        lagged = (np.arange(n)[:, None] - np.arange(p)[None, :]) % n
        self.states_ = z[lagged].reshape(n, -1)
        self.image_ = (np.arange(n) + 1) % n
        self._tree = cKDTree(self.states_)
        mid = (self.k_min + self.k_max) // 2
        dist, _ = self._tree.query(self.states_, k=[mid + 1])
        # The +1 skips each state itself.
        self.base_radius_ = float(np.median(dist))
        return self

    @property
    def dim(self) -> int:
        """``D``, dimensions of an observation."""
        return self.observed_.shape[1]

    def neighbourhood(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Observed states around a standardized state.

        Args:
            state: ``(p * D,)`` standardized state.

        Returns:
            ``(idx, dist, radius)``: indices and distances of the ``k_min`` to ``k_max``
            observed states within the radius, and the radius.
        """
        dist, idx = self._tree.query(state, k=self.k_max)
        radius = float(np.clip(self.base_radius_, dist[self.k_min - 1], dist[-1]))
        keep = dist <= radius
        return idx[keep], dist[keep], radius

    def _cells(self, images: np.ndarray) -> np.ndarray:
        """``(K,)`` cell id of each of ``(K, D)`` images on the grid around their barycentre."""
        centre = images.mean(0)
        half = np.abs(images - centre).max(0)
        width = np.where(half > 0, 2.0 * half / SUBDIVISIONS, 1.0)
        bins = np.clip(((images - centre + half) / width).astype(np.int64), 0, SUBDIVISIONS - 1)
        return bins @ (SUBDIVISIONS ** np.arange(images.shape[1], dtype=np.int64))

    def sample(
        self, n: int, rng: np.random.Generator, start: int | None = None
    ) -> LGBSample:
        """Generate ``n`` observations.

        Args:
            n: number of steps, independent of ``N``.
            rng: the only source of randomness (same seed, same sequence).
            start: observed state the chain starts from; drawn with ``rng`` if None.

        Returns:
            The generated observations, drawn indices and passengers.

        Raises:
            LGBError: not fitted, or ``n < 0``.
        """
        if self._tree is None:
            raise LGBError("fit the bootstrap before sampling")
        if n < 0:
            raise LGBError(f"the number of steps must be >= 0, got {n}")
        z, p, d = self.z_, self.order, self.dim
        num = len(z)
        i0 = int(rng.integers(num)) if start is None else int(start) % num
        state = self.states_[i0].copy()
        out = np.empty((n, d))
        index = np.empty(n, dtype=np.int64)
        extra = None if self.passengers_ is None else np.empty((n, self.passengers_.shape[1]))
        uniforms = rng.random(n)
        for t in range(n):
            idx, dist, radius = self.neighbourhood(state)
            h = 2.0 * radius * self.bandwidth
            weights = np.exp(-0.5 * (dist / h) ** 2) if h > 0 else np.ones(len(idx))
            cum = np.cumsum(weights)
            pick = min(int(np.searchsorted(cum, uniforms[t] * cum[-1], side="right")),
                       len(idx) - 1)
            img = self.image_[idx]
            cells = self._cells(z[img])
            members = img[cells == cells[pick]]
            nxt = z[members].mean(0)
            if self.carry:
                nxt += self.carry * (state[:d] - z[members - 1].mean(0))
            out[t] = nxt
            index[t] = img[pick]
            if extra is not None:
                extra[t] = self.passengers_[members].mean(0)
            # Shift the state: the new observation first, the oldest dropped.
            state[d:] = state[: (p - 1) * d]
            state[:d] = nxt
        return LGBSample(out * self.scale_ + self.mean_, index, extra)
