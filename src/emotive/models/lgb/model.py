"""Per-emotion resampling of end-effector trajectories, rebuilt into whole-body motion by IK.

Issue 7, section 2 (paper sections 5.2 and 5.3). For one emotional state:

1. **Features.** Every clip's pelvis path and chain targets (end effectors, elbows, shoulders,
   neck) are extracted in their chain frames (:func:`emotive.ik.extract_trajectories`) and laid
   out as one ``(T, F)`` feature row per frame (:func:`clip_features`), with two kinds of
   bookkeeping columns: each chain's *anchor* (its first joint in the chain's frame) and the
   local rotations of the *link* joints between a chain's frame and its first joint (the
   clavicles between the chest and the arms), which no chain drives. Every clip is put on the
   first clip's rig first: the files of one data set may differ in their end sites (Bandai
   Namco's ``normal`` clips have 5-10 cm hand, toe and head tips, the others none), and mixed
   end sites put the hand-tip and toe targets where the rebuilt rig cannot reach them.
2. **Closed sequence.** The clips are joined into one closed, continuous sequence: the last
   ``blend`` frames of each clip are cross-faded into the first ``blend`` frames of the next,
   and the last clip into the first (paper section 5.3). The pelvis path (stored as per-frame
   steps) is cross-faded as features; the poses are cross-faded as joint rotations (slerp) and
   their targets recomputed (:func:`pose_junctions`), which keeps every bone length.
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
4. **Continuity.** The bootstraps draw observed successors (the successor rule). Where a chain
   jumps to another passage, its offset fades over about 10 frames (:data:`CARRY`): for the
   pelvis path in feature space (:func:`~emotive.models.lgb.bootstrap.carry_offsets`), for the
   chains after the IK in joint-rotation space (:func:`blend_jumps`). Blending target positions
   instead shortens and stretches the limbs (on sad, forearms off by 1-2 cm in the median frame
   the IK then missed by more than 1 cm); rotations keep every bone length.
5. **IK.** The pelvis is put back in the world (:func:`emotive.ik.integrate_pelvis`), the arm
   targets are moved with their anchor onto the rebuilt shoulders, and the five chains are
   solved from the targets (:func:`emotive.ik.solve_chains`), in chunks (:func:`chunk_starts`)
   that can run in parallel worker processes; each chunk but the first starts
   :data:`OVERLAP_FRAMES` frames early and drops them, so that its first kept frame is
   warm-started. The chunks depend on the length only, not on the number of workers, so
   neither does the motion.

Legend: ``T`` frames, ``F`` features per frame, ``M`` targets of a chain, ``k`` joints.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from emotive.core.motion import Motion
from emotive.errors import EmotionError
from emotive.ik.api import IKResult
from emotive.models.lgb.bootstrap import (
    LGBError,
    LGBSample,
    LocalGridBootstrap,
    TooLittleDataError,
    carry_offsets,
    check_finite,
    min_observations,
)
from emotive.models.lgb.novelty import (
    EFFECTORS,
    WINDOW_SECONDS,
    NoveltyReference,
    NoveltyReport,
)

if TYPE_CHECKING:
    from emotive.data.clips import Clip
    from emotive.ik import Chain, Trajectories

#: Order of each process's Markov chain (paper: 3 for the head, 1 for the others; see the
#: module docstring for why the others use 2).
ORDERS: dict[str, int] = {"head": 3, "left_arm": 2, "right_arm": 2, "lower_body": 2}
#: Frames between the observations of a state (the paper's states: 1).
LAGS: dict[str, int] = {"head": 1, "left_arm": 5, "right_arm": 5, "lower_body": 5}

#: Fraction of a jump's offset kept per frame (see the module docstring): a jump between
#: passages fades over about 10 frames, a third of a second.
CARRY = 0.9
#: Next-state rule of the bootstraps (``"barycentre"``: the paper's, which stalls on these data).
RULE = "successor"

#: Most frames per IK chunk (the unit of parallel work and of progress reports). The solver's
#: cost per call is mostly fixed overhead (one sequential pass over a 40-frame segment per
#: chain), so few long chunks are fastest: a clip is cut into an even number of chunks (two
#: workers share them evenly), each at most this long; clips up to :data:`SPLIT_FRAMES` frames
#: are one chunk.
CHUNK_FRAMES = 15000
#: Longest clip solved as one chunk.
SPLIT_FRAMES = 3000
#: Frames each chunk but the first solves before its own first frame and drops.
OVERLAP_FRAMES = 16

#: Not-a-replay guard (:mod:`emotive.models.lgb.novelty`): windows are checked every this many
#: frames; a window within this factor of the threshold has the stretch around it redrawn
#: (this many window lengths each side in the first round, growing by as much each round), for
#: at most this many rounds.
GUARD_HOP = 5
GUARD_MARGIN = 1.1
GUARD_PAD = 0.5
GUARD_ROUNDS = 16

#: Frames cross-faded at each junction between clips (half a second at 30 fps).
BLEND_FRAMES = 15

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


@dataclass(frozen=True)
class _Column:
    """Columns of one named block of the ``(T, F)`` feature layout."""

    start: int
    width: int

    @property
    def slice(self) -> slice:
        return slice(self.start, self.start + self.width)


def chain_links(chain: Chain, parents: np.ndarray) -> np.ndarray:
    """``(L,)`` joints strictly between a chain's frame joint and its first joint, nearest the
    frame first (the clavicle of an arm); empty when the frame is the first joint's parent or
    not its ancestor."""
    out, j = [], int(parents[chain.joints[0]])
    while j >= 0 and j != chain.frame:
        out.append(j)
        j = int(parents[j])
    return np.array(out[::-1] if j == chain.frame else [], dtype=np.int64)


def _layout(chains: dict[str, Chain], parents: np.ndarray) -> dict[str, _Column]:
    """Feature blocks: ``chain:role`` targets (3 columns each), ``anchor:chain`` (3 each),
    ``link:chain`` (4 per link joint, chains with links only), then the pelvis path."""
    blocks: list[tuple[str, int]] = [
        (f"{name}:{role}", 3) for name, c in chains.items() for role in c.target_roles
    ]
    blocks += [(f"anchor:{name}", 3) for name in chains]
    blocks += [(f"link:{name}", 4 * len(chain_links(c, parents))) for name, c in chains.items()
               if len(chain_links(c, parents))]
    blocks += [("pelvis:height", 1), ("pelvis:step", 2), ("pelvis:turn", 1), ("pelvis:tilt", 4)]
    out, start = {}, 0
    for name, width in blocks:
        out[name] = _Column(start, width)
        start += width
    return out


def _columns(layout: dict[str, _Column], blocks: Sequence[str]) -> np.ndarray:
    """Columns of the blocks of ``layout`` among ``blocks``."""
    return np.concatenate([np.arange(layout[b].start, layout[b].start + layout[b].width)
                           for b in blocks if b in layout])


def chain_anchors(motion: Motion, chains: dict[str, Chain]) -> dict[str, np.ndarray]:
    """Chain name -> ``(T, 3)`` position of the chain's first joint in the chain's frame.

    For the arms it moves with the clavicle: :meth:`EmotionResampler.trajectories` moves each
    arm's sampled targets with the difference between the rebuilt anchor and the sampled one,
    so that they keep their sampled place relative to the shoulder.
    """
    from emotive.ik import to_frame

    grot, gpos = motion.global_transforms()
    return {
        name: to_frame(gpos[:, c.joints[:1]], grot[:, c.frame], gpos[:, c.frame])[:, 0]
        for name, c in chains.items()
    }


def _hemisphere(q: np.ndarray) -> np.ndarray:
    """Quaternions ``(..., 4)`` with ``w >= 0`` (one sign, so that blends stay short)."""
    return np.where(q[..., :1] < 0, -q, q)


def clip_features(
    motion: Motion, chains: dict[str, Chain], layout: dict[str, _Column], role_map: Any = None
) -> np.ndarray:
    """``(T, F)`` feature rows of a clip (see :func:`_layout`)."""
    from emotive.ik import extract_trajectories

    traj = extract_trajectories(motion, chains, role_map)
    n = len(traj.pelvis.height)
    anchors = chain_anchors(motion, chains)
    out = np.empty((n, sum(c.width for c in layout.values())))
    pelvis = {"height": traj.pelvis.height, "step": traj.pelvis.displacement,
              "turn": traj.pelvis.turn, "tilt": _hemisphere(traj.pelvis.tilt)}
    for key, col in layout.items():
        group, role = key.split(":")
        if group == "pelvis":
            out[:, col.slice] = np.reshape(pelvis[role], (n, -1))
        elif group == "anchor":
            out[:, col.slice] = anchors[role]
        elif group == "link":
            links = chain_links(chains[role], motion.skeleton.parents)
            out[:, col.slice] = _hemisphere(motion.rotations[:, links]).reshape(n, -1)
        else:
            targets = traj.targets[group]
            out[:, col.slice] = targets[:, chains[group].target_roles.index(role)]
    return out


def _smoothstep(blend: int) -> np.ndarray:
    """``(blend,)`` cross-fade weights of the second sequence, rising from 0 to 1."""
    s = (np.arange(blend) + 0.5) / blend
    return s * s * (3.0 - 2.0 * s)


def close_sequences(features: Sequence[np.ndarray], blend: int = BLEND_FRAMES) -> np.ndarray:
    """Join clips into one closed, continuous sequence by cross-fades.

    The last ``blend`` frames of each clip and the first ``blend`` frames of the next (the first
    clip after the last) are replaced by their smoothstep cross-fade, so every junction,
    including the wrap-around, moves continuously from one clip into the next.

    Args:
        features: ``(T_c, F)`` rows of each clip; each needs more than ``2 * blend`` frames.
        blend: frames of each cross-fade.

    Returns:
        ``(sum(T_c) - blend * C, F)`` rows; its last row is followed by its first.

    Raises:
        LGBError: no clip, a clip too short for the cross-fades, or mismatched widths.
    """
    if not features:
        raise LGBError("no clips to join")
    short = [i for i, f in enumerate(features) if len(f) <= 2 * blend]
    if short or len({f.shape[1] for f in features}) != 1:
        raise LGBError(f"every clip needs more than {2 * blend} frames and the same features; "
                       f"clips {short} are too short")
    w = _smoothstep(blend)[:, None]
    parts = []
    for i, cur in enumerate(features):
        prev = features[i - 1]
        parts.append((1.0 - w) * prev[-blend:] + w * cur[:blend])
        parts.append(cur[blend:-blend])
    return np.concatenate(parts)


def pose_junctions(
    observed: np.ndarray,
    motions: Sequence[Motion],
    chains: dict[str, Chain],
    layout: dict[str, _Column],
    blend: int = BLEND_FRAMES,
    role_map: Any = None,
) -> None:
    """Recompute everything but the pelvis path in the cross-faded frames of
    :func:`close_sequences` from cross-faded poses, in place.

    Cross-fading target positions shortens the limbs between two different poses (on the
    Bandai Namco data by up to several centimetres, which the IK cannot reach); cross-fading
    the joints' local rotations (slerp) keeps every bone length. The motions must share one rig.

    Args:
        observed: ``(sum(T_c) - blend * C, F)`` from :func:`close_sequences` of the motions'
            features.
        motions: the clips, in the order they were joined.
        chains: the IK chains of the rig.
        layout: the feature blocks.
        blend: frames of each cross-fade.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
    """
    from emotive.transforms.np_rotations import quaternion_slerp

    w = _smoothstep(blend)
    cols = _columns(layout, [k for k in layout if not k.startswith("pelvis:")])
    row = 0
    for i, cur in enumerate(motions):
        prev = motions[i - 1]
        a, b = prev.rotations[-blend:], cur.rotations[:blend]
        # The shorter way round: flip the second quaternion where the two disagree in sign.
        b = np.where(np.sum(a * b, -1, keepdims=True) < 0, -b, b)
        rot = quaternion_slerp(a, b, w[:, None])
        ww = w[:, None, None]
        pos = (1.0 - ww) * prev.positions[-blend:] + ww * cur.positions[:blend]
        mixed = cur.replace(rotations=rot, positions=pos)
        observed[row : row + blend, cols] = clip_features(mixed, chains, layout, role_map)[:, cols]
        row += cur.num_frames - blend


def blend_jumps(rotations: np.ndarray, jumps: np.ndarray, carry: float = CARRY) -> np.ndarray:
    """Fade the joint-rotation discontinuities at jumps over the following frames.

    The rotation analogue of :func:`~emotive.models.lgb.bootstrap.carry_offsets`. At a jump
    frame ``t`` the new passage's previous pose is extrapolated back from its own motion,
    ``p = v^-1 q_t`` with ``v = q_{t+1} q_t^-1``, and the offset
    ``O_t = (O_{t-1} q_{t-1} p^-1)^carry`` takes it to where the joint was; between jumps the
    offset decays, ``O_t = O_{t-1}^carry`` (powers scale the rotation angle). The result is
    ``O_t q_t``: continuous in pose and, to first order, in velocity.

    Args:
        rotations: ``(T, k, 4)`` local rotations, ``w, x, y, z``.
        jumps: ``(T,)`` bool, frames that start a new passage (frame 0 is ignored).
        carry: fraction of the offset kept per frame.

    Returns:
        ``(T, k, 4)`` blended rotations.
    """
    from emotive.transforms.np_rotations import (
        axis_angle_to_quaternion,
        quaternion_invert,
        quaternion_multiply,
        quaternion_to_axis_angle,
    )

    n = len(rotations)
    where = np.flatnonzero(np.asarray(jumps, bool)[1:]) + 1
    if not len(where) or not carry or n < 2:
        return rotations.copy()
    logs = np.empty((len(where), *rotations.shape[1:-1], 3))
    last, last_log = None, None
    for m, t in enumerate(where):
        before = rotations[t - 1]
        if last is not None:
            before = quaternion_multiply(
                axis_angle_to_quaternion(last_log * carry ** (t - 1 - last)), before)
        inv_t = quaternion_invert(rotations[t])
        raw = quaternion_multiply(before, inv_t)
        if t + 1 < n:
            raw = quaternion_multiply(raw, quaternion_multiply(rotations[t + 1], inv_t))
        logs[m] = last_log = carry * quaternion_to_axis_angle(raw)
        last = t
    # For every frame from the first jump on: the last jump at or before it, and its age.
    owner = np.searchsorted(where, np.arange(n), side="right") - 1
    out = rotations.copy()
    live = owner >= 0
    age = np.arange(n)[live] - where[owner[live]]
    offset = axis_angle_to_quaternion(logs[owner[live]] * (carry ** age)[:, None, None])
    out[live] = quaternion_multiply(offset, rotations[live])
    return out


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
    """:class:`~emotive.ik.IKResult` of resampled motion, with the not-a-replay guard's report
    (None when it did not run)."""

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
    layout: dict[str, _Column] = field(repr=False)
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
        import difflib

        from emotive.data.emotion import canonical_label
        from emotive.ik import resolve_chains

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
        layout = _layout(chains, first.skeleton.parents)
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
                observed[:, _columns(layout, state)], observed[:, _columns(layout, passengers)],
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
            out[:, _columns(self.layout, state)] = samples[name].states
            out[:, _columns(self.layout, passengers)] = samples[name].passengers
        if self.bootstraps["lower_body"].rule == "successor" and frames:
            index = samples["lower_body"].index
            cols = _columns(self.layout, PELVIS_BLOCKS)
            out[:, cols] = carry_offsets(self.observed[:, cols], index, self.carry, index[0] - 1)
        tilt = out[:, self.layout["pelvis:tilt"].slice]
        tilt /= np.linalg.norm(tilt, axis=-1, keepdims=True)
        return Resampled(out, samples, report)

    def _guard(
        self, samples: dict[str, LGBSample], frames: int, rng: np.random.Generator
    ) -> tuple[dict[str, LGBSample], NoveltyReport]:
        """Redraw the stretches that come too close to a captured window (see
        :meth:`sample_features`)."""
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
            out[name] = LGBSample(rows[:, _columns(self.layout, state)], index[name],
                                  rows[:, _columns(self.layout, passengers)])
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
        """Feature rows back to :class:`~emotive.ik.Trajectories` (pelvis starting at the
        origin, facing +Z).

        Args:
            features: ``(T, F)`` rows.
            base: from :meth:`base_motion` (built if None); each chain's targets move with the
                difference between its anchor on this pose and the sampled anchor.
        """
        from emotive.ik import PelvisTrajectory, Trajectories

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
        rotations, and the five chains are solved from their targets, in chunks (see the module
        docstring).

        Args:
            traj: from :meth:`trajectories`, ``T`` frames.
            base: ``T`` frames from :meth:`base_motion`; the reference pose if None.
            workers: worker processes solving chunks side by side (1: in this process). The
                result does not depend on it.
            chunk: frames per chunk; :func:`chunk_starts` if None.
            progress: called with ``(frames done, T)`` after each solved chunk.
            role_map: as for :func:`emotive.core.roles.resolve_roles`.
            **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

        Returns:
            The IK result; its motion is at the data's frame rate, and ``seconds`` is the wall
            time of the whole rebuild.

        Raises:
            LGBError: ``workers`` or ``chunk`` below 1.
        """
        import time

        from emotive.ik import integrate_pelvis

        if workers < 1 or (chunk is not None and chunk < 1):
            raise LGBError(f"workers and chunk must be >= 1, got {workers} and {chunk}")
        began = time.perf_counter()
        n = len(traj.pelvis.height)
        base = self.base_motion(np.repeat(self.observed[:1], n, axis=0)) if base is None else base
        pos_w, _ = integrate_pelvis(traj.pelvis)
        yaw = traj.pelvis.start_heading + np.cumsum(traj.pelvis.turn)
        starts = chunk_starts(n) if chunk is None else list(range(0, max(n, 1), chunk))
        ends = [*starts[1:], n]
        jobs = []
        for a, b in zip(starts, ends, strict=True):
            a0 = max(a - OVERLAP_FRAMES, 0)
            part = base.replace(rotations=base.rotations[a0:b], positions=base.positions[a0:b])
            jobs.append((part, self.chains, _slice_trajectories(traj, a0, b, pos_w[a0], yaw[a0]),
                         a - a0, role_map, solver))
        if workers == 1 or len(jobs) == 1:
            parts = []
            for job, b in zip(jobs, ends, strict=True):
                parts.append(_solve_chunk(*job))
                if progress is not None:
                    progress(b, n)
        else:
            parts = _run_parallel(jobs, workers, starts, ends, n, progress)
        return _join(parts, starts, base, list(self.chains), time.perf_counter() - began)

    def smooth_jumps(self, result: IKResult, samples: dict[str, LGBSample]) -> IKResult:
        """Fade each process's jumps in its joints' rotations (:func:`blend_jumps`).

        Args:
            result: the rebuilt motion of the samples.
            samples: from :meth:`sample_features`.

        Returns:
            ``result`` with the blended motion (residuals and reports are the IK's).
        """
        from dataclasses import replace

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
        import time

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


