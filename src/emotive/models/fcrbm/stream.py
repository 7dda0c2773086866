"""Streaming FCRBM: many agents walking ground paths, stepped frame by frame.

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
   its root is placed on the agent's path: the arc length advances by how far the stance foot
   moved back under the body (:mod:`~emotive.models.fcrbm.stream_feet`, the causal step of
   :func:`~emotive.ik.stance_root.root_from_stance`; clamped to ``[0, MAX_SPEED]``,
   low-passed) times the agent's pace, the heading is the path's tangent there and the height
   the model's. The model's sideways step and turn are dropped: the path steers. Planted feet
   are then held by the foot lock (:func:`emotive.ik.foot_lock.lock_feet`), as in the gait
   network's stream. Near the end of an open path (or a :meth:`~FCRBMStream.set_target`
   target) the agent slows down and blends to the standing pose, and stands there.

Emotion. Any label of the emotion model, any blend of them or any valence/arousal point
(:func:`~emotive.data.emotion.coerce_emotion`): the FCRBM reads only the valence/arousal
(label blends through their mean point, Sec. IV-A; a point exactly as given).

Starts. A new agent starts from the training data's mean frame and walks
:data:`~emotive.models.fcrbm.generate.WARMUP_SECONDS` at the neutral point, then changes to its
emotion over :data:`~emotive.models.fcrbm.generate.WARMUP_RAMP_SECONDS`, as
:func:`~emotive.models.fcrbm.generate.generate_motion` does; those frames are not streamed,
the agent appears in motion. Its seed drives that warm-up and every frame after it. By default
:meth:`~FCRBMStream.add_agents` runs the warm-up at once (0.3 s for one agent, 2.5-4 s for 50
on the shared 2-core machine); a ``deferred`` stream (the live server's) only books the agent
and warms it up inside the next steps, with the walking agents' batch: each waiting agent at
least one frame per model frame, at most :data:`WARMUP_PER_STEP`, all of them together at
most :data:`WARMUP_BUDGET` beyond one each, so a step's sampling is bounded by the agents in
the scene (one agent appears after 12 frames, 50 added at once after about 90).

Rate. The stream's frames are at :data:`OUTPUT_FPS`. The committed checkpoint runs at 30 fps,
so each output frame is one model frame. A checkpoint at another rate is resampled at this
edge: the model is stepped as often as the output clock needs (several times per output frame
or none) and each output frame blends the last two model frames at its time (rotations by
normalized linear interpolation, height and arc length linearly).

Cost, on one thread of the shared 2-core development machine: about 5 ms a frame for one
agent, 20-35 ms for 50 agents sharing three emotions, 60 ms for 50 with emotions of their own
(each Gibbs iteration is the bulk; ``gibbs=10`` roughly thirds it).

Limits. A pace other than 1 changes how fast the root advances but not the steps (the foot
lock holds what it can of the difference).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import torch

from emotive.data.emotion import ALL_LABELS, DEFAULT_LABELS, EmotionLike, coerce_emotion
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
from emotive.models.fcrbm.stream_feet import (
    MIN_STOP_DISTANCE,
    STOP_DISTANCE,
    STOP_SECONDS,
    StreamFeet,
    lock_rows,
    lock_state,
    store_lock,
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

__all__ = ["MAX_SPEED", "OUTPUT_FPS", "PACE_RANGE", "STOP_DISTANCE", "WARMUP_BUDGET",
           "FCRBMAgentError", "FCRBMFrame", "FCRBMStream"]

#: Frame rate of :meth:`FCRBMStream.step`, frames per second.
OUTPUT_FPS = 30.0
#: Fastest root speed along a path, metres per second (a forward step beyond it is clamped).
MAX_SPEED = 4.0
#: Metres of the gap to a new path (:meth:`FCRBMStream.set_path`) closed per metre walked.
PATH_MERGE_SLOPE = 0.5
#: Share of the change of the stance-driven step taken per model frame (a one-pole low-pass:
#: the stance point's switches from heel to toe and foot to foot make the raw step jump).
STEP_SMOOTHING = 0.5
#: Deferred warm-up: warm-up frames of waiting agents sampled per model frame, all of them
#: together (each waiting agent gets at least one).
WARMUP_BUDGET = 64
#: Deferred warm-up: most warm-up frames one waiting agent gets per model frame.
WARMUP_PER_STEP = 8


class FCRBMStream:
    """Steps many FCRBM agents along ground paths (see the module docstring).

    Args:
        model: the trained model (:func:`~emotive.models.fcrbm.generate.load_fcrbm_model`).
        seed: seed of the agents' samples (agent ``k`` draws from ``seed`` and ``k`` unless
            given a seed of its own).
        gibbs: Gibbs iterations per frame (default: the model's); fewer is faster and noisier.
        deferred: warm new agents up over the next steps instead of in
            :meth:`add_agents` (module docstring, "Starts"): what a live scene needs.

    Attributes:
        labels: the ``C`` emotion labels of :attr:`FCRBMFrame.emotion`: every label of the
            emotion model (each has a valence/arousal point, which is all the FCRBM reads).
        points_over: the labels a valence/arousal point is shown as a blend of (the four
            emotions; the model gets the point itself).
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

    def __init__(self, model: FCRBMModel, seed: int = 0, gibbs: int | None = None,
                 deferred: bool = False) -> None:
        if gibbs is not None and (isinstance(gibbs, bool) or not isinstance(gibbs, int)
                                  or gibbs < 1):
            raise FCRBMInputError(f"gibbs must be a whole number >= 1, got {gibbs!r}")
        self.model = model
        self.network = model.network.eval()
        self.seed = int(seed)
        self.gibbs = model.network.config.gibbs if gibbs is None else gibbs
        self.labels: tuple[str, ...] = ALL_LABELS
        self.points_over: tuple[str, ...] = DEFAULT_LABELS
        self.deferred = bool(deferred)
        self.fps = OUTPUT_FPS
        self.model_fps = float(model.fps)
        self.skeleton = model.codec.skeleton
        self.mover = int(model.codec.mover)
        self.diverged = 0
        self._pose = PoseDecoder(model.codec)
        self.rest = self._pose.rest(self.fps)
        self._weights = ContextWeights(self.network)
        self._warm_weights = ContextWeights(self.network)
        self._feet = StreamFeet.of(self._pose)
        self._warm_frames = len(warmup_context(np.zeros((1, 2)), self.model_fps))
        self._paths = PathBank()
        self._agents: dict[int, AgentInfo] = {}
        self._order: list[int] = []
        self._next_id = 0
        self._frames = 0
        self._model_frames = 0
        self._start = torch.from_numpy(seed_frames(model))
        self._rows = self._new_rows(torch.zeros((0, *self._start.shape)), np.zeros((0, 2)),
                                    np.zeros((0, len(self.labels))), np.zeros(0), np.zeros(0),
                                    np.zeros(0, dtype=np.int64), 0)

    # ----------------------------------------------------------------------------- agents

    @property
    def agents(self) -> tuple[int, ...]:
        """Ids of the live agents, in batch order (those still warming up included)."""
        return tuple(self._order)

    @property
    def warming(self) -> tuple[int, ...]:
        """Ids of the agents still warming up (deferred), not yet in the frames."""
        return tuple(a for a, w in zip(self._order, self._rows.warm, strict=True) if w > 0)

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
        schedules = [coerce_emotion(e, self.labels, self.points_over) for e in emotions]
        ids = list(range(self._next_id, self._next_id + n))
        own = [agent_seed(self.seed, a) for a in ids] if seeds is None else [
            check_seed(s) for s in seeds]
        gens = [torch.Generator().manual_seed(s) for s in own]
        va, weights = emotion_at(schedules, [0.0] * n, len(self.labels))
        context = self._context(va)
        if self.deferred:
            window, warm = self._start.expand(n, -1, -1).clone(), self._warm_frames
        else:
            with single_thread():
                window, warm = self._warm_up(context, gens), 0
        slots = np.array([self._paths.add(p) for p in paths], dtype=np.int64)
        self._next_id += n
        for a, schedule, gen in zip(ids, schedules, gens, strict=True):
            self._agents[a] = AgentInfo(schedule, self._model_frames, gen)
        self._order.extend(ids)
        self._rows = self._rows.join(self._new_rows(window, va, weights,
                                                    np.asarray(starts, dtype=np.float64),
                                                    np.asarray(paces), slots, warm))
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
        schedule = coerce_emotion(emotion, self.labels, self.points_over)
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
                  arc: np.ndarray, pace: np.ndarray, slot: np.ndarray, warm: int) -> Rows:
        body = self._pose.body(window[:, -1].numpy())
        n = len(va)
        return Rows(window=window, seed=window.clone(), context=self._context(va), va=va,
                    weights=weights, body=body.rotations, body_prev=body.rotations.copy(),
                    height=body.height, height_prev=body.height.copy(), arc=arc,
                    arc_prev=arc.copy(), offset=np.zeros((n, 2)), pace=pace, slot=slot,
                    warm=np.full(n, warm, dtype=np.int64), stop=np.zeros(n),
                    feet=self._feet.local_feet(body.rotations, body.height),
                    speed=np.zeros(n), **lock_rows(n))

    def _sample(self, rows: np.ndarray, context: np.ndarray, weights: ContextWeights
                ) -> tuple[torch.Tensor, np.ndarray]:
        """One Gibbs frame of agents ``rows`` (batch indices) at ``(n, 2)`` contexts.

        Their windows move on by the new frame. A frame out of the data's range resets the
        agent: a walking agent to its seed frames (the frame returned is the seed's last), a
        warming one to the start of its warm-up.

        Returns:
            ``(n, D)`` the new frames and ``(n,)`` which of them diverged.
        """
        r = self._rows
        if not len(rows):
            return torch.zeros(0, r.window.shape[-1]), np.zeros(0, dtype=bool)
        gens = [self._agents[self._order[k]].generator for k in rows]
        window = r.window[rows]
        v = gibbs_frame(self.network, weights, window, context, self._uniforms(gens))
        bad = ~(v.abs() <= DIVERGED).all(1)
        warming = torch.as_tensor(r.warm[rows] > 0)
        reset = torch.where(warming[:, None, None], self._start, r.seed[rows])
        v[bad] = reset[bad, -1]
        window = torch.cat((window[:, 1:], v[:, None]), 1)
        window[bad] = reset[bad]
        r.window[rows] = window
        bad_np = bad.numpy()
        r.warm[rows[bad_np & (r.warm[rows] > 0)]] = self._warm_frames + 1
        self.diverged += int(bad.sum())
        return v, bad_np

    def _warm_context(self, rows: np.ndarray) -> np.ndarray:
        """``(n, 2)`` the warm-up context of the next frame of warming agents ``rows``."""
        r = self._rows
        ramp = warmup_context(r.context[rows], self.model_fps)  # (W, n, 2)
        return ramp[self._warm_frames - r.warm[rows], np.arange(len(rows))]

    def _warm_more(self) -> None:
        """Deferred warm-up frames beyond the one of this model frame, within the budget."""
        r = self._rows
        waiting = np.flatnonzero(r.warm > 0)
        extra = min(WARMUP_PER_STEP, WARMUP_BUDGET // max(len(waiting), 1)) - 1
        for _ in range(extra):
            waiting = np.flatnonzero(r.warm > 0)
            if not len(waiting):
                return
            self._sample(waiting, self._warm_context(waiting), self._warm_weights)
            r.warm[waiting] -= 1

    def _model_step(self) -> None:
        """Generate the next model frame of every agent and move it along its path."""
        self._model_frames += 1
        r = self._rows
        if not self._order:
            return
        bank = self._paths
        warming = r.warm > 0
        remaining = np.where(bank.closed(r.slot), np.inf, bank.length(r.slot) - r.arc)
        # Stop where walking on at a falling speed (linear, over STOP_SECONDS) ends at the end;
        # once stopping, go on until standing unless the path moved on (hysteresis).
        brake = np.maximum(0.5 * r.speed * STOP_SECONDS, MIN_STOP_DISTANCE)
        halt = ~warming & ((remaining <= brake)
                           | ((r.stop > 0) & (remaining <= STOP_DISTANCE)))
        rate = np.where(halt, 1.0, -1.0) / (STOP_SECONDS * self.model_fps)
        before = r.stop
        r.stop = np.where(warming, 0.0, np.clip(r.stop + rate, 0.0, 1.0))
        # An agent standing at the end of its path is not sampled (its window is kept).
        rows = np.flatnonzero(~(halt & (r.stop >= 1.0)))
        context = r.context[rows].copy()
        wait = warming[rows]
        if wait.any():
            context[wait] = self._warm_context(rows[wait])
        v, _ = self._sample(rows, context, self._weights)
        r.warm[rows[wait]] -= 1
        if self.deferred:
            self._warm_more()
        ready = warming & (r.warm == 0)
        if ready.any():
            self._start_walking(np.flatnonzero(ready))
        walk = ~wait
        self._walk(rows[walk], v[torch.as_tensor(walk)].numpy(), before[rows[walk]],
                   remaining[rows[walk]])
        self._update_emotions()

    def _start_walking(self, rows: np.ndarray) -> None:
        """Agents ``rows`` that finished their warm-up: seed frames, body, feet."""
        r = self._rows
        r.seed[rows] = r.window[rows]
        body = self._pose.body(r.window[rows, -1].numpy())
        r.body[rows] = r.body_prev[rows] = body.rotations
        r.height[rows] = r.height_prev[rows] = body.height
        r.arc_prev[rows] = r.arc[rows]
        r.feet[rows] = self._feet.local_feet(body.rotations, body.height)

    def _walk(self, rows: np.ndarray, v: np.ndarray, before: np.ndarray,
              remaining: np.ndarray) -> None:
        """Agents ``rows`` (walking, sampled) placed after their new ``(n, D)`` frames ``v``.

        Each advances by the stance foot (:mod:`~emotive.models.fcrbm.stream_feet`), low-passed
        by :data:`STEP_SMOOTHING`, and blended towards standing by its stop weight; a stopping
        agent advances at least as a linear slowing down would (its remaining distance
        shrinking as ``(1 - stop)^2``), so it stands at the path's end when its weight reaches
        1. The other walking agents stand where they are.

        Args:
            rows: ``(n,)`` batch indices.
            v: ``(n, D)`` their new frames.
            before: ``(n,)`` their stop weights before this frame.
            remaining: ``(n,)`` metres to the end of their paths (``inf``: closed).
        """
        r = self._rows
        last = r.speed[rows] / self.model_fps
        still = np.flatnonzero(r.warm == 0)
        r.body_prev[still], r.height_prev[still] = r.body[still], r.height[still]
        r.arc_prev[still] = r.arc[still]
        r.speed[still] = 0.0
        if not len(rows):
            return
        body = self._feet.blend(self._pose.body(v), r.stop[rows])
        feet = self._feet.local_feet(body.rotations, body.height)
        forward = np.clip(body.forward, 0.0, MAX_SPEED / self.model_fps)
        step = self._feet.advance(r.feet[rows], feet, forward)
        step = np.clip(step, 0.0, MAX_SPEED / self.model_fps) * r.pace[rows]
        step = last + STEP_SMOOTHING * (step - last)
        stop = r.stop[rows]
        left = np.where(stop > before, (1.0 - stop) / np.maximum(1.0 - before, 1e-9), 1.0)
        arrive = np.where(np.isfinite(remaining), remaining, 0.0) * (1.0 - left**2)
        step = np.maximum(step * (1.0 - stop), arrive)
        bank, slot = self._paths, r.slot[rows]
        arc = r.arc[rows] + step
        arc = np.where(bank.closed(slot), arc, np.minimum(arc, bank.length(slot)))
        gap = np.linalg.norm(r.offset[rows], axis=1)
        shrink = np.maximum(gap - PATH_MERGE_SLOPE * step, 0.0) / np.maximum(gap, 1e-12)
        r.offset[rows] *= shrink[:, None]
        r.body[rows], r.height[rows], r.feet[rows] = body.rotations, body.height, feet
        r.speed[rows] = (arc - r.arc[rows]) * self.model_fps
        r.arc[rows] = arc

    # ----------------------------------------------------------------------------- stepping

    def step(self) -> FCRBMFrame:
        """Advance every agent by one frame (``1 / fps`` seconds) and return the new frame.

        Agents still warming up (deferred) are not in the frame.
        """
        with single_thread(), torch.no_grad():
            self._frames += 1
            now = self._frames / self.fps
            while self._model_frames / self.model_fps < now - 1e-9:
                self._model_step()
            weight = 1.0 - (self._model_frames / self.model_fps - now) * self.model_fps
            return self._frame(min(max(weight, 0.0), 1.0))

    def _frame(self, weight: float) -> FCRBMFrame:
        """The walking agents placed ``weight`` of the way from the last model frame but one."""
        r = self._rows
        rows = np.flatnonzero(r.warm == 0)
        body, height, arc = r.body[rows], r.height[rows], r.arc[rows]
        if weight < 1.0:
            body = nlerp(r.body_prev[rows], body, weight)
            height = r.height_prev[rows] + weight * (height - r.height_prev[rows])
            arc = r.arc_prev[rows] + weight * (arc - r.arc_prev[rows])
        slot = r.slot[rows]
        xz = self._paths.position(slot, arc) + r.offset[rows]
        placed = self._pose.place(body, height, self._paths.heading(slot, arc), xz)
        rotations, world, lock = self._feet.lock(lock_state(r, rows), placed.rotations,
                                                 placed.world, r.speed[rows], self.fps)
        store_lock(r, rows, lock)
        return FCRBMFrame(tuple(self._order[k] for k in rows), rotations, placed.positions,
                          world, r.weights[rows], xz, r.va[rows])
