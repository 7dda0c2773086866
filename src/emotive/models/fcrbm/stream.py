"""Streaming FCRBM: many agents walking ground paths, stepped frame by frame (issue 25).

Legend: ``B`` agents, ``J`` joints, ``E`` end sites, ``C`` emotion labels, ``N`` order (past
frames), ``D`` visible units.

:class:`FCRBMStream` is the FCRBM's counterpart of the gait network's streaming generator, with
the same methods, for ``emotive serve --model fcrbm``. Each :meth:`~FCRBMStream.step` returns
one frame of every agent at :data:`OUTPUT_FPS`.

Per model frame, every agent at once:

1. Context. Each agent's emotion is a schedule of the one emotion model
   (:func:`emotive.data.emotion.coerce_emotion`: a label, a blend, a valence/arousal point or
   keyframes), read at the agent's clock as valence/arousal on the toolkit's -1..1 scale and
   shifted by :data:`~emotive.models.fcrbm.adapter.SCALE_OFFSET` to the model's 1..3 scale.
2. Network. One Gibbs-sampled frame for the whole batch
   (:func:`~emotive.models.fcrbm.stream_gibbs.gibbs_frame`: the sampling of
   :meth:`FCRBM.generate <emotive.models.fcrbm.model.FCRBM.generate>`, the agents grouped by
   context), each agent's past window a row of one ``(B, N, D)`` tensor. Each agent draws its
   hidden samples from its own generator, so its motion follows from its seed and its context
   whatever else is in the scene.
3. Divergence. An agent whose frame leaves the data's range (beyond
   :data:`~emotive.models.fcrbm.generate.DIVERGED` standard deviations, or not finite) gets
   its seed frames back (the window it started streaming from) and is counted in
   :attr:`FCRBMStream.diverged`; the stream goes on.
4. Path following. The body comes from the model (:mod:`~emotive.models.fcrbm.stream_pose`);
   its root is placed on the agent's path: the arc length advances by the model's own forward
   step (clamped to ``[0, MAX_SPEED]``) times the agent's pace, the heading is the path's
   tangent there and the height the model's. The model's sideways step and turn are dropped:
   the path steers.

Starts. A new agent starts from the training data's mean frame and walks
:data:`~emotive.models.fcrbm.generate.WARMUP_SECONDS` at the neutral point, then changes to its
emotion over :data:`~emotive.models.fcrbm.generate.WARMUP_RAMP_SECONDS`, as
:func:`~emotive.models.fcrbm.generate.generate_motion` does; those frames are not streamed,
the agent appears in motion. Its seed drives that warm-up and every frame after it.

Rate. The stream's frames are at :data:`OUTPUT_FPS`. The committed checkpoint runs at 30 fps,
so each output frame is one model frame. A checkpoint at another rate is resampled at this
edge: the model is stepped as often as the output clock needs (several times per output frame
or none) and each output frame blends the last two model frames at its time (rotations by
normalized linear interpolation, height and arc length linearly).

Cost, on one thread of the shared 2-core development machine: about 5 ms a frame for one
agent, 20-35 ms for 50 agents sharing three emotions, 60 ms for 50 with emotions of their own
(each Gibbs iteration is the bulk; ``gibbs=10`` roughly thirds it); adding agents costs their
warm-up, 0.3 s for one and 2.5-4 s for 50 at once.

Limits. The FCRBM has no speed or stop control: at the end of an open path (or a
:meth:`~FCRBMStream.set_target` target) the agent stays where the path ends and walks on the
spot; a pace other than 1 changes how fast the root advances but not the steps, so the feet
slide by the difference.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import torch

from emotive.data.emotion import DEFAULT_LABELS, EmotionLike, coerce_emotion
from emotive.ik.solver import single_thread
from emotive.models.fcrbm.adapter import SCALE_OFFSET
from emotive.models.fcrbm.generate import (
    DIVERGED,
    FCRBMDivergedError,
    FCRBMInputError,
    FCRBMModel,
    check_context,
    seed_frames,
    warmup_context,
)
from emotive.models.fcrbm.stream_gibbs import ContextWeights, gibbs_frame
from emotive.models.fcrbm.stream_pose import PoseDecoder, nlerp
from emotive.models.fcrbm.stream_state import (
    PACE_RANGE,
    AgentInfo,
    FCRBMAgentError,
    FCRBMFrame,
    Rows,
    agent_seed,
    check_pace,
    check_path,
    check_seed,
    emotion_at,
    target_path,
)
from emotive.paths import GroundPath
from emotive.paths.bank import PathBank

__all__ = ["MAX_SPEED", "OUTPUT_FPS", "PACE_RANGE", "FCRBMAgentError", "FCRBMFrame",
           "FCRBMStream"]

#: Frame rate of :meth:`FCRBMStream.step`, frames per second.
OUTPUT_FPS = 30.0
#: Fastest root speed along a path, metres per second (a forward step beyond it is clamped).
MAX_SPEED = 4.0
#: Metres of the gap to a new path (:meth:`FCRBMStream.set_path`) closed per metre walked.
PATH_MERGE_SLOPE = 0.5


class FCRBMStream:
    """Steps many FCRBM agents along ground paths (see the module docstring).

    Args:
        model: the trained model (:func:`~emotive.models.fcrbm.generate.load_fcrbm_model`).
        seed: seed of the agents' samples (agent ``k`` draws from ``seed`` and ``k`` unless
            given a seed of its own).
        gibbs: Gibbs iterations per frame (default: the model's); fewer is faster and noisier.

    Attributes:
        labels: the ``C`` emotion labels of :attr:`FCRBMFrame.emotion`.
        fps: frame rate of :meth:`step` (:data:`OUTPUT_FPS`).
        model_fps: frame rate of the model.
        skeleton: the rig of the frames.
        mover: the joint whose local translation is the agent's world position.
        rest: a one-frame clip of the rig standing (the training data's mean pose).
        diverged: how many times an agent diverged and was reset to its seed frames.

    Raises:
        FCRBMInputError: ``gibbs`` is not a whole number >= 1.

    Example::

        stream = FCRBMStream(load_fcrbm_model())
        a = stream.add_agent(circle(2.0), "happy=0.7,neutral=0.3")
        for _ in range(300):
            frame = stream.step()      # frame.world[0]: agent a's joints
        stream.set_emotion(a, {"valence": -0.8, "arousal": -0.6})
    """

    def __init__(self, model: FCRBMModel, seed: int = 0, gibbs: int | None = None) -> None:
        if gibbs is not None and (isinstance(gibbs, bool) or not isinstance(gibbs, int)
                                  or gibbs < 1):
            raise FCRBMInputError(f"gibbs must be a whole number >= 1, got {gibbs!r}")
        self.model = model
        self.network = model.network.eval()
        self.seed = int(seed)
        self.gibbs = model.network.config.gibbs if gibbs is None else gibbs
        self.labels: tuple[str, ...] = DEFAULT_LABELS
        self.fps = OUTPUT_FPS
        self.model_fps = float(model.fps)
        self.skeleton = model.codec.skeleton
        self.mover = int(model.codec.mover)
        self.diverged = 0
        self._pose = PoseDecoder(model.codec)
        self.rest = self._pose.rest(self.fps)
        self._weights = ContextWeights(self.network)
        self._paths = PathBank()
        self._agents: dict[int, AgentInfo] = {}
        self._order: list[int] = []
        self._next_id = 0
        self._frames = 0
        self._model_frames = 0
        self._start = torch.from_numpy(seed_frames(model))
        self._rows = self._new_rows(torch.zeros((0, *self._start.shape)), np.zeros((0, 2)),
                                    np.zeros((0, len(self.labels))), np.zeros(0), np.zeros(0),
                                    np.zeros(0, dtype=np.int64))

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order."""
        return tuple(self._order)

    @property
    def model_frames(self) -> int:
        """Model frames generated since the stream started."""
        return self._model_frames

    def __len__(self) -> int:
        return len(self._order)

    def add_agent(self, path: GroundPath, emotion: EmotionLike = "neutral", start: float = 0.0,
                  pace: float = 1.0, seed: int | None = None) -> int:
        """Add an agent walking ``path`` from arc length ``start``; returns its id.

        Args:
            path: the path to follow.
            emotion: its emotion or schedule (times from now), anything
                :func:`~emotive.data.emotion.coerce_emotion` accepts.
            start: arc length (metres) where it starts.
            pace: factor on the model's forward speed, 0.5-1.5 (:data:`PACE_RANGE`).
            seed: seed of its samples (default: from the stream's seed and its id).

        Raises:
            EmotionError: a bad emotion. PathError: not a path or a bad start.
            FCRBMInputError: a pace outside :data:`PACE_RANGE`. FCRBMDivergedError: the model
            diverged while the agent warmed up to its emotion.
        """
        return self.add_agents([path], [emotion], starts=[start], paces=[pace],
                               seeds=None if seed is None else [seed])[0]

    def add_agents(self, paths: Sequence[GroundPath], emotions: Sequence[EmotionLike],
                   starts: Sequence[float] | None = None, paces: Sequence[float] | None = None,
                   seeds: Sequence[int] | None = None) -> list[int]:
        """Add many agents with one batched warm-up; returns their ids.

        Arguments are as for :meth:`add_agent`, one entry per agent (``None``: the defaults).
        Nothing is added if any entry is bad.
        """
        n = len(paths)
        starts = [0.0] * n if starts is None else list(starts)
        paces = [check_pace(p) for p in ([1.0] * n if paces is None else paces)]
        if not (len(emotions) == len(starts) == len(paces) == n
                and (seeds is None or len(seeds) == n)):
            raise FCRBMInputError("add_agents: give one emotion, start, pace and seed per path")
        for path, start in zip(paths, starts, strict=True):
            check_path(path, start)
        schedules = [coerce_emotion(e, self.labels) for e in emotions]
        ids = list(range(self._next_id, self._next_id + n))
        own = [agent_seed(self.seed, a) for a in ids] if seeds is None else [
            check_seed(s) for s in seeds]
        gens = [torch.Generator().manual_seed(s) for s in own]
        va, weights = emotion_at(schedules, [0.0] * n, len(self.labels))
        with single_thread():
            window = self._warm_up(self._context(va), gens)
        slots = np.array([self._paths.add(p) for p in paths], dtype=np.int64)
        self._next_id += n
        for a, schedule, gen in zip(ids, schedules, gens, strict=True):
            self._agents[a] = AgentInfo(schedule, self._model_frames, gen)
        self._order.extend(ids)
        self._rows = self._rows.join(self._new_rows(window, va, weights,
                                                    np.asarray(starts, dtype=np.float64),
                                                    np.asarray(paces), slots))
        return ids

    def remove_agent(self, agent: int) -> None:
        """Remove an agent.

        Raises:
            FCRBMAgentError: no live agent has that id.
        """
        k = self._index(agent)
        self._paths.release(int(self._rows.slot[k]))
        self._rows = self._rows.take(np.delete(np.arange(len(self._order)), k))
        del self._order[k]
        del self._agents[agent]

    def set_emotion(self, agent: int, emotion: EmotionLike) -> None:
        """Give an agent a new emotion or schedule; a schedule's time 0 is now.

        Raises:
            FCRBMAgentError: unknown agent. EmotionError: a bad emotion.
        """
        k = self._index(agent)
        schedule = coerce_emotion(emotion, self.labels)
        self._agents[agent] = replace(self._agents[agent], schedule=schedule,
                                      start=self._model_frames)
        va, weights = emotion_at([schedule], [0.0], len(self.labels))
        self._rows.va[k], self._rows.weights[k] = va[0], weights[0]
        self._rows.context[k] = self._context(va)[0]

    def set_path(self, agent: int, path: GroundPath) -> None:
        """Send an agent along another path from its nearest point.

        The agent does not jump: the gap to the new path closes as it walks
        (:data:`PATH_MERGE_SLOPE`).

        Raises:
            FCRBMAgentError: unknown agent. PathError: not a path.
        """
        check_path(path)
        k = self._index(agent)
        here = self._ground(k)
        arc, _ = path.nearest(here[None])
        self._follow(k, path, float(arc[0]), here - path.position(float(arc[0])))

    def set_target(self, agent: int, xz: Sequence[float]) -> GroundPath:
        """Send an agent to a ground point ``(x, z)`` (metres) along a smooth path.

        The path is a spline from where the agent stands, leaving along its heading, to the
        target (:func:`~emotive.models.fcrbm.stream_state.target_path`).

        Returns:
            The path the agent now follows.

        Raises:
            FCRBMAgentError: unknown agent. PathError: not two finite numbers, or beyond
            :data:`emotive.paths.MAX_COORDINATE`.
        """
        k = self._index(agent)
        yaw = float(self._paths.heading(self._rows.slot[k:k + 1], self._rows.arc[k:k + 1])[0])
        path = target_path(self._ground(k), yaw, xz)
        self._follow(k, path, 0.0, np.zeros(2))
        return path

    def set_pace(self, agent: int, pace: float) -> None:
        """Move an agent along its path faster or slower than the model walks, 0.5-1.5.

        Raises:
            FCRBMAgentError: unknown agent. FCRBMInputError: ``pace`` outside
            :data:`PACE_RANGE`.
        """
        k = self._index(agent)
        self._rows.pace[k] = check_pace(pace)

    def _index(self, agent: int) -> int:
        try:
            return self._order.index(agent)
        except ValueError:
            raise FCRBMAgentError(f"no live agent with id {agent!r}; live agents: "
                                  f"{self._order}") from None

    def _ground(self, k: int) -> np.ndarray:
        """``(2,)`` where agent ``k`` (batch index) stands, path gap included."""
        r = self._rows
        return self._paths.position(r.slot[k:k + 1], r.arc[k:k + 1])[0] + r.offset[k]

    def _follow(self, k: int, path: GroundPath, arc: float, offset: np.ndarray) -> None:
        """Put agent ``k`` (batch index) on ``path`` at ``arc``, ``offset`` (2,) metres off it."""
        r = self._rows
        self._paths.release(int(r.slot[k]))
        r.slot[k] = self._paths.add(path)
        r.arc[k] = r.arc_prev[k] = arc
        r.offset[k] = offset

    # ----------------------------------------------------------------------------- emotion

    def _context(self, va: np.ndarray) -> np.ndarray:
        """``(n, 2)`` context on the model's 1..3 scale of ``(n, 2)`` valence/arousal."""
        return check_context(SCALE_OFFSET + va, "emotion")

    def _update_emotions(self) -> None:
        """Read every scheduled agent's emotion at its clock (after a model frame)."""
        r = self._rows
        for k, agent in enumerate(self._order):
            info = self._agents[agent]
            if len(info.schedule.times) > 1:
                t = (self._model_frames - info.start) / self.model_fps
                va, weights = emotion_at([info.schedule], [t], len(self.labels))
                r.va[k], r.weights[k] = va[0], weights[0]
                r.context[k] = self._context(va)[0]

    # ----------------------------------------------------------------------------- model

    def _uniforms(self, gens: Sequence[torch.Generator]) -> torch.Tensor:
        """``(S - 1, B, H)`` the hidden units' noise of one frame, each agent's own."""
        shape = (self.gibbs - 1, self.network.config.hidden)
        if not gens:
            return torch.zeros(shape[0], 0, shape[1])
        return torch.stack([torch.rand(shape, generator=g) for g in gens], 1)

    def _warm_up(self, first: np.ndarray, gens: Sequence[torch.Generator]) -> torch.Tensor:
        """``(n, N, D)`` windows of new agents after their warm-up to ``(n, 2)`` contexts."""
        window = self._start.expand(len(first), -1, -1).clone()
        weights = ContextWeights(self.network)
        for context in warmup_context(first, self.model_fps):
            v = gibbs_frame(self.network, weights, window, context, self._uniforms(gens))
            if not (v.abs() <= DIVERGED).all():
                raise FCRBMDivergedError(
                    f"the model diverged while warming up to valence/arousal "
                    f"{np.round(first - SCALE_OFFSET, 2).tolist()}: use an emotion closer to "
                    "the middle of the circumplex")
            window = torch.cat((window[:, 1:], v[:, None]), 1)
        return window

    def _new_rows(self, window: torch.Tensor, va: np.ndarray, weights: np.ndarray,
                  arc: np.ndarray, pace: np.ndarray, slot: np.ndarray) -> Rows:
        body = self._pose.body(window[:, -1].numpy())
        n = len(va)
        return Rows(window, window.clone(), self._context(va), va, weights, body.rotations,
                     body.rotations.copy(), body.height, body.height.copy(), arc, arc.copy(),
                     np.zeros((n, 2)), pace, slot)

    def _model_step(self) -> None:
        """Generate the next model frame of every agent and move it along its path."""
        self._model_frames += 1
        r = self._rows
        if not self._order:
            return
        gens = [self._agents[a].generator for a in self._order]
        v = gibbs_frame(self.network, self._weights, r.window, r.context, self._uniforms(gens))
        bad = ~(v.abs() <= DIVERGED).all(1)
        v[bad] = r.seed[bad, -1]
        r.window = torch.cat((r.window[:, 1:], v[:, None]), 1)
        r.window[bad] = r.seed[bad]
        self.diverged += int(bad.sum())
        body = self._pose.body(v.numpy())
        step = np.clip(body.forward, 0.0, MAX_SPEED / self.model_fps) * r.pace
        bank = self._paths
        arc = r.arc + step
        arc = np.where(bank.closed(r.slot), arc, np.minimum(arc, bank.length(r.slot)))
        gap = np.linalg.norm(r.offset, axis=1)
        shrink = np.maximum(gap - PATH_MERGE_SLOPE * step, 0.0) / np.maximum(gap, 1e-12)
        r.offset = r.offset * shrink[:, None]
        r.body_prev, r.body = r.body, body.rotations
        r.height_prev, r.height = r.height, body.height
        r.arc_prev, r.arc = r.arc, arc
        self._update_emotions()

    # ----------------------------------------------------------------------------- stepping

    def step(self) -> FCRBMFrame:
        """Advance every agent by one frame (``1 / fps`` seconds) and return the new frame."""
        with single_thread(), torch.no_grad():
            self._frames += 1
            now = self._frames / self.fps
            while self._model_frames / self.model_fps < now - 1e-9:
                self._model_step()
            weight = 1.0 - (self._model_frames / self.model_fps - now) * self.model_fps
            return self._frame(min(max(weight, 0.0), 1.0))

    def _frame(self, weight: float) -> FCRBMFrame:
        """The agents placed ``weight`` of the way from the previous model frame to the last."""
        r = self._rows
        if weight < 1.0:
            body = nlerp(r.body_prev, r.body, weight)
            height = r.height_prev + weight * (r.height - r.height_prev)
            arc = r.arc_prev + weight * (r.arc - r.arc_prev)
        else:
            body, height, arc = r.body, r.height, r.arc
        xz = self._paths.position(r.slot, arc) + r.offset
        placed = self._pose.place(body, height, self._paths.heading(r.slot, arc), xz)
        return FCRBMFrame(tuple(self._order), placed.rotations, placed.positions, placed.world,
                          r.weights.copy(), xz, r.va.copy())
