"""Typed config of the MAR style transfer (Xia et al. 2015), saved inside every index file.

Paper values: ``K = 40`` neighbours, ridge weight ``lambda = 0.1``, mixture kernel width
``delta = 0.7``, output bias ``rho = 0.7`` (section 7, "very few parameters"). The paper does
not give the confidence width ``kappa`` of section 5.3, the timing kernel width, the window
weights or the smoothing of the footplant likelihoods; the defaults here are our own. The
paper's window is 5 frames at 120 fps (1/24 s); at the 30 fps of the Bandai Namco data we keep
5 frames (1/6 s), so that the window still carries velocity.

The search settings (``screen``, ``max_classes``, ``candidates``, ``pca_dims``) only decide
how the exact nearest neighbours are found fast (see :mod:`emotive.models.mar.search`).
"""

from __future__ import annotations

from dataclasses import dataclass

from emotive.errors import EmotiveError
from emotive.models.training import DictConfig


class TransferError(EmotiveError):
    """Input the style transfer cannot use.

    Unknown styles or actions, short or NaN input, a rig that cannot be mapped, a missing or stale
    index.
    """


@dataclass(frozen=True)
class MARConfig(DictConfig):
    """Everything that shapes the database and the online models.

    Attributes:
        k: ``K``, nearest neighbours per class.
        ridge: ``lambda`` of the ridge regression, in the data's units (applied as
            ``lambda / sigma_d^2`` to each standardized degree of freedom ``d``).
        delta: kernel width of the mixture weights ``exp(-D_j / (delta min D))``.
        rho: share of the input's bias passed to the output (0: pure style, 1: keep content).
        kappa: half width, in standard deviations of the neighbours, of the confidence
            interval outside which an input degree of freedom gets a bias (section 5.3).
        window: ``s``, frames of the sliding window of the point-cloud distance.
        taper: weight of the oldest window frame relative to the newest (linear in between).
        timing_k: neighbours of the timing prediction.
        contact_sigma: Gaussian smoothing of the footplant likelihood, frames.
        fps: frame rate of the database (clips at other rates are resampled).
        max_takes: at most this many takes per (data set, action, style) go into the index.
        min_styles: actions recorded in fewer styles are left out (nothing to translate).
        pca_dims: dimensions of the reduced window features of the search trees.
        screen: frames of the global tree query that pick the promising classes.
        max_classes: classes given an exact search per frame when the input is unlabeled.
        candidates: per class, ``candidates * k`` tree candidates get the exact distance.
        min_weight: mixture weights below this are dropped (the rest renormalized).
        datasets: data sets the default index is built from.
        actions: actions (contents) the default index holds.
    """

    k: int = 40
    ridge: float = 0.1
    delta: float = 0.7
    rho: float = 0.7
    kappa: float = 3.0
    window: int = 5
    taper: float = 0.5
    timing_k: int = 40
    contact_sigma: float = 2.0
    fps: float = 30.0
    max_takes: int = 12
    min_styles: int = 2
    pca_dims: int = 24
    screen: int = 96
    max_classes: int = 8
    candidates: int = 2
    min_weight: float = 1e-4
    datasets: tuple[str, ...] = ("bandai-namco-1", "bandai-namco-2-locomotion")
    actions: tuple[str, ...] = (
        "walk", "run", "dash", "walk-back", "walk-left", "walk-right", "walk-turn-left",
        "walk-turn-right", "bow", "bye", "byebye", "guide",
    )

    def __post_init__(self) -> None:
        positive = {"k": self.k, "window": self.window, "timing_k": self.timing_k,
                    "fps": self.fps, "max_takes": self.max_takes, "pca_dims": self.pca_dims,
                    "screen": self.screen, "max_classes": self.max_classes,
                    "candidates": self.candidates, "delta": self.delta}
        bad = [name for name, value in positive.items() if not value > 0]
        if bad:
            raise TransferError(f"MAR config: {bad} must be positive")
        if not (self.ridge >= 0 and self.kappa > 0 and 0 <= self.rho <= 1
                and 0 < self.taper <= 1 and self.contact_sigma >= 0):
            raise TransferError(
                "MAR config: need ridge >= 0, kappa > 0, 0 <= rho <= 1, 0 < taper <= 1 and "
                f"contact_sigma >= 0 (got ridge={self.ridge}, kappa={self.kappa}, "
                f"rho={self.rho}, taper={self.taper}, contact_sigma={self.contact_sigma})"
            )
