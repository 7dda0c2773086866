"""Table 1 predictors (:class:`emotive.eval.table1.Predictor`) of the gait network and of the
QuaterNet baseline.

Both see the primer through the same per-frame inputs as in training
(:func:`~emotive.models.gait.generate.primer_features`), run it through the network
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
from typing import Any

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.generate import GaitGenerator, primer_features
from emotive.models.gait.model import GaitModel
from emotive.paths import GroundPath

#: Length (metres) of the straight path laid ahead of a primer.
AHEAD_METRES = 200.0


def straight_ahead(primer: Motion, controls: GaitControls) -> GroundPath:
    """A straight path from the primer's last ground position along its last heading."""
    from emotive.core.ops import heading
    from emotive.core.roles import resolve_roles

    root = resolve_roles(primer.skeleton).index["root"]
    start = primer.positions_with_end_sites()[-1, root][[0, 2]]
    yaw = float(heading(primer)[-1])
    u = np.linspace(0.0, AHEAD_METRES, int(AHEAD_METRES / 0.05) + 1)
    points = start + u[:, None] * np.array([math.sin(yaw), math.cos(yaw)])
    return GroundPath.from_polyline(points, name="straight ahead")


def _frames_at(count: int, src_fps: float, dst_fps: float) -> int:
    """Frames at ``src_fps`` that cover ``count`` frames at ``dst_fps``, plus one."""
    return math.ceil(count * src_fps / dst_fps) + 1


def _back_to(motion: Motion, fps: float, frames: int) -> Motion:
    """``motion`` (starting one frame before the prediction) at ``fps``, the first
    ``frames`` frames after its frame 0."""
    from emotive.core.ops import resample

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
        """The ``frames`` frames after ``primer`` (see
        :meth:`emotive.eval.table1.Predictor.predict`)."""
        from emotive.data.emotion import Emotion

        gen = GaitGenerator(self.model)
        gen.add_agent(straight_ahead(primer, self.model.controls), Emotion(emotion, labels),
                      primer=primer)
        first = gen.first_frame()
        steps = _frames_at(frames, self.model.fps, primer.fps)
        out = [first] + [gen.step() for _ in range(steps)]
        motion = Motion(self.model.controls.skeleton, np.stack([f.rotations[0] for f in out]),
                        np.stack([f.positions[0] for f in out]), self.model.fps,
                        {**primer.metadata, "predictor": self.name})
        return _back_to(motion, primer.fps, frames)


@dataclass
class QuaterNetPredictor:
    """The QuaterNet baseline as a Table 1 predictor (see the module docstring).

    Attributes:
        network: the trained :class:`~emotive.models.quaternet.QuaterNetwork`.
        controls: the rig and standing pose of its checkpoint.
        name: the name in the table.
    """

    network: Any
    controls: GaitControls
    name: str = "QuaterNet"

    @torch.no_grad()
    def predict(self, primer: Motion, frames: int, emotion: np.ndarray,
                labels: tuple[str, ...]) -> Motion:
        """The ``frames`` frames after ``primer``; ``emotion`` is not used."""
        from emotive.core.ops import heading, resample
        from emotive.transforms.np_rotations import quaternion_multiply, yaw_quaternion

        c = self.controls
        f = primer_features(primer, c)
        net = self.network.eval()
        dtype = next(net.parameters()).dtype

        def t(x: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(x, dtype=dtype)

        _, state = net(t(f["rotations"][None, :-1]), t(f["movement"][None, :-1]))
        rot = t(f["rotations"][-1:])
        move = f["movement"][-1].copy()
        theta = math.atan2(move[0], move[1])
        omega, speed = float(move[2]), float(move[3])
        steps = _frames_at(frames, c.fps, primer.fps)
        rotations = [f["rotations"][-1]]
        for _ in range(steps):
            movement = np.array([math.sin(theta), math.cos(theta), omega, speed, 0.0])
            out, state = net.step(rot, t(movement[None]), state)
            rot = out.rotations
            rotations.append(rot[0].double().numpy())
            theta += omega
        q = np.stack(rotations)
        # Joints above the mover stay at the identity, as in the data.
        j = int(c.skeleton.parents[c.mover])
        while j >= 0:
            q[:, j] = (1.0, 0.0, 0.0, 0.0)
            j = int(c.skeleton.parents[j])
        # World placement: the primer's last heading and height, moving at its speed.
        mover = c.mover
        motion = primer if abs(primer.fps - c.fps) < 1e-9 * c.fps else resample(primer, c.fps)
        yaw = float(heading(motion)[-1])
        last = motion.positions[-1, mover]
        q[:, mover] = quaternion_multiply(yaw_quaternion(np.full(len(q), yaw)), q[:, mover])
        positions = np.repeat(motion.positions[-1:], len(q), axis=0)
        travel = speed * np.arange(len(q))[:, None] * np.array([math.sin(yaw), math.cos(yaw)])
        positions[:, mover, 0] = last[0] + travel[:, 0]
        positions[:, mover, 2] = last[2] + travel[:, 1]
        out_motion = Motion(c.skeleton, q, positions, c.fps,
                            {**primer.metadata, "predictor": self.name})
        return _back_to(out_motion, primer.fps, frames)
