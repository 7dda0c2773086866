"""Per-emotion resampling of end-effector trajectories, rebuilt into whole-body motion by IK.

Issue 7, section 2 (paper sections 5.2 and 5.3). For one emotional state:

1. Every clip's pelvis path and chain targets (end effectors, elbows, shoulders, neck) are
   extracted in their chain frames (:func:`emotive.ik.extract_trajectories`) and laid out as one
   ``(T, F)`` feature row per frame.
2. The clips are joined into one **closed, continuous** sequence: the last ``blend`` frames of
   each clip are cross-faded (smoothstep weights) into the first ``blend`` frames of the next,
   and the last clip into the first. Cross-fading in the chain-frame trajectory space needs no
   IK and keeps every junction continuous; the pelvis path is stored as per-frame steps, so the
   joined path stays continuous in the world too.
3. Four processes are resampled independently, each by a
   :class:`~emotive.models.lgb.bootstrap.LocalGridBootstrap` (the paper's processes and orders):

   ========== ==== ===== ======================================= ===========================
   process    D    order state                                   passengers
   ========== ==== ===== ======================================= ===========================
   head       3    3     head (pelvis frame)                     neck, shoulders
   left_arm   6    1     left elbow and wrist (chest frame)      left hand tip
   right_arm  6    1     right elbow and wrist (chest frame)     right hand tip
   lower_body 9    1     both ankles (pelvis frame), pelvis      toes, pelvis turn and tilt
                         height and ground step
   ========== ==== ===== ======================================= ===========================

   The targets the IK chains need but the paper's processes leave out (neck, shoulders, hand
   tips, toes) and the rest of the root motion (turn and tilt) are passengers: the barycentre
   of their values over the observations of the drawn cell, so they follow the drawn states.
4. The sampled trajectories are put back in the world (:func:`emotive.ik.integrate_pelvis`)
   and the five chains are solved from the targets (:func:`emotive.ik.solve_chains`).

Legend: ``T`` frames, ``F`` features per frame, ``M`` targets of a chain.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from emotive.core.motion import Motion
from emotive.errors import EmotionError
from emotive.models.lgb.bootstrap import (
    LGBError,
    LGBSample,
    LocalGridBootstrap,
    TooLittleDataError,
    check_finite,
    min_observations,
)

if TYPE_CHECKING:
    from emotive.data.clips import Clip
    from emotive.ik import Chain, IKResult, Trajectories, Unreachable

#: Order of each process's Markov chain (paper: 3 for the head, 1 for the others).
ORDERS: dict[str, int] = {"head": 3, "left_arm": 1, "right_arm": 1, "lower_body": 1}

#: Fraction of the offset from the drawn cell each step keeps (see
#: :class:`~emotive.models.lgb.bootstrap.LocalGridBootstrap`): the paper's plain barycentre
#: (0) traps the chains in the still stretches of the Bandai Namco clips.
CARRY = 1.0

#: Frames cross-faded at each junction between clips (half a second at 30 fps).
BLEND_FRAMES = 15


@dataclass(frozen=True)
class _Column:
    """Columns of one named block of the ``(T, F)`` feature layout."""

    start: int
    width: int

    @property
    def slice(self) -> slice:
        return slice(self.start, self.start + self.width)


def _layout(chains: dict[str, Chain]) -> dict[str, _Column]:
    """Feature blocks: ``chain:role`` targets (3 columns each), then the pelvis path."""
    blocks: list[tuple[str, int]] = [
        (f"{name}:{role}", 3) for name, c in chains.items() for role in c.target_roles
    ]
    blocks += [("pelvis:height", 1), ("pelvis:step", 2), ("pelvis:turn", 1), ("pelvis:tilt", 4)]
    out, start = {}, 0
    for name, width in blocks:
        out[name] = _Column(start, width)
        start += width
    return out


#: Process name -> (state blocks, passenger blocks) of the feature layout.
PROCESSES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "head": (
        ("head_torso:head",),
        ("head_torso:l_shoulder", "head_torso:r_shoulder", "head_torso:neck"),
    ),
    "left_arm": (("left_arm:l_elbow", "left_arm:l_wrist"), ("left_arm:l_handtip",)),
    "right_arm": (("right_arm:r_elbow", "right_arm:r_wrist"), ("right_arm:r_handtip",)),
    "lower_body": (
        ("left_leg:l_ankle", "right_leg:r_ankle", "pelvis:height", "pelvis:step"),
        ("left_leg:l_toe", "right_leg:r_toe", "pelvis:turn", "pelvis:tilt"),
    ),
}


def _columns(layout: dict[str, _Column], blocks: Sequence[str]) -> np.ndarray:
    return np.concatenate([np.arange(layout[b].start, layout[b].start + layout[b].width)
                           for b in blocks])


def trajectory_features(traj: Trajectories, layout: dict[str, _Column]) -> np.ndarray:
    """``(T, F)`` feature rows of a clip's trajectories (see :func:`_layout`)."""
    n = len(traj.pelvis.height)
    out = np.empty((n, sum(c.width for c in layout.values())))
    pelvis = {"height": traj.pelvis.height, "step": traj.pelvis.displacement,
              "turn": traj.pelvis.turn, "tilt": traj.pelvis.tilt}
    for key, col in layout.items():
        group, role = key.split(":")
        if group == "pelvis":
            out[:, col.slice] = np.reshape(pelvis[role], (n, -1))
    for name, targets in traj.targets.items():
        roles = [k.split(":")[1] for k in layout if k.startswith(f"{name}:")]
        for r, role in enumerate(roles):
            out[:, layout[f"{name}:{role}"].slice] = targets[:, r]
    return out


