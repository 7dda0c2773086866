"""Local Grid Bootstrap (Monbet & Marteau; paper section 5.2) of one closed observed sequence.

The observed sequence ``x`` is treated as closed (frame ``N - 1`` is followed by frame 0), so
every observation has an image one step ahead and a generated chain can run for any length.
The state of order ``p`` and lag ``L`` at frame ``i`` is
``Y_i = (x_i, x_{i-L}, ..., x_{i-(p-1)L})`` (the paper's states have ``L = 1``).

The paper's step (``rule="barycentre"``), from the generated state ``Y``:

1. **Neighbourhood.** The observed states within radius ``r`` of ``Y``. The radius follows
   the paper's rule of keeping between ``k_min = 50`` and ``k_max = 100`` observed states:
   ``r = clip(r0, d_kmin(Y), d_kmax(Y))``, where ``d_k(Y)`` is the distance from ``Y`` to its
   ``k``-th nearest observed state and ``r0`` is the median, over the observed states, of the
   distance to their ``(k_min + k_max) / 2``-th nearest neighbour.
2. **Image.** The observations one step ahead of those states, ``x_{i+1}``.
3. **Hyper-grid.** Centred on the barycentre of the images, spanning their extent along each
   dimension, 3 subdivisions per dimension (``3^D`` cells, of which only the occupied ones can
   be drawn).
4. **Probabilities.** A Gaussian local density kernel on the states,
   ``w_i = exp(-|Y_i - Y|^2 / (2 h^2))`` with ``h = sigma / 3`` and ``sigma = 2 r`` the
   neighbourhood's diameter; a cell's probability is the sum of the weights of the neighbours
   whose image falls in it.
5. **Next observation.** A cell is drawn, and the barycentre of the images in it is the next
   observation; the state shifts to ``(x_hat, x_t, ...)``. (``carry > 0`` keeps a part of the
   current offset from the cell: ``x_hat += carry * (x_t - mean(predecessors))``.)

The default ``rule="successor"`` keeps steps 1, 2 and 4 and changes what is drawn and what
follows from the draw (documented deviation from the paper):

* **State.** The chain's state is the observed state ``Y_s`` of its *source* frame ``s``, the
  frame the current generated observation was drawn from.
* **Kernel.** The neighbourhood's states on the source's own passage (within ``theiler``
  frames along the closed sequence) are not candidates; any other neighbour ``j`` gets
  ``q_sj = eps * exp(-|Y_j - Y_s|^2 / (2 h^2))``, made symmetric (``q_sj = q_js``, over the
  union of the two neighbourhoods), with ``eps`` such that the most crowded state's weights
  sum to one. The bandwidth is tied to the **nearest non-consecutive neighbour**: ``h`` is
  ``kernel_scale`` (0.5) times the median, over the observed states, of the distance to the
  nearest state more than ``theiler`` frames away. The source's own continuation gets
  ``1 - sum_j q_sj``.
* **Draw.** A neighbour is drawn with these probabilities and the next observation is its
  **observed successor** ``x_{j+1}``, plus a decaying part of the current offset from it
  (:func:`carry_offsets`: ``x_hat = x_{j+1} + carry * (x_t - x_j)``); the source becomes
  ``j + 1``. Drawing the source itself continues its passage.

Drawing a hyper-grid cell by its summed weight and then a member by its weight draws each
neighbour with probability proportional to its weight, so with this rule the grid would not
change the draw: the implementation draws the neighbour directly, from candidates and
probabilities precomputed for every observed state at :meth:`LocalGridBootstrap.fit`.

Why, measured on the Bandai Namco data (``bench/eval_lgb.py``; its JSON in
``bench/results/eval_lgb.json`` holds every number for the four emotions and processes; sad has
2,701 closed frames, and 30,000 frames were generated per emotion):

* A neighbourhood of 50-100 states is mostly the same passage, about +-25 frames around the
  state. With the paper's rule the barycentre of a cell of such images is pulled to the middle
  of the passage, and order-1 position states do not tell a forward swing from the backward
  one, so the steps in a cell cancel: on sad the left arm, the lower body and the head move
  at 0.24, 0.20 and 0.33 of the observed mean speed (over the four emotions and processes
  0.18-1.46: where it comes near 1 it jitters back and forth instead of travelling; on a
  synthetic swing it reverses 15 times a second instead of 1.4, see
  ``tests/models/lgb/test_bootstrap.py``). ``carry = 1`` (following the cell's mean step)
  moves at 0.25-1.05 of the speed but integrates every error and drifts off the data: the arms
  and lower body end up 57-197 mm (median) from the nearest observation.
* Drawing a neighbour's successor from the *generated* state (with its offset) still stalls:
  in standing stretches every state is equally near, the chain re-draws its phase at every
  step and never reaches a stretch's end (sad left arm: 0.08 of the step size, 73 % of 1-s
  windows below the observed 5th percentile of path length). Hence the observed source state.
* With symmetric weights the uniform distribution over the observed frames is stationary (the
  flow ``s -> s + 1`` keeps it and every jump ``s -> j + 1`` is balanced by ``j -> s + 1``),
  so the generated steps follow the observed step distribution: over all emotions and
  processes the final motion moves at 0.98-1.08 of the observed mean speed (Kolmogorov-Smirnov
  distance of the speed distributions at most 0.10), at most 2.2 % of its 1-s stretches are
  slower than the observed 5th percentile, it stays 0.1-8.4 mm (median) from the nearest
  observation with no growth from the first to the last third of 30,000 frames (no drift),
  and its largest coordinates are the data's (no explosion). Passages last 6-19 frames
  between jumps.
* The bandwidth: with the full nearest non-consecutive distance (``kernel_scale = 1``) jumps
  come every 4-9 frames; each adds the fading offset's path to the motion, which made sad look
  faster and the classifier read 28 % of its resampled windows as angry (recognized 0.60-0.87
  over three seeds of 3,000 frames); ``0.5`` (0.72-1.00) keeps jumps to nearer passages.
* Order 1 on positions knows no direction, so a jump may reverse a swing (3.2 reversals a
  second on the synthetic swing against 1.4): the arms and lower body use order 2 with a lag of
  5 frames (see :data:`emotive.models.lgb.resampler.ORDERS`).
* ``carry = 0.9`` fades a jump's offset over about 10 frames (a third of a second); it pulls
  the path back to the data geometrically, so it cannot drift.
  :class:`~emotive.models.lgb.resampler.EmotionResampler` draws with ``carry = 0`` and applies the
  same fading itself, to the pelvis path and to joint rotations after the IK, so that blended
  positions never shorten a limb.

Distances are computed on standardized dimensions (each scaled by its observed standard
deviation) so that a process mixing positions and velocities weighs them alike.

Legend: ``N`` observations, ``D`` dimensions of an observation, ``p`` order, ``L`` lag,
``E`` passenger dimensions, ``n`` generated steps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy import sparse
from scipy.signal import lfilter
from scipy.spatial import cKDTree

from emotive.errors import EmotiveError

#: The paper keeps between 50 and 100 observed states in a neighbourhood.
K_MIN = 50
K_MAX = 100
#: Subdivisions of the hyper-grid along each dimension.
SUBDIVISIONS = 3
#: The two next-state rules (see the module docstring).
RULES = ("successor", "barycentre")
#: Successor rule: kernel bandwidth over the median nearest non-consecutive neighbour distance.
KERNEL_SCALE = 0.5


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
        index: ``(n,)`` observed frame each step was built from (successor rule: the drawn
            neighbour's successor; barycentre rule: the image of a neighbour in the drawn cell).
        passengers: ``(n, E)`` passengers built like the states (not part of the distances),
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


def min_observations(order: int, k_max: int = K_MAX, lag: int = 1) -> int:
    """Fewest observations :meth:`LocalGridBootstrap.fit` accepts.

    Twice the largest neighbourhood (so that a neighbourhood stays local) plus the frames one state
    spans.
    """
    return 2 * k_max + (order - 1) * lag + 1


def carry_offsets(
    values: np.ndarray, index: np.ndarray, carry: float, start: int
) -> np.ndarray:
    """Observed successors with a decaying part of each step's offset carried along.

    ``x_hat_t = x[i_t] + carry * (x_hat_{t-1} - x[i_t - 1])``: where the chain continues a
    passage (``i_t = i_{t-1} + 1``) the offset only decays; where it jumps, the jump's
    difference joins the offset, so the path stays continuous and fades back onto the data.

    Args:
        values: ``(N, D)`` closed observed sequence.
        index: ``(n,)`` frames drawn at each step.
        carry: fraction of the offset kept per step, in ``[0, 1]``.
        start: the frame before ``index[0]`` (where the chain started; no offset).

    Returns:
        ``(n, D)`` generated values.
    """
    num = len(values)
    prev = np.concatenate(([start], index[:-1]))
    jumps = values[prev] - values[(index - 1) % num]
    if not carry or not len(index):
        return values[index].copy()
    return values[index] + lfilter([carry], [1.0, -carry], jumps, axis=0)


def _circular_gap(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Frames between ``a`` and ``b`` along a closed sequence of ``n`` frames."""
    gap = np.abs(a - b)
    return np.minimum(gap, n - gap)


