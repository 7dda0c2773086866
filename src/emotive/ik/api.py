"""Whole-body IK on a clip: solve chains, rebuild a clip from its trajectories, pin feet.

Legend: ``T`` frames, ``J`` joints, ``E`` end sites, ``k`` chain joints, ``M`` chain targets.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from emotive.core.motion import Motion
from emotive.core.roles import resolve_roles
from emotive.ik.chains import Chain, IKError, link_transforms, resolve_chains
from emotive.ik.foot_lock import leg_rig, move_ankles
from emotive.ik.solver import Unreachable, single_thread, solve_chain
from emotive.ik.trajectories import Trajectories, extract_trajectories, integrate_pelvis, to_world
from emotive.transforms.kinematics import forward_kinematics_np
from emotive.transforms.np_rotations import quaternion_apply, quaternion_invert, quaternion_multiply

RoleMap = str | Path | dict[str, str] | None


@dataclass(frozen=True)
class IKResult:
    """Result of :func:`solve_chains`, :func:`reconstruct` and :func:`pin_feet`.

    Attributes:
        motion: the solved clip.
        residuals: chain name -> ``(T,)`` largest target error per frame, metres.
        unreachable: chain name -> targets clamped to the chain's reach (frames, distances).
        iterations: chain name -> ``(T,)`` DLS iterations per frame.
        seconds: wall time of the solve.
        off_target: chain name -> ``(K,)`` frames whose residual stays above the solver's
            ``off_target`` tolerance after its retries (see :mod:`emotive.ik.solver`).
    """

    motion: Motion
    residuals: dict[str, np.ndarray]
    unreachable: dict[str, Unreachable]
    iterations: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0
    off_target: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def ms_per_frame(self) -> float:
        """Solve time per frame (all chains), milliseconds."""
        n = self.motion.num_frames
        return 1000.0 * self.seconds / n if n else 0.0


def _target_offsets(
    chain: Chain, grot: np.ndarray, gpos: np.ndarray, pts: np.ndarray
) -> np.ndarray:
    """``(T, M, 3)`` target points in their anchor joint's frame."""
    anchor = chain.joints[chain.anchors]
    inv = quaternion_invert(grot[:, anchor])
    return quaternion_apply(inv, pts[:, chain.targets] - gpos[:, anchor])


def solve_chains(
    motion: Motion,
    targets: dict[str, np.ndarray],
    chains: dict[str, Chain] | None = None,
    *,
    frame: str = "chain",
    init: str = "motion",
    role_map: RoleMap = None,
    **solver: Any,
) -> IKResult:
    """Solve the chains named in ``targets`` on a clip, keeping every other joint.

    Chains are solved in the order of ``chains`` (torso before arms), each from the clip as
    updated by the chains before it, so arm targets in the chest frame follow the new torso.
    Intermediate joints between chain joints (CMU's ``Neck1``) keep the clip's rotations and
    move with the chain joint above them.

    Args:
        motion: the clip supplying the root path, untouched joints and (``init="motion"``)
            the initial pose.
        targets: chain name -> ``(T, M, 3)`` targets in the order of ``Chain.target_roles``.
        chains: from :func:`resolve_chains`; resolved with ``motion`` as reference if None.
        frame: ``"chain"`` (targets in each chain's frame) or ``"world"``.
        init: ``"motion"`` (start from and lean to the clip's own rotations) or ``"neutral"``
            (the chain's neutral pose).
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

    Returns:
        The solved clip and per-chain reports.

    Raises:
        IKError: unknown chain, bad ``frame``/``init``, wrong shapes or NaN targets.
    """
    if frame not in ("chain", "world") or init not in ("motion", "neutral"):
        raise IKError(f"frame must be 'chain' or 'world' and init 'motion' or 'neutral', "
                      f"got {frame!r} and {init!r}")
    chains = chains if chains is not None else resolve_chains(motion.skeleton, motion, role_map)
    unknown = sorted(set(targets) - set(chains))
    if unknown:
        raise IKError(f"targets for unknown chains {unknown}; chains: {list(chains)}")
    with single_thread():
        return _solve_chains(motion, targets, chains, frame, init, solver)