def effector_columns(layout: dict[str, _Column]) -> np.ndarray:
    """Feature columns of the not-a-replay effector points (:data:`EFFECTORS`), ``(3P,)``."""
    return _columns(layout, EFFECTORS)


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


def chunk_starts(frames: int) -> list[int]:
    """First frame of each IK chunk of a ``frames``-frame clip: one chunk up to
    :data:`SPLIT_FRAMES` frames, else an even number of equal chunks of at most
    :data:`CHUNK_FRAMES` frames."""
    if frames <= SPLIT_FRAMES:
        return [0]
    count = 2 * math.ceil(frames / (2 * CHUNK_FRAMES))
    return [round(i * frames / count) for i in range(count)]


def _streams(
    seed: int | np.random.Generator | np.random.SeedSequence, count: int
) -> list[np.random.Generator]:
    """``count`` independent generators from one seed."""
    if isinstance(seed, np.random.Generator):
        return seed.spawn(count)
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return [np.random.default_rng(s) for s in seq.spawn(count)]


def _slice_trajectories(
    traj: Trajectories, a: int, b: int, start: np.ndarray, heading: float
) -> Trajectories:
    """Frames ``a:b`` of ``traj``, starting at world position ``start`` facing ``heading``."""
    from emotive.ik import PelvisTrajectory, Trajectories

    p = traj.pelvis
    step, turn = p.displacement[a:b].copy(), p.turn[a:b].copy()
    step[:1], turn[:1] = 0.0, 0.0
    pelvis = PelvisTrajectory(p.height[a:b], step, turn, p.tilt[a:b], np.array(start, float),
                              float(heading))
    return Trajectories(pelvis, {k: v[a:b] for k, v in traj.targets.items()})


