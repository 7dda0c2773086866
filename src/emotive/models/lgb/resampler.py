"""Per-emotion resampling of end-effector trajectories, rebuilt into whole-body motion by IK.

Issue 7, section 2 (paper sections 5.2 and 5.3). For one emotional state:

1. **Features.** Every clip's pelvis path and chain targets become one ``(T, F)`` feature row
   per frame (:mod:`emotive.models.lgb.features`). Every clip is put on the first clip's rig
   first: the files of one data set may differ in their end sites (Bandai Namco's ``normal``
   clips have 5-10 cm hand, toe and head tips, the others none), and mixed end sites put the
   hand-tip and toe targets where the rebuilt rig cannot reach them.
2. **Closed sequence.** The clips are joined into one closed, continuous sequence by
   cross-fades (:func:`~emotive.models.lgb.blending.close_sequences`,
   :func:`~emotive.models.lgb.blending.pose_junctions`).
3. **Resampling.** Four processes are resampled independently, each by a
   :class:`~emotive.models.lgb.bootstrap.LocalGridBootstrap` (the paper's processes; orders and
   lags in :data:`ORDERS` and :data:`LAGS`), each from its own random stream spawned from the
   seed, so the result does not depend on the order or the process they run in:

   ========== ==== ========= ======================================= ========================
   process    D    order/lag state                                   passengers
   ========== ==== ========= ======================================= ========================
   head       3    3 / 1     head (pelvis frame)                     neck, shoulders,
                                                                     clavicles
   left_arm   6    2 / 5     left elbow and wrist (chest frame)      left hand tip
   right_arm  6    2 / 5     right elbow and wrist (chest frame)     right hand tip
   lower_body 9    2 / 5     both ankles (pelvis frame), pelvis      toes, pelvis turn and tilt
                             height and ground step
   ========== ==== ========= ======================================= ========================

   The paper uses order 1 for the arms and the lower body; a state of one position cannot tell
   a forward swing from the backward one, so here those processes also see their observation
   5 frames (1/6 s) earlier (see :mod:`emotive.models.lgb.bootstrap`). The head keeps the
   paper's order 3. The targets the IK chains need but the paper's processes leave out (neck,
   shoulders, hand tips, toes), the clavicles and the rest of the root motion (turn and tilt)
   are passengers: taken from the drawn observations, so they follow them.
   **Not a replay.** Four independent chains can still line up on one captured passage, or
   hold a near-still pose that a take also holds. The guard (:meth:`EmotionResampler
   .sample_features`, :mod:`emotive.models.lgb.novelty`) compares every 5th 1-s window of the
   resampled head, wrists and ankles with every captured window of the emotion and redraws
   the stretches that come within 10 % of how close two distinct captured clips come (their
   5th percentile); on the Bandai data this redraws a few dozen stretches per 30,000 frames.
4. **Continuity.** Where a chain jumps to another passage, its offset fades over about 10
   frames (:data:`~emotive.models.lgb.blending.CARRY`, :mod:`emotive.models.lgb.blending`).
5. **IK.** The arm targets are moved with their anchor onto the rebuilt shoulders and the
   whole body is rebuilt by IK in chunks that can run in parallel worker processes
   (:mod:`emotive.models.lgb.rebuild`); the motion does not depend on the number of workers.

Legend: ``T`` frames, ``F`` features per frame, ``M`` targets of a chain, ``k`` joints.
"""

from __future__ import annotations

import difflib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from emotive.core.motion import Motion
from emotive.data.emotion import canonical_label
from emotive.errors import EmotionError
from emotive.ik import PelvisTrajectory, Trajectories, resolve_chains
from emotive.ik.api import IKResult
from emotive.models.lgb.blending import (
    BLEND_FRAMES,
    CARRY,
    blend_jumps,
    close_sequences,
    pose_junctions,
)
from emotive.models.lgb.bootstrap import (
    LGBError,
    LGBSample,
    LocalGridBootstrap,
    TooLittleDataError,
    carry_offsets,
    check_finite,
    min_observations,
)
from emotive.models.lgb.features import (
    Column,
    chain_anchors,
    chain_links,
    clip_features,
    effector_columns,
    feature_layout,
    layout_columns,
)
from emotive.models.lgb.novelty import (
    EFFECTORS,
    WINDOW_SECONDS,
    NoveltyReference,
    NoveltyReport,
)
from emotive.models.lgb.rebuild import rebuild_in_chunks