def _solve_chains(
    motion: Motion,
    targets: dict[str, np.ndarray],
    chains: dict[str, Chain],
    frame: str,
    init: str,
    solver: dict[str, Any],
) -> IKResult:
    start = time.perf_counter()
    rot = motion.rotations.copy()
    residuals, unreachable, iterations, off_target = {}, {}, {}, {}
    sk = motion.skeleton
    for name, chain in chains.items():
        if name not in targets:
            continue
        current = motion.replace(rotations=rot)
        grot, gpos = forward_kinematics_np(rot, motion.positions, sk.parents)
        pts = current.positions_with_end_sites()
        tgt = np.asarray(targets[name], dtype=np.float64)
        if tgt.shape != (motion.num_frames, len(chain.targets), 3):
            raise IKError(
                f"chain {name}: targets must have shape ({motion.num_frames}, "
                f"{len(chain.targets)}, 3) for {list(chain.target_roles)}, got {tgt.shape}"
            )
        if frame == "chain":
            tgt = to_world(tgt, grot[:, chain.frame], gpos[:, chain.frame])
        start_pose = rot[:, chain.joints] if init == "motion" else chain.neutral
        local_pos, link_rot = link_transforms(chain, rot, motion.positions)
        sol = solve_chain(
            chain, grot[:, chain.base], gpos[:, chain.base], local_pos,
            _target_offsets(chain, grot, gpos, pts), tgt, start_pose, link_rot=link_rot,
            **solver,
        )
        rot[:, chain.joints] = sol.rotations
        residuals[name], unreachable[name] = sol.residual, sol.unreachable
        iterations[name] = sol.iterations
        off_target[name] = sol.off_target
    return IKResult(
        motion.replace(rotations=rot), residuals, unreachable, iterations,
        time.perf_counter() - start, off_target,
    )


def reconstruct(
    motion: Motion,
    chains: dict[str, Chain] | None = None,
    role_map: RoleMap = None,
    **solver: Any,
) -> IKResult:
    """Rebuild a clip from its own trajectories (the paper's motion reconstruction task).

    Extracts the pelvis path and every chain's targets, puts the pelvis back from its
    invariant path, resets the chain joints to their neutral pose and solves the five chains
    from the targets alone. Joints outside the chains (clavicles, toes, intermediate joints
    between chain joints such as CMU's ``Neck1``, ...) keep their rotations.

    Args:
        motion: the clip.
        chains: from :func:`resolve_chains`; resolved with ``motion`` as reference if None.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

    Returns:
        The rebuilt clip and per-chain reports.
    """
    with single_thread():
        chains = chains if chains is not None else resolve_chains(motion.skeleton, motion, role_map)
        traj = extract_trajectories(motion, chains, role_map)
        return rebuild(motion, traj, chains, role_map=role_map, **solver)


def rebuild(
    motion: Motion,
    traj: Trajectories,
    chains: dict[str, Chain],
    *,
    role_map: RoleMap = None,
    **solver: Any,
) -> IKResult:
    """Whole-body motion following chain-frame trajectories, on ``motion``'s rig.

    The pelvis is integrated from its invariant path, the chain joints start from their
    neutral pose and the chains are solved from the targets alone; every other joint keeps
    ``motion``'s rotations (which must have as many frames as ``traj``).

    Args:
        motion: the clip that gives the rig and the joints outside the chains, ``T`` frames.
        traj: pelvis path and chain targets, ``T`` frames (:func:`extract_trajectories`).
        chains: from :func:`resolve_chains`.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

    Returns:
        The rebuilt clip and per-chain reports.
    """
    sk = motion.skeleton
    root = resolve_roles(sk, role_map).index["root"]
    pos_w, rot_w = integrate_pelvis(traj.pelvis)
    rot, pos = motion.rotations.copy(), motion.positions.copy()
    parent = sk.parents[root]
    if parent >= 0:
        # The root role may sit under a static file root (Bandai's joint_Root).
        grot, gpos = motion.global_transforms()
        inv = quaternion_invert(grot[:, parent])
        rot_w = quaternion_multiply(inv, rot_w)
        pos_w = quaternion_apply(inv, pos_w - gpos[:, parent])
    rot[:, root], pos[:, root] = rot_w, pos_w
    for chain in chains.values():
        rot[:, chain.joints] = chain.neutral
    start = motion.replace(rotations=rot, positions=pos)
    return solve_chains(start, traj.targets, chains, frame="chain", init="neutral",
                        role_map=role_map, **solver)


def _contact_runs(column: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate(([0], column.astype(np.int8), [0])))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def pin_feet(
    motion: Motion,
    contacts: np.ndarray,
    chains: dict[str, Chain] | None = None,
    *,
    blend: int = 4,
    role_map: RoleMap = None,
    **solver: Any,
) -> IKResult:
    """Foot-plant cleanup: hold each planted foot still in the world while it is in contact.

    During each contact run, the foot's targets (ankle and toe) are pinned to their mean
    world position over the run; over ``blend`` frames either side the correction fades out.
    The leg chains are then solved from the clip's own pose.

    Args:
        motion: the clip.
        contacts: ``(T, 2)`` bool, columns left and right foot (as from
            :func:`emotive.features.contacts.foot_contacts`).
        chains: from :func:`resolve_chains`; resolved with ``motion`` as reference if None.
        blend: frames over which the correction fades in and out.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.
        **solver: keyword arguments of :func:`emotive.ik.solver.solve_chain`.

    Returns:
        The cleaned clip; unreachable pins are clamped to the leg's reach and reported.

    Raises:
        IKError: ``contacts`` is not ``(T, 2)``.
    """
    contacts = np.asarray(contacts, dtype=bool)
    n = motion.num_frames
    if contacts.shape != (n, 2):
        raise IKError(f"contacts must have shape ({n}, 2) (left, right), got {contacts.shape}")
    names = ("left_leg", "right_leg")
    if chains is None:
        chains = resolve_chains(motion.skeleton, motion, role_map, names=names)
    pts = motion.positions_with_end_sites()
    targets = {name: _pinned(pts[:, chains[name].targets], contacts[:, side], blend)
               for side, name in enumerate(names)}
    return solve_chains(motion, targets, chains, frame="world", init="motion", **solver)