def _solve_chunk(
    base: Motion,
    chains: dict[str, Chain],
    traj: Trajectories,
    keep: int,
    role_map: Any,
    solver: dict[str, Any],
) -> tuple:
    """Rebuild one chunk and drop its first ``keep`` frames (runs in a worker process).

    Returns:
        ``(rotations, positions, residuals, unreachable, iterations, off_target)`` of the kept
        frames, frame numbers relative to the first kept frame.
    """
    from emotive.ik import Unreachable, rebuild

    r = rebuild(base, traj, chains, role_map=role_map, **solver)
    unreachable = {}
    for name, u in r.unreachable.items():
        sel = u.frames >= keep
        unreachable[name] = Unreachable(u.frames[sel] - keep,
                                        tuple(t for t, s in zip(u.targets, sel, strict=True) if s),
                                        u.distances[sel])
    return (
        r.motion.rotations[keep:], r.motion.positions[keep:],
        {k: v[keep:] for k, v in r.residuals.items()}, unreachable,
        {k: v[keep:] for k, v in r.iterations.items()},
        {k: v[v >= keep] - keep for k, v in r.off_target.items()},
    )


def _run_parallel(
    jobs: list[tuple],
    workers: int,
    starts: list[int],
    ends: list[int],
    n: int,
    progress: Callable[[int, int], None] | None,
) -> list[tuple]:
    """Solve the chunks in ``workers`` fresh processes, in any order; results in order.

    The calling program's main module must be import-safe (``if __name__ == "__main__":``).
    """
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    # Not forked from this process: a fork of a process that has run torch's thread pools can
    # hang. A fork server (where the platform has one) imports the IK once and forks clean
    # workers from it, a second or two sooner than spawning each worker.
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["emotive.models.lgb.model", "emotive.ik"])
    else:
        ctx = multiprocessing.get_context("spawn")
    parts: list[tuple | None] = [None] * len(jobs)
    done = 0
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx,
                             initializer=_worker_init) as pool:
        futures = {pool.submit(_solve_chunk, *job): i for i, job in enumerate(jobs)}
        for fut in as_completed(futures):
            i = futures[fut]
            parts[i] = fut.result()
            done += ends[i] - starts[i]
            if progress is not None:
                progress(done, n)
    return parts  # type: ignore[return-value]


def _worker_init() -> None:
    """One torch thread per worker: the workers are the parallelism."""
    import torch

    torch.set_num_threads(1)


def _join(
    parts: list[tuple], starts: list[int], template: Motion, names: list[str], seconds: float
) -> IKResult:
    """One :class:`~emotive.ik.IKResult` from chunk results starting at ``starts``, on the rig,
    frame rate and metadata of ``template``."""
    from emotive.ik import IKResult, Unreachable

    rot = np.concatenate([p[0] for p in parts])
    pos = np.concatenate([p[1] for p in parts])
    return IKResult(
        template.replace(rotations=rot, positions=pos),
        {k: np.concatenate([p[2][k] for p in parts]) for k in names},
        {
            k: Unreachable(
                np.concatenate([p[3][k].frames + a for p, a in zip(parts, starts, strict=True)]),
                tuple(t for p in parts for t in p[3][k].targets),
                np.concatenate([p[3][k].distances for p in parts]),
            )
            for k in names
        },
        {k: np.concatenate([p[4][k] for p in parts]) for k in names},
        seconds,
        {k: np.concatenate([p[5][k] + a for p, a in zip(parts, starts, strict=True)])
         for k in names},
    )