if TYPE_CHECKING:
    from emotive.data.clips import Clip
    from emotive.ik import Chain, Trajectories

__all__ = [
    "GUARD_HOP",
    "GUARD_MARGIN",
    "GUARD_PAD",
    "GUARD_ROUNDS",
    "LAGS",
    "ORDERS",
    "PELVIS_BLOCKS",
    "PROCESSES",
    "PROCESS_CHAINS",
    "RULE",
    "EmotionResampler",
    "ResampleResult",
    "Resampled",
]


#: Order of each process's Markov chain (paper: 3 for the head, 1 for the others; see the
#: module docstring for why the others use 2).
ORDERS: dict[str, int] = {"head": 3, "left_arm": 2, "right_arm": 2, "lower_body": 2}
#: Frames between the observations of a state (the paper's states: 1).
LAGS: dict[str, int] = {"head": 1, "left_arm": 5, "right_arm": 5, "lower_body": 5}

#: Next-state rule of the bootstraps (``"barycentre"``: the paper's, which stalls on these data).
RULE = "successor"

#: Not-a-replay guard (:mod:`emotive.models.lgb.novelty`): windows are checked every this many
#: frames; a window within this factor of the threshold has the stretch around it redrawn
#: (this many window lengths each side in the first round, growing by as much each round), for
#: at most this many rounds.
GUARD_HOP = 5
GUARD_MARGIN = 1.1
GUARD_PAD = 0.5
GUARD_ROUNDS = 16

#: Process name -> (state blocks, passenger blocks) of the feature layout. Blocks a rig does
#: not have (a chain without link joints) are left out.
PROCESSES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "head": (
        ("head_torso:head",),
        ("head_torso:l_shoulder", "head_torso:r_shoulder", "head_torso:neck",
         "anchor:head_torso", "link:left_arm", "link:right_arm"),
    ),
    "left_arm": (
        ("left_arm:l_elbow", "left_arm:l_wrist"), ("left_arm:l_handtip", "anchor:left_arm")
    ),
    "right_arm": (
        ("right_arm:r_elbow", "right_arm:r_wrist"), ("right_arm:r_handtip", "anchor:right_arm")
    ),
    "lower_body": (
        ("left_leg:l_ankle", "right_leg:r_ankle", "pelvis:height", "pelvis:step"),
        ("left_leg:l_toe", "right_leg:r_toe", "pelvis:turn", "pelvis:tilt", "anchor:left_leg",
         "anchor:right_leg"),
    ),
}
#: Chains whose joints each process moves (its link joints included).
PROCESS_CHAINS: dict[str, tuple[str, ...]] = {
    "head": ("head_torso",), "left_arm": ("left_arm",), "right_arm": ("right_arm",),
    "lower_body": ("left_leg", "right_leg"),
}
#: Blocks of the pelvis path (carried in feature space).
PELVIS_BLOCKS = ("pelvis:height", "pelvis:step", "pelvis:turn", "pelvis:tilt")


class Resampled(NamedTuple):
    """What :meth:`EmotionResampler.sample_features` returns.

    Attributes:
        features: ``(T, F)`` resampled feature rows.
        samples: process name -> its sample (``index`` gives the drawn observations of
            :attr:`EmotionResampler.observed`).
        novelty: the not-a-replay guard's report (None when it did not run).
    """

    features: np.ndarray
    samples: dict[str, LGBSample]
    novelty: NoveltyReport | None


@dataclass(frozen=True)
class ResampleResult(IKResult):
    """:class:`~emotive.ik.IKResult` of resampled motion, with the guard's report.

    :class:`~emotive.ik.IKResult` of resampled motion, with the not-a-replay guard's report
    (None when it did not run).
    """

    novelty: NoveltyReport | None = None


