"""The QuaterNet baseline as a Table 1 predictor (:class:`emotive.eval.table1.Predictor`).

It sees the primer through the gait network's per-frame inputs
(:func:`~emotive.models.gait.primer.primer_features`), runs it through the network
teacher-forced, then feeds back its own predictions. QuaterNet reads no emotion: the movement
inputs continue the primer's own pace (the last step frequency and low-passed speed held, the
phase advancing, no curvature); its root moves at that speed along the primer's last heading,
at the primer's last height. Predictions come back at the primer's rate
(:func:`~emotive.models.gait.predict.back_to_rate`).

Legend: ``T`` frames, ``J`` joints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from emotive.core.motion import Motion
from emotive.core.ops import heading, resample
from emotive.models.gait.controls import GaitControls
from emotive.models.gait.predict import back_to_rate, frames_at
from emotive.models.gait.primer import primer_features
from emotive.models.gait.quaternet.network import QuaterNetwork
from emotive.transforms.np_rotations import quaternion_multiply, yaw_quaternion


@dataclass
class QuaterNetPredictor:
    """The QuaterNet baseline as a Table 1 predictor (see the module docstring).

    Attributes:
        network: the trained :class:`~emotive.models.gait.quaternet.network.QuaterNetwork`.
        controls: the rig and standing pose of its checkpoint.
        name: the name in the table.
    """

    network: QuaterNetwork
    controls: GaitControls
    name: str = "QuaterNet"

    @torch.no_grad()
    def predict(self, primer: Motion, frames: int, emotion: np.ndarray,
                labels: tuple[str, ...]) -> Motion:
        """The ``frames`` frames after ``primer``; ``emotion`` is not used."""
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
        steps = frames_at(frames, c.fps, primer.fps)
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
        return back_to_rate(out_motion, primer.fps, frames)
