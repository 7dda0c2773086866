"""The Table 1 predictor of the gait network, and helpers shared with QuaterNet's.

The Table 1 predictor (:class:`emotive.eval.table1.Predictor`) of the gait network, and the
helpers it shares with the QuaterNet baseline's
(:class:`~emotive.models.gait.quaternet.predict.QuaterNetPredictor`).

Both see the primer through the same per-frame inputs as in training
(:func:`~emotive.models.gait.primer.primer_features`), run it through the network
teacher-forced, then feed back their own predictions. The protocol gives no trajectory, so both
walk straight on from the primer's last position along its last heading:

* the gait network through :class:`~emotive.models.gait.generate.GaitGenerator` on that
  straight path, with the clip's emotion (so its pace follows the emotion, as in use);
* QuaterNet, which reads no emotion, with the movement inputs continuing the primer's own pace
  (the last step frequency and low-passed speed held, the phase advancing, no curvature); its
  root moves at that speed, at the primer's last height.

Predictions come back at the primer's rate: primers at another rate than the network's are
resampled up for the network and the prediction resampled back.

Legend: ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from emotive.core.motion import Motion
from emotive.core.ops import heading, resample
from emotive.core.roles import resolve_roles
from emotive.data.emotion import Emotion
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.generate import GaitGenerator
from emotive.models.gait.model import GaitModel
from emotive.paths import GroundPath

#: Length (metres) of the straight path laid ahead of a primer.
AHEAD_METRES = 200.0


def straight_ahead(primer: Motion, controls: GaitControls) -> GroundPath:
    """A straight path from the primer's last ground position along its last heading."""
    root = resolve_roles(primer.skeleton).index["root"]
    start = primer.positions_with_end_sites()[-1, root][[0, 2]]
    yaw = float(heading(primer)[-1])
    u = np.linspace(0.0, AHEAD_METRES, int(AHEAD_METRES / 0.05) + 1)
    points = start + u[:, None] * np.array([math.sin(yaw), math.cos(yaw)])
    return GroundPath.from_polyline(points, name="straight ahead")


def frames_at(count: int, src_fps: float, dst_fps: float) -> int:
    """Frames at ``src_fps`` (Hz) that cover ``count`` frames at ``dst_fps`` (Hz), plus one."""
    return math.ceil(count * src_fps / dst_fps) + 1


def back_to_rate(motion: Motion, fps: float, frames: int) -> Motion:
    """``motion`` at ``fps`` (Hz), the first ``frames`` frames after its frame 0.

    ``motion`` (starting one frame before the prediction) at ``fps`` (Hz), the first
    ``frames`` frames after its frame 0.
    """
    if abs(motion.fps - fps) > 1e-9 * fps:
        motion = resample(motion, fps)
    return motion.replace(rotations=motion.rotations[1:frames + 1],
                          positions=motion.positions[1:frames + 1])


@dataclass
class GaitPredictor:
    """The gait network as a Table 1 predictor (see the module docstring)."""

    model: GaitModel
    name: str = "Ours"

    def predict(self, primer: Motion, frames: int, emotion: np.ndarray,
                labels: tuple[str, ...]) -> Motion:
        """The ``frames`` frames after ``primer``.

        The ``frames`` frames after ``primer`` (see
        :meth:`emotive.eval.table1.Predictor.predict`).
        """
        # Table 1 measures the network's prediction, as the paper does: no foot lock.
        gen = GaitGenerator(self.model, foot_lock=False)
        gen.add_agent(straight_ahead(primer, self.model.controls), Emotion(emotion, labels),
                      primer=primer)
        first = gen.first_frame()
        steps = frames_at(frames, self.model.fps, primer.fps)
        out = [first] + [gen.step() for _ in range(steps)]
        motion = Motion(self.model.controls.skeleton, np.stack([f.rotations[0] for f in out]),
                        np.stack([f.positions[0] for f in out]), self.model.fps,
                        {**primer.metadata, "predictor": self.name})
        return back_to_rate(motion, primer.fps, frames)