def _pinned(world: np.ndarray, contact: np.ndarray, blend: int) -> np.ndarray:
    """``(T, M, 3)`` targets: each contact run's points held at their mean, faded at the ends.

    Args:
        world: ``(T, M, 3)`` world positions of one foot's target points.
        contact: ``(T,)`` bool, the foot's contacts.
        blend: frames over which the correction fades out either side of a run.
    """
    delta = np.zeros_like(world)
    for a, b in _contact_runs(contact):
        delta[a:b] = world[a:b].mean(0) - world[a:b]
    return world + fade_out(delta, contact, blend)


def fade_out(delta: np.ndarray, contact: np.ndarray, blend: int) -> np.ndarray:
    """Corrections of contact runs continued, fading linearly, over ``blend`` frames either side.

    Args:
        delta: ``(T, ...)`` a correction per frame, set inside the runs of ``contact``.
        contact: ``(T,)`` bool.
        blend: frames of the fade; the ``i``-th frame out of a run takes ``1 - i / (blend +
            1)`` of the run's first (before it) or last (after it) correction.

    Returns:
        A copy of ``delta`` with the faded corrections outside the runs.
    """
    n = len(delta)
    delta = delta.copy()
    for a, b in _contact_runs(contact):
        for i in range(1, blend + 1):
            w = 1.0 - i / (blend + 1)
            if a - i >= 0 and not contact[a - i]:
                delta[a - i] = w * delta[a]
            if b - 1 + i < n and not contact[b - 1 + i]:
                delta[b - 1 + i] = w * delta[b - 1]
    return delta


def pin_feet_two_bone(motion: Motion, contacts: np.ndarray, *, blend: int = 4,
                      role_map: RoleMap = None) -> Motion:
    """:func:`pin_feet` by the foot lock's analytic two-bone solve, all frames at once.

    The same targets (each planted heel and toe held at its mean over the contact run,
    faded over ``blend`` frames), met by :func:`emotive.ik.foot_lock.move_ankles`: the heel
    lands on its target (an ankle the straight leg cannot reach is lifted until it can, so
    no frame is thrown off), the foot turns about the vertical so that its toe points at
    the toe's target, and the knee stays in its bending plane. Much cheaper than the damped
    least squares of :func:`pin_feet` and exact in the heel, but it holds the toe only in
    heading, not in height or pitch.

    Args:
        motion: the clip, on a rig whose hip, knee and ankle are parent and child.
        contacts: ``(T, 2)`` bool, columns left and right foot.
        blend: frames over which the correction fades in and out.
        role_map: as for :func:`emotive.core.roles.resolve_roles`.

    Returns:
        The clip with its planted feet held.

    Raises:
        IKError: ``contacts`` is not ``(T, 2)``, or the legs have joints between hip, knee
            and ankle (use :func:`pin_feet`).
    """
    contacts = np.asarray(contacts, dtype=bool)
    n = motion.num_frames
    if contacts.shape != (n, 2):
        raise IKError(f"contacts must have shape ({n}, 2) (left, right), got {contacts.shape}")
    roles = resolve_roles(motion.skeleton, role_map)
    points = motion.positions_with_end_sites()
    try:
        legs = leg_rig(motion.skeleton, roles, points[0])
    except ValueError as exc:
        raise IKError(f"{exc}; pin_feet solves any leg") from None
    shift = np.zeros((n, 2, 3))
    yaw = np.zeros((n, 2))
    for side, prefix in enumerate(("l", "r")):
        feet = points[:, roles.indices((f"{prefix}_ankle", f"{prefix}_toe"))]
        targets = _pinned(feet, contacts[:, side], blend)
        shift[:, side] = targets[:, 0] - feet[:, 0]
        turn = _heading(targets) - _heading(feet)
        flat = np.linalg.norm((targets[:, 1] - targets[:, 0])[:, [0, 2]], axis=-1)
        yaw[:, side] = np.where(flat > 1e-5, np.angle(np.exp(1j * turn)), 0.0)
    moving = (np.abs(shift).max(axis=(1, 2)) > 1e-9) | (np.abs(yaw).max(axis=1) > 1e-9)
    if not moving.any():
        return motion
    rotations = motion.rotations.copy()
    rotations[moving], _ = move_ankles(legs, rotations[moving], points[moving],
                                       shift[moving], yaw[moving])
    return motion.replace(rotations=rotations)


def _heading(feet: np.ndarray) -> np.ndarray:
    """``(T,)`` world heading (radians, 0 facing +Z) of heel -> toe, ``(T, 2, 3)`` points."""
    d = feet[:, 1] - feet[:, 0]
    return np.arctan2(d[:, 0], d[:, 2])