def _align_tilt(features: np.ndarray, tilt: slice) -> None:
    """Flip quaternion signs in place so that blending and averaging stay on one hemisphere."""
    q = features[:, tilt]
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)


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
    s = (np.arange(blend) + 0.5) / blend
    w = (s * s * (3.0 - 2.0 * s))[:, None]
    parts = []
    for i, cur in enumerate(features):
        prev = features[i - 1]
        parts.append((1.0 - w) * prev[-blend:] + w * cur[:blend])
        parts.append(cur[blend:-blend])
    return np.concatenate(parts)


@dataclass(eq=False)
class EmotionResampler:
    """Local Grid Bootstrap of one emotional state's trajectories, rebuilt by IK.

    Build it with :meth:`fit`. Attributes:
        emotion: the emotional state.
        reference: a clip of the data's rig (its first frame supplies the joints outside the
            chains and the rig written out).
        chains: the IK chains on that rig.
        observed: ``(T, F)`` closed observed feature sequence.
        bootstraps: process name -> fitted bootstrap.
        fps: frame rate of the data.
    """

    emotion: str
    reference: Motion
    chains: dict[str, Chain]
    observed: np.ndarray
    bootstraps: dict[str, LocalGridBootstrap]
    fps: float
    layout: dict[str, _Column] = field(repr=False)

    @classmethod
    def fit(
        cls,
        clips: Sequence[Clip],
        emotion: str,
        *,
        blend: int = BLEND_FRAMES,
        orders: dict[str, int] | None = None,
        carry: float = CARRY,
        role_map: Any = None,
    ) -> EmotionResampler:
        """Fit the four processes on the clips of one emotional state.

        Args:
            clips: clips (any emotions; only those labelled ``emotion`` are used).
            emotion: the emotional state, any spelling :func:`canonical_label` accepts.
            blend: frames of each cross-fade between clips.
            orders: process -> Markov order; :data:`ORDERS` if None.
            carry: see :data:`CARRY`.
            role_map: as for :func:`emotive.core.roles.resolve_roles`.

        Returns:
            The fitted resampler.

        Raises:
            EmotionError: no clip has that emotion.
            TooLittleDataError: the emotion's joined sequence is shorter than the bootstraps
                need (:func:`~emotive.models.lgb.bootstrap.min_observations`).
            LGBError: NaN in the trajectories.
        """
        from emotive.data.emotion import canonical_label
        from emotive.ik import extract_trajectories, resolve_chains

        label = canonical_label(emotion)
        orders = {**ORDERS, **(orders or {})}
        mine = [c for c in clips if c.info.emotion == label]
        if not mine:
            known = sorted({c.info.emotion for c in clips})
            raise EmotionError(f"no clips of emotion {label!r}; the clips have {known}")
        usable = [c for c in mine if c.motion.num_frames > 2 * blend]
        have = sum(c.motion.num_frames for c in usable) - blend * len(usable)
        need = max(min_observations(p) for p in orders.values())
        if have < need:
            raise TooLittleDataError(
                f"emotion {label!r} ({len(mine)} clips)", max(have, 0), need,
                "the closed sequence of its clips must hold twice the 100 states of the largest "
                f"neighbourhood plus the order {max(orders.values())}",
            )
        first = usable[0].motion
        # Chain neutral poses and hinge axes from every frame of the emotion on the first rig.
        same = [c.motion for c in usable
                if c.motion.skeleton.num_joints == first.skeleton.num_joints]
        reference = first.replace(
            rotations=np.concatenate([m.rotations for m in same]),
            positions=np.concatenate([m.positions for m in same]),
        )
        chains = resolve_chains(first.skeleton, reference, role_map)
        layout = _layout(chains)
        tilt = layout["pelvis:tilt"].slice
        rows = []
        for clip in usable:
            f = trajectory_features(extract_trajectories(clip.motion, chains, role_map), layout)
            check_finite(f"trajectories of clip {clip.info.name}", f)
            _align_tilt(f, tilt)
            rows.append(f)
        observed = close_sequences(rows, blend)
        boots = {}
        for name, (state, passengers) in PROCESSES.items():
            boots[name] = LocalGridBootstrap(order=orders[name], carry=carry).fit(
                observed[:, _columns(layout, state)], observed[:, _columns(layout, passengers)],
                name=f"emotion {label!r}, process {name}",
            )
        return cls(label, first, chains, observed, boots, float(first.fps), layout)

    def sample_features(
        self, frames: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, dict[str, LGBSample]]:
        """Resample ``frames`` feature rows.

        Args:
            frames: ``T``, any length.
            rng: source of every draw.

        Returns:
            ``(T, F)`` rows and each process's raw sample (``index`` gives the drawn
            observations of :attr:`observed`).
        """
        out = np.empty((frames, self.observed.shape[1]))
        samples = {}
        for name, (state, passengers) in PROCESSES.items():
            s = self.bootstraps[name].sample(frames, rng)
            out[:, _columns(self.layout, state)] = s.states
            out[:, _columns(self.layout, passengers)] = s.passengers
            samples[name] = s
        tilt = out[:, self.layout["pelvis:tilt"].slice]
        tilt /= np.linalg.norm(tilt, axis=-1, keepdims=True)
        return out, samples

    def trajectories(self, features: np.ndarray) -> Trajectories:
        """Feature rows back to :class:`~emotive.ik.Trajectories` (pelvis starting at the
        origin, facing +Z)."""
        from emotive.ik import PelvisTrajectory, Trajectories

        n = len(features)
        lay = self.layout

        def block(key: str) -> np.ndarray:
            return features[:, lay[key].slice]

        step = block("pelvis:step").copy()
        turn = block("pelvis:turn")[:, 0].copy()
        # Frame 0 carries no step from a previous frame.
        step[0], turn[0] = 0.0, 0.0
        height = block("pelvis:height")[:, 0].copy()
        pelvis = PelvisTrajectory(height, step, turn, block("pelvis:tilt").copy(),
                                  np.array([0.0, height[0], 0.0]), 0.0)
        targets = {
            name: np.stack([block(f"{name}:{r}") for r in c.target_roles], 1).reshape(n, -1, 3)
            for name, c in self.chains.items()
        }
        return Trajectories(pelvis, targets)

    def rebuild(self, traj: Trajectories, role_map: Any = None, **solver: Any) -> IKResult:
        """Whole-body motion on the reference rig following sampled trajectories.

        The pelvis is integrated from its path, the joints outside the chains keep the
        reference's first-frame rotations, and the five chains are solved from their targets.

        Args:
            traj: from :meth:`trajectories`.
            role_map: as for :func:`emotive.core.roles.resolve_roles`.
            **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

        Returns:
            The IK result; its motion is at the data's frame rate.
        """
        from emotive.ik import rebuild

        n = len(traj.pelvis.height)
        ref = self.reference
        base = Motion(ref.skeleton, np.repeat(ref.rotations[:1], n, axis=0),
                      np.repeat(ref.positions[:1], n, axis=0), self.fps, dict(ref.metadata))
        return rebuild(base, traj, self.chains, role_map=role_map, **solver)

    def generate(
        self,
        frames: int,
        seed: int | np.random.Generator = 0,
        progress: Callable[[int, int], None] | None = None,
        chunk: int = 3000,
    ) -> IKResult:
        """Resample ``frames`` frames and rebuild them into whole-body motion.

        Args:
            frames: ``T``, any length.
            seed: seed (or generator) of the draws; the same seed gives the same motion.
            progress: called with ``(frames done, frames)`` after each solved chunk.
            chunk: frames solved per IK call (progress granularity).

        Returns:
            The IK result (motion, residuals, unreachable targets).

        Raises:
            LGBError: ``frames < 1``.
        """
        if frames < 1:
            raise LGBError(f"the number of frames must be >= 1, got {frames}")
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        features, _ = self.sample_features(frames, rng)
        traj = self.trajectories(features)
        if progress is None and frames <= chunk:
            return self.rebuild(traj)
        return self._rebuild_in_chunks(traj, chunk, progress)

    def _rebuild_in_chunks(
        self, traj: Trajectories, chunk: int, progress: Callable[[int, int], None] | None
    ) -> IKResult:
        from emotive.ik import IKResult, PelvisTrajectory, Trajectories, integrate_pelvis

        n = len(traj.pelvis.height)
        pos_w, _ = integrate_pelvis(traj.pelvis)
        yaw = np.cumsum(traj.pelvis.turn)
        p = traj.pelvis
        results = []
        starts = list(range(0, n, chunk))
        for a in starts:
            b = min(a + chunk, n)
            # Each chunk starts where the previous one left the pelvis (position, heading).
            step, turn = p.displacement[a:b].copy(), p.turn[a:b].copy()
            step[0], turn[0] = 0.0, 0.0
            part = Trajectories(
                PelvisTrajectory(p.height[a:b], step, turn, p.tilt[a:b], pos_w[a].copy(),
                                 float(yaw[a])),
                {k: v[a:b] for k, v in traj.targets.items()},
            )
            results.append(self.rebuild(part))
            if progress is not None:
                progress(b, n)
        first = results[0].motion
        motion = first.replace(
            rotations=np.concatenate([r.motion.rotations for r in results]),
            positions=np.concatenate([r.motion.positions for r in results]),
        )
        return IKResult(
            motion,
            {k: np.concatenate([r.residuals[k] for r in results]) for k in self.chains},
            {k: _merge_unreachable([r.unreachable[k] for r in results], starts)
             for k in self.chains},
            {k: np.concatenate([r.iterations[k] for r in results]) for k in self.chains},
            sum(r.seconds for r in results),
        )


def _merge_unreachable(parts: Sequence[Unreachable], starts: Sequence[int]) -> Unreachable:
    """Join per-chunk reports, shifting frames by each chunk's first frame."""
    from emotive.ik import Unreachable

    return Unreachable(
        np.concatenate([u.frames + a for u, a in zip(parts, starts, strict=True)]),
        tuple(t for u in parts for t in u.targets),
        np.concatenate([u.distances for u in parts]),
    )
