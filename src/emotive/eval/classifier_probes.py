"""Inputs that lie clearly outside what the classifier has seen, to measure its "unsure".

* :func:`spinning_figure`: one pose of a real clip held still and turned about the vertical
  axis through its root: a figure that stands and spins, nothing like locomotion.
* :func:`joint_noise`: every role at a random place around a standing height, new each frame.

Both give role tracks ``(T, J, 3)`` (metres, Y up, :data:`emotive.core.roles.ROLES` order) for
:func:`emotive.eval.classifier.track_features`.
"""

from __future__ import annotations

import numpy as np

from emotive.core.roles import ROLES


def spinning_figure(pose: np.ndarray, fps: float, seconds: float,
                    turns_per_second: float = 1.0) -> np.ndarray:
    """A still pose turned about the vertical axis through its root.

    Args:
        pose: ``(J, 3)`` role positions of one frame, metres, Y up.
        fps: frame rate of the result.
        seconds: its duration.
        turns_per_second: whole turns per second.

    Returns:
        ``(T, J, 3)`` role positions, ``T = round(seconds * fps)``.
    """
    pose = np.asarray(pose, dtype=np.float64)
    t = np.arange(round(seconds * fps)) / fps
    a = 2 * np.pi * turns_per_second * t
    centre = pose[ROLES.index("root")] * [1.0, 0.0, 1.0]
    rel = pose - centre
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    x = c * rel[:, 0] + s * rel[:, 2]
    z = -s * rel[:, 0] + c * rel[:, 2]
    y = np.broadcast_to(rel[:, 1], x.shape)
    return np.stack((x, y, z), -1) + centre


def joint_noise(rng: np.random.Generator, frames: int, height_m: float = 1.7) -> np.ndarray:
    """Random role positions: x, z within +-0.3 height of the origin, y in 0..height.

    Args:
        rng: random draws.
        frames: number of frames.
        height_m: height of the box the points fall in, metres.

    Returns:
        ``(T, J, 3)`` role positions.
    """
    p = rng.uniform(-0.3, 0.3, (frames, len(ROLES), 3)) * height_m
    p[..., 1] = rng.uniform(0.0, height_m, (frames, len(ROLES)))
    return p