@dataclass(eq=False)
class LocalGridBootstrap:
    """Local Grid Bootstrap of one process (see the module docstring for the procedure).

    Args:
        order: ``p``, observations per state.
        lag: ``L``, frames between the observations of a state.
        k_min: fewest observed states in a neighbourhood.
        k_max: most observed states in a neighbourhood.
        bandwidth: barycentre rule: kernel bandwidth as a fraction of the neighbourhood's
            diameter (the paper's ``1 / 3``).
        rule: ``"successor"`` or ``"barycentre"`` (the paper's; see the module docstring).
        carry: fraction of the current offset from the drawn observation (successor rule) or
            from the drawn cell (barycentre rule) that the next observation keeps.
        theiler: successor rule: frames either side of a state that count as its own passage.
        kernel_scale: successor rule: kernel bandwidth as a multiple of the median nearest
            non-consecutive neighbour distance.
    """

    order: int = 1
    lag: int = 1
    k_min: int = K_MIN
    k_max: int = K_MAX
    bandwidth: float = 1.0 / SUBDIVISIONS
    rule: str = "successor"
    carry: float = 0.9
    theiler: int = 10
    kernel_scale: float = KERNEL_SCALE

    def __post_init__(self) -> None:
        if (self.order < 1 or self.lag < 1 or not 1 <= self.k_min <= self.k_max
                or self.bandwidth <= 0 or not 0.0 <= self.carry <= 1.0 or self.theiler < 0
                or self.rule not in RULES or self.kernel_scale <= 0):
            raise LGBError(
                f"need order >= 1, lag >= 1, 1 <= k_min <= k_max, bandwidth > 0, carry in "
                f"[0, 1], theiler >= 0, kernel_scale > 0 and rule in {RULES}, got "
                f"order={self.order}, lag={self.lag}, k_min={self.k_min}, k_max={self.k_max}, "
                f"bandwidth={self.bandwidth}, carry={self.carry}, theiler={self.theiler}, "
                f"kernel_scale={self.kernel_scale}, rule={self.rule!r}"
            )
        self._tree = None

    @property
    def span(self) -> int:
        """Frames one state reaches back, ``(p - 1) L``."""
        return (self.order - 1) * self.lag

    def fit(
        self, observed: np.ndarray, passengers: np.ndarray | None = None, name: str = "process"
    ) -> LocalGridBootstrap:
        """Index the states of a closed observed sequence.

        Args:
            observed: ``(N, D)`` observations, the last followed by the first.
            passengers: ``(N, E)`` values carried along (built from the drawn observations like
                the states, but not part of the distances), or None.
            name: what the sequence is, for error messages.

        Returns:
            ``self``.

        Raises:
            LGBError: wrong shapes or NaN/infinite values.
            TooLittleDataError: fewer than :func:`min_observations` observations.
        """
        x = np.asarray(observed, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] < 1:
            raise LGBError(f"{name}: observations must have shape (N, D), got {x.shape}")
        check_finite(name, x)
        need = min_observations(self.order, self.k_max, self.lag)
        if len(x) < need:
            raise TooLittleDataError(
                name, len(x), need,
                f"twice the {self.k_max} states of the largest neighbourhood plus the "
                f"{self.span + 1} frames of a state",
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
        n = len(x)
        lagged = (np.arange(n)[:, None] - self.lag * np.arange(self.order)[None, :]) % n
        self.states_ = z[lagged].reshape(n, -1)
        self.image_ = (np.arange(n) + 1) % n
        self._tree = cKDTree(self.states_)
        dist, idx = self._tree.query(self.states_, k=self.k_max)
        mid = (self.k_min + self.k_max) // 2
        # Column 0 is each state itself.
        self.base_radius_ = float(np.median(dist[:, mid]))
        far = _circular_gap(idx, np.arange(n)[:, None], n) > self.theiler
        has = far.any(1)
        self.nc_distance_ = (float(np.median(dist[has, np.argmax(far[has], 1)])) if has.any()
                             else self.base_radius_)
        if self.rule == "successor":
            self._transitions(dist, idx)
        return self

    def _transitions(self, dist: np.ndarray, idx: np.ndarray) -> None:
        """Candidates and cumulative probabilities of every observed state (successor rule).

        Args:
            dist: ``(N, k_max)`` distances of each state's nearest states, nearest first.
            idx: ``(N, k_max)`` their indices.
        """
        n = len(self.z_)
        radius = np.clip(self.base_radius_, dist[:, self.k_min - 1], dist[:, -1])
        keep = dist <= radius[:, None]
        rows = np.broadcast_to(np.arange(n)[:, None], idx.shape)[keep]
        cols, d = idx[keep], dist[keep]
        other = _circular_gap(rows, cols, n) > self.theiler
        rows, cols, d = rows[other], cols[other], d[other]
        h = max(self.kernel_scale * self.nc_distance_, 1e-12)
        kern = sparse.coo_matrix((np.exp(-0.5 * (d / h) ** 2), (rows, cols)), shape=(n, n))
        kern = kern.tocsr()
        # Symmetric weights keep the uniform distribution over the observed frames stationary.
        kern = kern.maximum(kern.T).tocsr()
        kern.sort_indices()
        total = np.asarray(kern.sum(1)).ravel()
        eps = 1.0 / total.max() if total.max() > 0 else 0.0
        counts = np.diff(kern.indptr)
        ptr = np.concatenate(([0], np.cumsum(counts + 1)))
        cand = np.empty(ptr[-1], dtype=np.int64)
        prob = np.empty(ptr[-1])
        own = ptr[:-1]
        rest = np.ones(ptr[-1], bool)
        rest[own] = False
        cand[own], prob[own] = np.arange(n), np.clip(1.0 - eps * total, 0.0, 1.0)
        cand[rest], prob[rest] = kern.indices, eps * kern.data
        cum = np.cumsum(prob)
        start = np.repeat(cum[own] - prob[own], counts + 1)
        row_total = np.repeat(cum[ptr[1:] - 1] - (cum[own] - prob[own]), counts + 1)
        self.jump_probability_ = np.minimum(eps * total, 1.0)
        self.candidates_ = cand
        self.cumulative_ = (cum - start) / row_total
        self.pointers_ = ptr

    @property
    def dim(self) -> int:
        """``D``, dimensions of an observation."""
        return self.observed_.shape[1]

    def neighbourhood(self, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Observed states around a standardized state.

        Args:
            state: ``(p * D,)`` standardized state.

        Returns:
            ``(idx, dist, radius)``: indices and distances (nearest first) of the ``k_min`` to
            ``k_max`` observed states within the radius, and the radius.
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
            start: observed frame the chain starts from; drawn with ``rng`` if None.

        Returns:
            The generated observations, drawn indices and passengers.

        Raises:
            LGBError: not fitted, or ``n < 0``.
        """
        if self._tree is None:
            raise LGBError("fit the bootstrap before sampling")
        if n < 0:
            raise LGBError(f"the number of steps must be >= 0, got {n}")
        num = len(self.z_)
        i0 = int(rng.integers(num)) if start is None else int(start) % num
        uniforms = rng.random(n)
        if self.rule == "successor":
            states, index, extra = self._successors(n, i0, uniforms)
        else:
            states, index, extra = self._barycentres(n, i0, uniforms)
        return LGBSample(states * self.scale_ + self.mean_, index, extra)

    def _successors(
        self, n: int, i0: int, uniforms: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The successor rule from observed frame ``i0``, standardized."""
        cand, cum, ptr, num = self.candidates_, self.cumulative_, self.pointers_, len(self.z_)
        index = np.empty(n, dtype=np.int64)
        src = i0
        for t in range(n):
            a, b = ptr[src], ptr[src + 1]
            j = cand[a + min(int(np.searchsorted(cum[a:b], uniforms[t], side="right")),
                             b - a - 1)]
            index[t] = src = (j + 1) % num
        out = carry_offsets(self.z_, index, self.carry, i0)
        pas = self.passengers_
        extra = None if pas is None else carry_offsets(pas, index, self.carry, i0)
        return out, index, extra

    def _barycentres(
        self, n: int, i0: int, uniforms: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The paper's rule from observed frame ``i0``, standardized."""
        z, d, lag, num = self.z_, self.dim, self.lag, len(self.z_)
        pas = self.passengers_
        # Generated observations a state needs, newest last.
        hist = z[(i0 - np.arange(self.span, -1, -1)) % num].copy()
        taps = self.span - lag * np.arange(self.order)
        out = np.empty((n, d))
        index = np.empty(n, dtype=np.int64)
        extra = None if pas is None else np.empty((n, pas.shape[1]))
        for t in range(n):
            idx, dist, radius = self.neighbourhood(hist[taps].ravel())
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
                nxt += self.carry * (hist[-1] - z[members - 1].mean(0))
            out[t] = nxt
            index[t] = img[pick]
            if extra is not None:
                extra[t] = pas[members].mean(0)
            hist[:-1] = hist[1:]
            hist[-1] = nxt
        return out, index, extra