@dataclass(eq=False)
class EmotionResampler:
    """Local Grid Bootstrap of one emotional state's trajectories, rebuilt by IK.

    Build it with :meth:`fit`. Attributes:
        emotion: the emotional state.
        reference: one frame of the data's rig (it supplies the joints that neither a chain nor
            a process drives, and the rig written out).
        chains: the IK chains on that rig.
        observed: ``(T, F)`` closed observed feature sequence.
        bootstraps: process name -> fitted bootstrap.
        fps: frame rate of the data.
        layout: the feature blocks of :attr:`observed`.
        carry: see :data:`CARRY`.
        novelty: the captured windows and not-a-replay threshold of the emotion (None when
            the rig lacks one of the compared effectors).
    """

    emotion: str
    reference: Motion
    chains: dict[str, Chain]
    observed: np.ndarray
    bootstraps: dict[str, LocalGridBootstrap]
    fps: float
    layout: dict[str, Column] = field(repr=False)
    carry: float = CARRY
    novelty: NoveltyReference | None = field(default=None, repr=False)

    @classmethod
    def fit(
        cls,
        clips: Sequence[Clip],
        emotion: str,
        *,
        blend: int = BLEND_FRAMES,
        orders: dict[str, int] | None = None,
        lags: dict[str, int] | None = None,
        carry: float = CARRY,
        rule: str = RULE,
        role_map: Any = None,
        source: str = "",
    ) -> EmotionResampler:
        """Fit the four processes on the clips of one emotional state.

        Args:
            clips: clips (any emotions; only those labelled ``emotion`` are used).
            emotion: the emotional state, any spelling :func:`canonical_label` accepts.
            blend: frames of each cross-fade between clips.
            orders: process -> Markov order, over :data:`ORDERS`.
            lags: process -> frames between a state's observations, over :data:`LAGS`.
            carry: see :data:`CARRY`.
            rule: see :data:`RULE`.
            role_map: as for :func:`emotive.core.roles.resolve_roles`.
            source: where the clips come from (a data set name), for error messages.

        Returns:
            The fitted resampler.

        Raises:
            EmotionError: no clip has that emotion.
            TooLittleDataError: the emotion's joined sequence is shorter than the bootstraps
                need (:func:`~emotive.models.lgb.bootstrap.min_observations`).
            LGBError: NaN in the trajectories, or clips on different rigs.
        """
        label = canonical_label(emotion)
        orders = {**ORDERS, **(orders or {})}
        lags = {**LAGS, **(lags or {})}
        where = f" in {source}" if source else ""
        mine = [c for c in clips if c.info.emotion == label]
        if not mine:
            known = sorted({c.info.emotion for c in clips})
            close = difflib.get_close_matches(label, known, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise EmotionError(f"no clips of emotion {label!r}{where}{hint}; choose one of "
                               f"{known}")
        usable = [c for c in mine if c.motion.num_frames > 2 * blend]
        have = sum(c.motion.num_frames for c in usable) - blend * len(usable)
        need = max(min_observations(orders[p], lag=lags[p]) for p in PROCESSES)
        if have < need:
            raise TooLittleDataError(
                f"emotion {label!r}{where} ({len(mine)} clip{'s' if len(mine) != 1 else ''})",
                max(have, 0), need,
                "the closed sequence of its clips must hold twice the 100 states of the largest "
                "neighbourhood plus the frames of one state; add clips of this emotion",
            )
        first = usable[0].motion
        rig = first.skeleton
        other = [c.info.name for c in usable if c.motion.skeleton.names != rig.names
                 or not np.array_equal(c.motion.skeleton.parents, rig.parents)]
        if other:
            raise LGBError(f"clips {other[:3]} are not on the rig of {usable[0].info.name}; "
                           "resample clips of one rig")
        # One rig for all: the files of one data set may differ in their end sites (Bandai
        # Namco's "normal" clips have 5-10 cm hand, toe and head tips, the others none), which
        # would put the hand-tip and toe targets where the rebuilt rig cannot reach.
        motions = [c.motion.replace(skeleton=rig) for c in usable]
        # Chain neutral poses and hinge axes from every frame of the emotion.
        reference = first.replace(rotations=np.concatenate([m.rotations for m in motions]),
                                  positions=np.concatenate([m.positions for m in motions]))
        chains = resolve_chains(first.skeleton, reference, role_map)
        layout = feature_layout(chains, first.skeleton.parents)
        rows = []
        for clip, motion in zip(usable, motions, strict=True):
            f = clip_features(motion, chains, layout, role_map)
            check_finite(f"trajectories of clip {clip.info.name}", f)
            rows.append(f)
        observed = close_sequences(rows, blend)
        pose_junctions(observed, motions, chains, layout, blend, role_map)
        # The chain processes draw observed successors; continuity comes from CARRY (step 4).
        boot_carry = 0.0 if rule == "successor" else carry
        boots = {}
        for name, (state, passengers) in PROCESSES.items():
            boots[name] = LocalGridBootstrap(
                order=orders[name], lag=lags[name], carry=boot_carry, rule=rule
            ).fit(
                observed[:, layout_columns(layout, state)],
                observed[:, layout_columns(layout, passengers)],
                name=f"emotion {label!r}, process {name}",
            )
        ref0 = first.replace(rotations=first.rotations[:1].copy(),
                             positions=first.positions[:1].copy())
        novelty = None
        if all(k in layout for k in EFFECTORS):
            length = max(2, round(WINDOW_SECONDS * first.fps))
            novelty = NoveltyReference.fit([r[:, effector_columns(layout)] for r in rows], length)
        return cls(label, ref0, chains, observed, boots, float(first.fps), layout, carry,
                   novelty)

    def sample_features(
        self, frames: int, seed: int | np.random.Generator | np.random.SeedSequence = 0
    ) -> Resampled:
        """Resample ``frames`` feature rows, with the not-a-replay guard.

        The guard (successor rule, when :attr:`novelty` is known): every
        :data:`GUARD_HOP`-th window of the effector points whose distance to the nearest
        captured window is within :data:`GUARD_MARGIN` of the threshold has the stretch around
        it redrawn for every process (from the frame before the stretch, with a stream of its
        own), up to :data:`GUARD_ROUNDS` rounds; the chains then jump back to their own draws
        at the stretch's end, and those jumps fade like any other. The points checked are the
        drawn observations with each jump's offset fading (:data:`CARRY`), as the rebuilt
        motion will have them.

        Args:
            frames: ``T``, any length.
            seed: the seed (or generator, or seed sequence) every draw comes from; each process
                gets its own stream spawned from it, and the guard one more.

        Returns:
            The rows, each process's sample and the guard's report.

        Raises:
            LGBError: ``frames < 0``.
        """
        *streams, guard_stream = _streams(seed, len(PROCESSES) + 1)
        samples = {name: self.bootstraps[name].sample(frames, rng)
                   for name, rng in zip(PROCESSES, streams, strict=True)}
        report = None
        if self.novelty is not None and all(
                b.rule == "successor" for b in self.bootstraps.values()):
            samples, report = self._guard(samples, frames, guard_stream)
        out = np.empty((frames, self.observed.shape[1]))
        for name, (state, passengers) in PROCESSES.items():
            out[:, layout_columns(self.layout, state)] = samples[name].states
            out[:, layout_columns(self.layout, passengers)] = samples[name].passengers
        if self.bootstraps["lower_body"].rule == "successor" and frames:
            index = samples["lower_body"].index
            cols = layout_columns(self.layout, PELVIS_BLOCKS)
            out[:, cols] = carry_offsets(self.observed[:, cols], index, self.carry, index[0] - 1)
        tilt = out[:, self.layout["pelvis:tilt"].slice]
        tilt /= np.linalg.norm(tilt, axis=-1, keepdims=True)
        return Resampled(out, samples, report)

    def _guard(
        self, samples: dict[str, LGBSample], frames: int, rng: np.random.Generator
    ) -> tuple[dict[str, LGBSample], NoveltyReport]:
        """Redraw the stretches that come too close to a captured window.

        Redraw the stretches that come too close to a captured window (see
        :meth:`sample_features`).
        """
        ref = self.novelty
        index = {name: s.index.copy() for name, s in samples.items()}
        owner = {k: next(p for p, (state, _) in PROCESSES.items() if k in state)
                 for k in EFFECTORS}
        cols = {k: self.layout[k].slice for k in EFFECTORS}
        pad = max(1, round(GUARD_PAD * ref.length))
        limit = ref.threshold * GUARD_MARGIN
        redrawn = rounds = 0
        while True:
            # The jumps' offsets fade as they will in the rebuilt motion (smooth_jumps).
            points = np.concatenate([
                carry_offsets(self.observed[:, cols[k]], index[owner[k]], self.carry,
                              index[owner[k]][0] - 1) for k in EFFECTORS], axis=1)
            starts, dist = ref.novelty(points, GUARD_HOP)
            bad = starts[dist <= limit]
            if not len(bad) or rounds == GUARD_ROUNDS:
                break
            rounds += 1
            # A spot that stays too close after a redraw gets a wider one.
            grow = pad * rounds
            for a, b in _merge_spans(bad - grow, bad + ref.length + grow, frames):
                for name, boot in self.bootstraps.items():
                    start = index[name][a - 1] if a else None
                    index[name][a:b] = boot.sample(b - a, rng, start=start).index
                redrawn += 1
        report = NoveltyReport(
            threshold=ref.threshold, windows=len(starts), redrawn=redrawn, rounds=rounds,
            closest=float(dist.min()) if len(dist) else math.inf,
            below=int((dist <= ref.threshold).sum()),
        )
        out = {}
        for name, (state, passengers) in PROCESSES.items():
            rows = self.observed[index[name]]
            out[name] = LGBSample(rows[:, layout_columns(self.layout, state)], index[name],
                                  rows[:, layout_columns(self.layout, passengers)])
        return out, report

    def base_motion(self, features: np.ndarray) -> Motion:
        """``T`` frames of the reference pose with the link joints (clavicles) of the rows."""
        n = len(features)
        ref = self.reference
        rot = np.repeat(ref.rotations[:1], n, axis=0)
        parents = ref.skeleton.parents
        for key, col in self.layout.items():
            if key.startswith("link:"):
                links = chain_links(self.chains[key.split(":")[1]], parents)
                q = features[:, col.slice].reshape(n, len(links), 4)
                rot[:, links] = q / np.linalg.norm(q, axis=-1, keepdims=True)
        meta = {**ref.metadata, "name": f"lgb-{self.emotion}", "emotion": self.emotion}
        return Motion(ref.skeleton, rot, np.repeat(ref.positions[:1], n, axis=0), self.fps, meta)

    def trajectories(self, features: np.ndarray, base: Motion | None = None) -> Trajectories:
        """Feature rows back to :class:`~emotive.ik.Trajectories`.

        Feature rows back to :class:`~emotive.ik.Trajectories` (pelvis starting at the
        origin, facing +Z).

        Args:
            features: ``(T, F)`` rows.
            base: from :meth:`base_motion` (built if None); each chain's targets move with the
                difference between its anchor on this pose and the sampled anchor.
        """
        n = len(features)
        lay = self.layout
        base = self.base_motion(features) if base is None else base

        def block(key: str) -> np.ndarray:
            return features[:, lay[key].slice]

        step = block("pelvis:step").copy()
        turn = block("pelvis:turn")[:, 0].copy()
        # Frame 0 carries no step from a previous frame.
        step[:1], turn[:1] = 0.0, 0.0
        height = block("pelvis:height")[:, 0].copy()
        pelvis = PelvisTrajectory(height, step, turn, block("pelvis:tilt").copy(),
                                  np.array([0.0, height[0] if n else 0.0, 0.0]), 0.0)
        anchors = chain_anchors(base, self.chains)
        targets = {}
        for name, c in self.chains.items():
            pts = np.stack([block(f"{name}:{r}") for r in c.target_roles], 1).reshape(n, -1, 3)
            shift = anchors[name] - block(f"anchor:{name}")
            targets[name] = pts + shift[:, None, :]
        return Trajectories(pelvis, targets)

    def rebuild(
        self,
        traj: Trajectories,
        base: Motion | None = None,
        *,
        workers: int = 1,
        chunk: int | None = None,
        progress: Callable[[int, int], None] | None = None,
        role_map: Any = None,
        **solver: Any,
    ) -> IKResult:
        """Whole-body motion on the reference rig following sampled trajectories.

        The pelvis is integrated from its path, the joints outside the chains keep ``base``'s
        rotations, and the five chains are solved from their targets, in chunks
        (:func:`~emotive.models.lgb.rebuild.rebuild_in_chunks`).

        Args:
            traj: from :meth:`trajectories`, ``T`` frames.
            base: ``T`` frames from :meth:`base_motion`; the reference pose if None.
            workers: worker processes solving chunks side by side (1: in this process). The
                result does not depend on it.
            chunk: frames per chunk; :func:`~emotive.models.lgb.rebuild.chunk_starts` if None.
            progress: called with ``(frames done, T)`` after each solved chunk.
            role_map: as for :func:`emotive.core.roles.resolve_roles`.
            **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

        Returns:
            The IK result; its motion is at the data's frame rate, and ``seconds`` is the wall
            time of the whole rebuild.

        Raises:
            LGBError: ``workers`` or ``chunk`` below 1.
        """
        began = time.perf_counter()
        n = len(traj.pelvis.height)
        base = self.base_motion(np.repeat(self.observed[:1], n, axis=0)) if base is None else base
        result = rebuild_in_chunks(base, self.chains, traj, workers=workers, chunk=chunk,
                                   progress=progress, role_map=role_map, **solver)
        return replace(result, seconds=time.perf_counter() - began)

    def smooth_jumps(self, result: IKResult, samples: dict[str, LGBSample]) -> IKResult:
        """Fade each process's jumps in its joints' rotations (:func:`blend_jumps`).

        Args:
            result: the rebuilt motion of the samples.
            samples: from :meth:`sample_features`.

        Returns:
            ``result`` with the blended motion (residuals and reports are the IK's).
        """
        rot = result.motion.rotations.copy()
        parents = self.reference.skeleton.parents
        for name, s in samples.items():
            if self.bootstraps[name].rule != "successor" or not len(s.index):
                continue
            n_obs = len(self.observed)
            jumps = np.concatenate(([False], np.diff(s.index) % n_obs != 1))
            joints = np.concatenate([self.chains[c].joints for c in PROCESS_CHAINS[name]])
            if name == "head":
                links = [chain_links(c, parents) for c in self.chains.values()]
                joints = np.concatenate([joints, *links])
            rot[:, joints] = blend_jumps(rot[:, joints], jumps, self.carry)
        return replace(result, motion=result.motion.replace(rotations=rot))

    def generate(
        self,
        frames: int,
        seed: int | np.random.Generator | np.random.SeedSequence = 0,
        progress: Callable[[int, int], None] | None = None,
        *,
        workers: int = 1,
        chunk: int | None = None,
        **solver: Any,
    ) -> ResampleResult:
        """Resample ``frames`` frames and rebuild them into whole-body motion.

        Args:
            frames: ``T``, any length.
            seed: seed (or generator) of the draws; the same seed gives the same motion,
                whatever ``workers``.
            progress: called with ``(frames done, frames)`` after each solved chunk.
            workers: worker processes for the IK (see :meth:`rebuild`).
            chunk: frames per IK chunk (see :meth:`rebuild`).
            **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

        Returns:
            The IK result (motion, residuals, unreachable and off-target frames) and the
            not-a-replay guard's report; ``seconds`` is the wall time of resampling and
            rebuilding.

        Raises:
            LGBError: ``frames < 1``.
        """
        if frames < 1:
            raise LGBError(f"the number of frames must be >= 1, got {frames}")
        began = time.perf_counter()
        features, samples, report = self.sample_features(frames, seed)
        base = self.base_motion(features)
        result = self.rebuild(self.trajectories(features, base), base, workers=workers,
                              chunk=chunk, progress=progress, **solver)
        result = self.smooth_jumps(result, samples)
        fields = {f.name: getattr(result, f.name) for f in dataclass_fields(result)}
        return ResampleResult(**fields | {"seconds": time.perf_counter() - began},
                              novelty=report)


def _merge_spans(starts: np.ndarray, ends: np.ndarray, frames: int) -> list[tuple[int, int]]:
    """Sorted ``[a, b)`` spans, clipped to ``[0, frames)``, overlapping ones merged."""
    spans: list[tuple[int, int]] = []
    for a, b in sorted(zip(np.maximum(starts, 0).tolist(),
                           np.minimum(ends, frames).tolist(), strict=True)):
        if spans and a <= spans[-1][1]:
            spans[-1] = (spans[-1][0], max(spans[-1][1], b))
        else:
            spans.append((a, b))
    return spans


def _streams(
    seed: int | np.random.Generator | np.random.SeedSequence, count: int
) -> list[np.random.Generator]:
    """``count`` independent generators from one seed."""
    if isinstance(seed, np.random.Generator):
        return seed.spawn(count)
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return [np.random.default_rng(s) for s in seq.spawn(count)]
